"""What the search commands (query, find, knn, match, search, template) ask of their arguments: the engine of their
database (``DB`` and ``--scheduler``) and the example (``--example``)."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from ..engine import Engine
from ..errors import ParameterError

if TYPE_CHECKING:
    from ..engine import MotionDB


def engine_of(args) -> Engine:
    """The engine of a search command's database: its shards in this process, or on the cluster of
    ``--scheduler local|ADDRESS``."""
    return Engine(args.db, scheduler=getattr(args, "scheduler", None))


def example_of(db: MotionDB, text: str) -> int | Path:
    """``--example``: a document id of ``db`` (digits; :meth:`MotionDB.document` refuses one it does not hold) or
    a motion file."""
    if text.isdigit():
        try:
            return int(db.document(int(text))["doc_id"])
        except ParameterError as exc:
            raise ParameterError(f"--example {text}: {exc}") from None
    if Path(text).is_file():
        return Path(text)
    ids = db.documents["doc_id"]
    raise ParameterError(f"--example {text} is neither a document id of {db.path} (doc ids {ids.min()}..{ids.max()}) "
                         "nor a motion file")
