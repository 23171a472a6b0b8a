"""Typed errors of mocapviz.

Every error a user can cause by passing bad input is one of these, raised with one sentence that names the
file (and line or frame where there is one) and says what is wrong.
"""
from __future__ import annotations

import os


class MocapvizError(Exception):
    """The base of every error mocapviz raises on purpose (bad input, a bad file, a bad database)."""


class Cancelled(BaseException):
    """A computation stopped between two of its steps because its caller asked it to (a dashboard job cancelled, or
    its browser session closed): raised by :func:`mocapviz.parallel.checkpoint` inside
    :func:`mocapviz.parallel.watching`. Not an error of the input, and like :class:`asyncio.CancelledError` not an
    :class:`Exception`, so that the handlers that skip a bad file or note a failed method let it through."""


class ParameterError(MocapvizError, ValueError):
    """A bad argument: a value outside its range, an unknown name, an array of the wrong shape or with non-finite
    values. The message names the parameter, the value given and what to pass instead."""


class UnknownKeyError(ParameterError, KeyError):
    """A name or id that is not there: a document id, a joint name, a label column (also a KeyError, so that
    ``except KeyError`` around a lookup keeps working). The message names the key and what exists."""

    __str__ = Exception.__str__  # the message as written, not KeyError's quoted repr


class LabelTableError(MocapvizError, ValueError):
    """A label table or label file beside the data (``labels.tsv``, Bandai Namco ``.json``) is malformed; the message
    names the file."""


class MocapFormatError(MocapvizError, ValueError):
    """A motion file is malformed: truncated, wrong channel count, unknown bone, non-finite value, ...

    Parameters
    ----------
    path : str, os.PathLike or None
        The file that failed (None: ``<input>``).
    reason : str
        What is wrong, in words.
    line : int, optional
        1-based line number in that file where the problem was found, if it has one.

    Attributes
    ----------
    path : str or None
        The file that failed.
    line : int or None
        1-based line number in that file where the problem was found, if it has one.
    reason : str
        What is wrong, in words.

    Examples
    --------
    >>> str(MocapFormatError("walk.bvh", "OFFSET needs three numbers", line=4))
    'walk.bvh, line 4: OFFSET needs three numbers'
    """

    def __init__(self, path: str | os.PathLike | None, reason: str, line: int | None = None):
        self.path, self.line, self.reason = _located(self, path, reason, line)


class MocapFormatWarning(UserWarning):
    """A motion file was read with a part of it left out, legitimately (an AMC cut off inside its last frame loses
    that frame); the message names the file, the line and what was left out. Issued by
    :func:`mocapviz.io.checks.format_warning`; ``mocapviz ingest`` prints it.

    Parameters and attributes are those of :class:`MocapFormatError`.

    Examples
    --------
    >>> str(MocapFormatWarning("golf_01.amc", "last frame 445 is incomplete; dropped it", line=14233))
    'golf_01.amc, line 14233: last frame 445 is incomplete; dropped it'
    """

    def __init__(self, path: str | os.PathLike | None, reason: str, line: int | None = None):
        self.path, self.line, self.reason = _located(self, path, reason, line)


def _located(exc: BaseException, path, reason: str, line: int | None) -> tuple[str | None, int | None, str]:
    """Give ``exc`` the message ``"<path>, line <line>: <reason>"``; return (path as a str or None, line, reason)."""
    path = None if path is None else os.fspath(path)
    where = path or "<input>"
    if line is not None:
        where = f"{where}, line {line}"
    Exception.__init__(exc, f"{where}: {reason}")
    return path, line, reason


class SkeletonMappingError(MocapvizError, ValueError):
    """A skeleton's joints could not be mapped to the canonical joints (``mocapviz.motion.skeleton``)."""


class MotionDBError(MocapvizError, ValueError):
    """A MotionDB on disk is missing, of another format version, or inconsistent."""


class StaleDataError(MotionDBError):
    """Derived data stored with a MotionDB (a relational index, a numeric feature set, a document's markers) reads
    back exactly as written but belongs to an earlier state of the database: another generation or frame count, or
    a PCA model since replaced; or was written by an older mocapviz in another version of its format
    (:mod:`mocapviz.db.arrays`). Nothing is damaged; the message names the command that computes it again
    (``mocapviz check DB`` reports it as "stale", apart from "damaged")."""


class SourceFileError(MocapvizError, ValueError):
    """A document's source file, needed to export it on its own rig (``mocapviz.export``), is gone or is not the file
    that was ingested (its sha256 differs from the documents table's); the message names the file and the way out
    (export on the canonical rig, from the database's own frames)."""


class DescriptionError(ParameterError):
    """A scene description (``docs/descriptions.md``) that cannot be read: a syntax error, an unknown body part,
    state word or name, a bad time. The message starts with the line and column.

    Parameters
    ----------
    reason : str
        What is wrong, in words (with the closest valid names where there are some).
    line, column : int, optional
        1-based position in the description's text.
    source : str, optional
        Where the text came from when it is not the query itself (a file, the shipped library).

    Examples
    --------
    >>> str(DescriptionError("unknown body part 'rkne'; did you mean 'rknee'?", 1, 1))
    "line 1, column 1: unknown body part 'rkne'; did you mean 'rknee'?"
    """

    def __init__(self, reason: str, line: int | None = None, column: int | None = None, source: str | None = None):
        self.reason, self.line, self.column, self.source = reason, line, column, source
        where = ", ".join(x for x in (source, None if line is None else f"line {line}",
                                      None if column is None else f"column {column}") if x)  # fmt: skip
        super().__init__(f"{where}: {reason}" if where else reason)


class ClusterError(MocapvizError, RuntimeError):
    """A sharded search could not get a whole answer from its Dask cluster (a worker died and no other could take
    its shards, or a shard failed twice). Never a partial answer: the message names the shard and what happened."""


class SchedulerError(ClusterError, OSError):
    """A Dask scheduler given by address (``--scheduler ADDRESS``, ``scheduler="tcp://..."``) cannot be used: nothing
    answers there in time, what answers is not a Dask scheduler (a web server, a Dask worker, a silent peer), or it
    has no worker. Raised by :func:`mocapviz.parallel.dask_client` within its ``timeout``; the message starts with
    "cannot reach dask scheduler at ADDRESS". An :class:`OSError` too, as the connection errors it replaces."""


class UsersFileError(MocapvizError, ValueError):
    """The users file of ``mocapviz serve --auth`` (``mocapviz users FILE ...``, :mod:`mocapviz.users`) is missing,
    not JSON, of another format or version, or holds a record that is not a user's; the message names the file."""
