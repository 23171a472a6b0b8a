"""The Panel dashboard (``mocapviz serve [DB]``): browse a MotionDB, query it, compare, all in the browser.

backend.py     Backend: one MotionDB and its cached indexes, feature sets, kd-trees and page results (per database,
               shared by sessions).
state.py       Selection: the session's clip, frame and span, shared by its pages.
progress.py    Task: long computations in a worker thread behind a progress bar; errors as one red line.
player.py      SkeletonPlayer: PyVista offscreen skeletons, one or more clips side by side, aligned playback.
pages/         one module per page: database (documents, player, timelines, curves), relational (query by
               example, Müller et al. 2005), similarity (DTW search of clips and stretches, kNN of a frame, LNG
               matching, similarity matrix; Krüger et al. 2010), retrieval (retrieval quality of every search
               method: mAP, per-class AP, P/R curves), correlations (Fig. 2), statistics (Müller Tables 2-3,
               Krüger Table 1), reconstruction (Krüger §5.2).

:func:`dashboard` builds one session's page; :func:`serve` runs the server (bound to 127.0.0.1 unless told
otherwise).
"""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import panel as pn

from .backend import Backend
from .state import Selection

LOG = logging.getLogger("mocapviz.app")
LOCAL = "127.0.0.1"
TITLE = "mocapviz"


def _pages():
    from .pages import correlations, database, reconstruction, relational, retrieval, similarity, statistics

    return [("Database", database.DatabasePage), ("Relational query", relational.RelationalPage),
            ("Similarity search", similarity.SimilarityPage), ("Retrieval quality", retrieval.RetrievalPage),
            ("Correlations", correlations.CorrelationsPage),
            ("Index statistics", statistics.StatisticsPage), ("Reconstruction", reconstruction.ReconstructionPage)]


def dashboard(db_path) -> pn.viewable.Viewable:
    """One session's dashboard over the MotionDB at ``db_path``: a header and one tab per page.

    Pages are built when their tab is first opened (the first page at once), so the first page shows quickly.
    """
    backend = Backend.open(db_path)
    selection = Selection(doc=int(backend.documents["doc_id"].iloc[0]))
    pages = _pages()
    built: dict[int, object] = {}

    def build(i: int):
        if i not in built:
            built[i] = pages[i][1](backend, selection)
        return built[i]

    tabs = pn.Tabs(*[(name, pn.Column(sizing_mode="stretch_width")) for name, _ in pages], dynamic=False,
                   sizing_mode="stretch_width", css_classes=["mv-tabs"])

    def show(event=None):
        i = tabs.active
        holder = tabs[i]
        if not len(holder):
            holder.append(build(i))
        page = built[i]
        if hasattr(page, "activate"):
            page.activate()

    tabs.param.watch(show, "active")
    show()
    db = backend.db
    header = pn.pane.Markdown(
        f"## mocapviz · {db.path.name}\n{len(db)} documents · {db.n_frames:,} frames · "
        + (f"{db.fps:g} fps" if db.fps else "mixed frame rates"), css_classes=["mv-header"], margin=(0, 10))
    return pn.Column(header, tabs, sizing_mode="stretch_width")


def _warm_search(backend: Backend) -> None:
    """One small search of each kind, so that the Similarity page's first search finds the DTW kernels compiled
    (or loaded from numba's cache), the F15E kd-tree and the coarse database built."""
    docs = backend.documents
    doc = int(docs.loc[docs["n_frames"].idxmax(), "doc_id"])
    search = backend.search("F15E")
    for mode in ("fast", "exact"):
        search.clips(doc, frames=(0, 2), n_matches=1, mode=mode)
        search.stretches(doc, frames=(0, 2), n_matches=1, mode=mode)


def serve(db_path, port: int = 5006, address: str = LOCAL, show: bool = False, threaded: bool = False):
    """Serve the dashboard of the MotionDB at ``db_path`` on http://address:port/ until interrupted.

    The database is opened (and checked) and one dashboard built before the server starts, so a bad path fails at
    once and the first page comes quickly. Any address other
    than 127.0.0.1 / localhost exposes the database to the network: a warning says so.

    Raises
    ------
    MotionDBError
        ``db_path`` is not a MotionDB, or holds no documents.
    """
    dashboard(db_path)  # once before listening: the first visitor then finds numba kernels, the EGL context,
    # HoloViews' option trees and the first clip's features ready
    _warm_search(Backend.open(db_path))
    if address not in (LOCAL, "localhost"):
        warnings.warn(f"serving on {address}: anyone who can reach this machine's port {port} can browse "
                      f"{db_path}", UserWarning, stacklevel=2)
    origins = [f"{host}:{port}" for host in {address, LOCAL, "localhost"}]
    if address in ("0.0.0.0", "::"):
        origins = ["*"]
    pn.extension("tabulator", notifications=False)
    path = Path(db_path)
    return pn.serve({"/": lambda: dashboard(path)}, port=port, address=address, show=show, threaded=threaded,
                    websocket_origin=origins, title=f"{TITLE} · {path.name}")


__all__ = ["Backend", "Selection", "dashboard", "serve"]
