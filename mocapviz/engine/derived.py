"""The derived data stored with a MotionDB (relational indexes, numeric feature sets) brought up to date after an
ingest, incrementally: an ingest only appends documents, and every feature of a frame reads its own document only,
so the stored data of the old documents stay as they are and only the new documents' frames are computed and
appended (:func:`mocapviz.relational.index.extend`, :func:`mocapviz.features.numeric.extend_numeric`); the result
equals a rebuild of the whole database. ``mocapviz ingest`` runs :func:`update_derived` after its commit, so that a
lab's one command leaves the database, its indexes and feature sets current (and a server following it,
:class:`mocapviz.app.backend.Backend`, finds them so).

stored_sets     the relational and numeric sets stored with a MotionDB.
update_derived  each stored set: current, extended with the documents appended since, or rebuilt.
"""
from __future__ import annotations

import json
import time

import pandas as pd

from ..db import layout
from ..db.database import MotionDB
from ..errors import MotionDBError

__all__ = ["stored_sets", "update_derived"]

UPDATE_COLUMNS = ("kind", "set", "how", "documents", "frames", "seconds")


def stored_sets(db: MotionDB) -> dict[str, list[str]]:
    """The sets whose derived data are stored with ``db``: ``{"relational": [...], "numeric": [...]}``, each in
    name order (an index of any group counts for its set)."""
    return {"relational": sorted(set(layout.index_files(db.path).values())), "numeric": layout.numeric_sets(db.path)}


def update_derived(db: MotionDB, relational_sets=None, numeric_sets=None, progress: bool = False,
                   rebuild: bool = True) -> pd.DataFrame:  # fmt: skip
    """Bring the stored derived data of ``db`` up to date: each set current already, or extended with the documents
    appended since it was stored (only their frames computed), or -- when it was not stored for the first documents
    of this database (another database, or stored by a mocapviz before derived data recorded their documents) --
    computed again whole.

    Parameters
    ----------
    db : MotionDB
        The database (its folder writable).
    relational_sets, numeric_sets : sequence of str, optional
        The sets to bring up to date (default: those stored, :func:`stored_sets`).
    progress : bool
        Progress bars while features are computed.
    rebuild : bool
        Compute a set that cannot be extended again whole (default); False leaves it as it is ("left").

    Returns
    -------
    pandas.DataFrame
        One row per set: ``kind`` ("relational index" or "numeric set"), ``set``, ``how`` ("current", "extended",
        "rebuilt" or "left"), ``documents`` and ``frames`` computed (the new ones when extended), ``seconds``.

    Examples
    --------
    >>> import tempfile
    >>> from mocapviz.io import datasets
    >>> from mocapviz.relational.index import build
    >>> amc = sorted((datasets.sample() / "hdm05-cut" / "amc").glob("*.amc"))
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     db = MotionDB.ingest(amc[:3], f"{tmp}/db.mdb", progress=False)
    ...     _ = build(db, progress=False)
    ...     db = db.append(amc[3:4], progress=False)
    ...     print(update_derived(db)[["kind", "set", "how", "documents"]].to_string(index=False))
                kind  set      how  documents
    relational index 2005 extended          1
    """
    from ..features.numeric import default_pca, extend_numeric, load_numeric, store_numeric
    from ..relational.index import build, extend, load

    sets = stored_sets(db)
    relational_sets = sets["relational"] if relational_sets is None else list(relational_sets)
    numeric_sets = sets["numeric"] if numeric_sets is None else list(numeric_sets)
    rows = []
    for name in relational_sets:
        rows.append(_updated(db, "relational index", name, lambda name=name: load(db, name),
                             lambda name=name: extend(db, name, progress=progress),
                             lambda name=name: build(db, name, progress=progress), rebuild))  # fmt: skip
    for name in numeric_sets:
        pca = (lambda: default_pca(db, progress)) if name.startswith("Fp") else (lambda: None)
        rows.append(_updated(db, "numeric set", name, lambda name=name: load_numeric(db, name),
                             lambda name=name: extend_numeric(db, name, progress=progress),
                             lambda name=name, pca=pca: store_numeric(db, name, pca=pca(), progress=progress),
                             rebuild))  # fmt: skip
    return pd.DataFrame(rows, columns=list(UPDATE_COLUMNS))


def _updated(db: MotionDB, kind: str, name: str, load, extend, build, rebuild: bool) -> dict:
    """One row of :func:`update_derived`: ``load()`` (current), else ``extend()``, else ``build()`` (or left)."""
    t0 = time.perf_counter()
    before = _covered(db, kind, name)
    try:
        load()
        how = "current"
    except MotionDBError:
        try:
            extend()
            how = "extended"
        except MotionDBError:
            if rebuild:
                build()
            how = "rebuilt" if rebuild else "left"
    documents, frames = {"current": (0, 0), "left": (0, 0), "rebuilt": (len(db), db.n_frames),
                         "extended": (len(db) - before[0], db.n_frames - before[1])}[how]  # fmt: skip
    return {"kind": kind, "set": name, "how": how, "documents": documents, "frames": frames,
            "seconds": time.perf_counter() - t0}  # fmt: skip


def _covered(db: MotionDB, kind: str, name: str) -> tuple[int, int]:
    """(documents, frames) the stored data of a set record that they cover ((0, 0) when unreadable)."""
    from ..relational.index import InvertedIndex

    try:
        if kind == "numeric set":
            record = json.loads(layout.numeric_header(db.path, name).read_text())
        else:
            record = InvertedIndex.load(next(f for f, s in layout.index_files(db.path).items() if s == name)).meta
        return int(record.get("n_documents") or 0), int(record.get("n_frames") or 0)
    except (MotionDBError, OSError, ValueError, StopIteration):
        return 0, 0
