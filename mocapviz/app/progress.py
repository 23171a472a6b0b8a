"""Long computations of a page, run off the server's event loop with a progress bar, so the page never freezes.

:class:`Task` shows an indeterminate bar and a status line while a function runs in a worker thread; when it ends,
the line says how long it took, or shows its error as one red message: a user's error
(:class:`~mocapviz.errors.MocapvizError`: a bad value, a missing document, ...) by its message alone, with one line
in the server log; any other error as "… failed (an unexpected error); see the server log", the log keeping its
traceback. No exception type or traceback reaches the page. The red message goes away when the next run starts;
what showed the previous result (``stale=``) is emptied when a run fails, so no old answer stays under its error.
:func:`in_thread` runs the computing part of any other callback (a row click) off the event loop.
"""

from __future__ import annotations

import asyncio
import logging
import time
from concurrent.futures import ThreadPoolExecutor

import panel as pn

from ..errors import MocapvizError
from ..heap import trim_free_memory
from .widgets import clear

LOG = logging.getLogger("mocapviz.app")
# threads answering the pages' queries, all sessions together: more than the event loop's default executor (cores
# + 4), so that a quick search is not queued behind several sessions' long ones (a template's search of every
# frame), which it then shares the cores with instead; bounded, as each running query holds its temporary arrays
QUERY_THREADS = 16
_QUERIES = ThreadPoolExecutor(QUERY_THREADS, thread_name_prefix="mocapviz-query")


class Task(pn.viewable.Viewer):
    """A status line and progress bar for one page's long computations.

    ``await task.run("Searching", fn, *args, busy=button, stale=(table, plot))`` returns ``fn(*args)``, computed in
    a worker thread (the ``busy`` widgets disabled meanwhile), or None after showing its error and emptying the
    ``stale`` panes (:func:`~mocapviz.app.widgets.clear`: what showed the previous result).
    """

    def __init__(self, **params):
        super().__init__(**params)
        # the bar stays in the layout (empty when idle): showing and hiding it would make the browser lay out the
        # whole page again on every run, which costs more than most searches
        self.bar = pn.indicators.Progress(value=0, active=False, height=8, sizing_mode="stretch_width",
                                          bar_color="primary")
        self.status = pn.pane.Markdown("", margin=(0, 10), css_classes=["mv-status"])
        self.error = pn.pane.Alert("", alert_type="danger", visible=False, css_classes=["mv-error"])
        self.seconds = None

    def __panel__(self):
        return pn.Column(self.bar, self.status, self.error, sizing_mode="stretch_width", margin=0)

    def forget(self) -> None:
        """Empty the status line and hide the error: the result they were about is no longer shown (another run
        replaced what it was computed from)."""
        self.status.object = ""
        self.error.visible = False

    async def run(self, label: str, fn, *args, busy=(), stale=()):
        busy = [busy] if isinstance(busy, pn.widgets.Widget) else list(busy)
        for w in busy:
            w.disabled = True
        self.error.visible = False
        self.status.object = f"{label} …"
        self.bar.param.update(value=-1, active=True)
        t0 = time.perf_counter()
        try:
            result = await self._call(fn, *args)
        except MocapvizError as exc:  # the user's input: its message says what to change
            LOG.warning("%s refused: %s", label, exc)
            self.error.param.update(object=f"**{label} failed.** {exc}", visible=True)
            self.status.object = ""
            clear(*stale)
            return None
        except Exception:
            LOG.exception("%s failed", label)
            self.error.param.update(object=f"**{label} failed** (an unexpected error); see the server log.",
                                    visible=True)
            self.status.object = ""
            clear(*stale)
            return None
        finally:
            self.bar.param.update(value=0, active=False)
            for w in busy:
                w.disabled = False
        self.seconds = time.perf_counter() - t0
        self.status.object = f"{label}: done in {self.seconds:.2f} s"
        return result

    async def _call(self, fn, *args):
        return await in_thread(_then_trim, fn, *args)


def _then_trim(fn, *args):
    try:
        return fn(*args)
    finally:
        trim_free_memory()


async def in_thread(fn, *args):
    """``fn(*args)`` computed in one of the :data:`QUERY_THREADS` threads answering queries: the server's event loop,
    which every session's page updates go through, stays free meanwhile. For a page's query and the computing part of
    its other callbacks (a clip's features, an alignment); the widgets are then updated on the event loop, after the
    ``await``."""
    return await asyncio.get_running_loop().run_in_executor(_QUERIES, fn, *args)
