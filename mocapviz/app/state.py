"""What one browser session has chosen, shared by its pages: the clip, the frame the player shows and the span
(from the Database page's player) that the query pages take as their example."""

from __future__ import annotations

import param


class Selection(param.Parameterized):
    """The current clip, frame and span of a dashboard session.

    ``doc`` is a document id of the database; ``frame`` and ``span`` (first, last, inclusive) are frame numbers
    within that document.
    """

    doc = param.Integer(default=0, doc="document id")
    frame = param.Integer(default=0, bounds=(0, None), doc="frame within the document")
    span = param.Tuple(default=(0, 0), length=2, doc="(first, last) frames within the document, inclusive")
