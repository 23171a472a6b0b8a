"""The one stored format of derived files made of arrays: named arrays, a JSON header and the arrays' sha256, in an
``.npz`` (no pickled objects).

save_arrays  arrays + header -> a file, written atomically (:func:`mocapviz.store.atomic_file`); the header gets the
             format's stamp (:func:`mocapviz.store.stamp`) and the sha256 of the arrays (:func:`mocapviz.store.digest`).
load_arrays  the file -> (arrays, header), every check made: readable, the format, its version, the sha256.

Relational indexes (``mocapviz.InvertedIndex``), PCA models (``mocapviz.PCAModel``), motion templates
(``mocapviz.MotionTemplate``) and the markers of C3D documents (``mocapviz-markers``) are stored so; where in a
database is :mod:`mocapviz.db.layout`'s business. A file of the right format but another version (an older
mocapviz's) is stale (:class:`~mocapviz.errors.StaleDataError`, ``mocapviz check`` says "stale"); anything else
that does not read back as written is damaged (:class:`~mocapviz.errors.MotionDBError`); both name the file and
the way out.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import numpy as np

from .. import store
from ..errors import MotionDBError, StaleDataError

__all__ = ["load_arrays", "save_arrays"]


def save_arrays(path: str | os.PathLike, arrays: dict, header: dict, format_name: str, version: int) -> None:
    """Write ``arrays`` and ``header`` to ``path`` atomically (its folder created); an existing file is replaced.

    Parameters
    ----------
    path : str or os.PathLike
        The file (``.npz``).
    arrays : dict
        Name -> np.ndarray (numbers, booleans or text; no objects).
    header : dict
        Anything JSON can hold (other values are written as their ``str``); ``format``, ``version``,
        ``written_by`` and ``sha256`` are added.
    format_name : str
        The format, e.g. ``"mocapviz.InvertedIndex"``.
    version : int
        Its version.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     save_arrays(f"{folder}/x.npz", {"a": np.arange(3)}, {"note": "hi"}, "mocapviz.Example", 1)
    ...     arrays, header = load_arrays(f"{folder}/x.npz", "mocapviz.Example", 1, "example")
    >>> arrays["a"].tolist(), header["note"], header["version"], len(header["sha256"])
    ([0, 1, 2], 'hi', 1, 64)
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {name: np.asarray(a) for name, a in arrays.items()}
    header = {**store.stamp(format_name, version), **header, "sha256": store.digest(arrays)}
    with store.atomic_file(path) as tmp, open(tmp, "wb") as fh:  # (np.savez would add ".npz" to a bare name)
        np.savez(fh, header=np.array(json.dumps(header, default=str)), **arrays)


def load_arrays(path: str | os.PathLike, format_name: str, version: int, what: str,
                rebuild: str = "") -> tuple[dict, dict]:  # fmt: skip
    """The arrays and header of a file written by :func:`save_arrays`, checked.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    format_name : str
        The format it must be.
    version : int
        The version this mocapviz reads.
    what : str
        What the file is, for the messages (``"index"``, ``"motion template"``, ...).
    rebuild : str
        How to write it again, appended to the messages (e.g. "rebuild it with `mocapviz index DB`").

    Returns
    -------
    arrays : dict
        Name -> np.ndarray, in memory.
    header : dict
        As written, with ``format``, ``version``, ``written_by`` and ``sha256``.

    Raises
    ------
    StaleDataError
        The format, another version ("stale: ... version 1 file; this mocapviz reads version 2; REBUILD").
    MotionDBError
        Missing, not an ``.npz`` or unreadable ("not a readable WHAT"), another format, or arrays that differ from
        the sha256 written with them ("the WHAT is damaged").

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     save_arrays(f"{folder}/x.npz", {"a": np.zeros(2)}, {}, "mocapviz.Example", 1)
    ...     try:
    ...         load_arrays(f"{folder}/x.npz", "mocapviz.Example", 2, "example", "write it again")
    ...     except StaleDataError as exc:
    ...         print(str(exc).split(": ", 1)[1])
    stale: a mocapviz.Example version 1 file; this mocapviz reads version 2; write it again
    """
    path = Path(path)
    hint = f"; {rebuild}" if rebuild else ""
    try:
        with open(path, "rb") as fh:  # before np.load, which would read a whole .npy array (or text) first
            if not zipfile.is_zipfile(fh):
                raise ValueError("not an .npz archive")
        with np.load(path, allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
        header = (json.loads(str(arrays.pop("header"))) if "header" in arrays  # (PCAModel version 1: as arrays)
                  else {key: arrays.pop(key).item() for key in ("format", "version") if key in arrays})
    # (RuntimeError: a damaged zip header reads as "encrypted", or as an unknown compression, NotImplementedError)
    except (OSError, ValueError, EOFError, RuntimeError, zipfile.BadZipFile) as exc:
        raise MotionDBError(f"{path}: not a readable {what} ({exc}){hint}") from None
    if isinstance(header, dict) and header.get("format") == format_name and header.get("version") != version:
        raise StaleDataError(f"{path}: stale: a {format_name} version {header.get('version')} file; this mocapviz "
                             f"reads version {version}{hint}")  # fmt: skip
    store.check_format(header, format_name, version, path, rebuild)
    if store.digest(arrays) != header.get("sha256"):
        raise MotionDBError(f"{path}: its arrays differ from those written (sha256): the {what} is damaged{hint}")
    return arrays, header
