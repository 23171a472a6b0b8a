"""What one browser session has chosen, shared by its pages: the clip, the frame the player shows and the span
(from the Database page's player) that the query pages take as their example, or a take the user uploaded
(:mod:`mocapviz.app.upload`) and its span."""

from __future__ import annotations

import param


class Selection(param.Parameterized):
    """The current clip, frame and span of a dashboard session.

    ``doc`` is a document id of the database; ``frame`` and ``span`` are frame numbers within that document,
    ``span`` (start, end) half-open as a hit's (:func:`mocapviz.db.hits.hit_table`): frames start..end - 1. The
    sliders show first and last frames; pages read positions only through :func:`mocapviz.db.hits.database_frames`.
    """

    doc = param.Integer(default=0, doc="document id")
    frame = param.Integer(default=0, bounds=(0, None), doc="frame within the document")
    span = param.Tuple(default=(0, 1), length=2, doc="(start, end) frames within the document, half-open")
    upload = param.Parameter(default=None, doc="the session's uploaded take (mocapviz.app.upload.Upload), or None")
    use_upload = param.Boolean(default=False, doc="the uploaded take, not the document, is the query clip")
    upload_span = param.Tuple(default=(0, 1), length=2, doc="(start, end) frames of the uploaded take, half-open")

    def query(self) -> tuple:
        """The query clip of the query pages: (document id or the uploaded take, span, frame), the span half-open
        and the frame within that clip (an upload's: the first of its span)."""
        if self.use_upload and self.upload is not None:
            return self.upload, tuple(self.upload_span), int(self.upload_span[0])
        return int(self.doc), tuple(self.span), int(self.frame)


def half_open(value) -> tuple[int, int]:
    """A span slider's (first, last) frames as a session's span (start, end), half-open."""
    first, last = (int(v) for v in value)
    return first, last + 1


def inclusive(span) -> tuple[int, int]:
    """A session's span (start, end), half-open, as a slider's (first, last) frames."""
    start, end = (int(v) for v in span)
    return start, end - 1
