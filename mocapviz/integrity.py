"""Checking a MotionDB on disk and its derived data, file by file (``mocapviz check DB``).

check   path -> one row per stored file: what it is, whether it reads back exactly as written, and why not.

Every stored file carries a fingerprint written with it: the frame arrays and documents table their size and
sha256 in the manifest, a relational index the sha256 of its arrays in its header, a numeric feature set its data
file's size and sha256 in its header, an Fp set the sha256 of the PCA model it used, a motion template the sha256
of its values in its header, a C3D document's stored markers the sha256 of their arrays in their header. Opening a database checks the sizes (and the documents table's sha256); :func:`check`
reads everything and checks every sha256 (and records the per-block xxh3 of frame arrays written before they were
kept, :meth:`MotionDB.add_block_checksums`); between checks, every block of a frame array or numeric feature set is
verified by its xxh3 when first read in a process (:mod:`mocapviz.checked_map`).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from .db.database import MotionDB
from .errors import MocapvizError, MotionDBError

COLUMNS = ["file", "what", "ok", "detail"]


def check(path) -> pd.DataFrame:
    """Read every file of the MotionDB at ``path`` and its derived data back and compare it with what was written.

    Parameters
    ----------
    path : str or os.PathLike
        The database folder.

    Returns
    -------
    pandas.DataFrame
        One row per file: ``file`` (relative to the database), ``what``, ``ok`` (bool), ``detail`` (the reason
        when not ok: damaged, stale, unreadable). When the database itself does not open, one row saying why.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> report = check(MotionDB.sample().path)
    >>> report[report["what"] == "MotionDB"][["file", "ok"]].values.tolist()  # and a row per derived file stored
    [['positions.g1.npy', True], ['quaternions.g1.npy', True], ['documents.g1.parquet', True]]
    """
    from .features import numeric as numeric_mod
    from .relational.index import InvertedIndex
    from .relational.templates import TEMPLATES, MotionTemplate

    path = Path(path)
    rows = []
    try:
        db = MotionDB.open(path, verify=True).add_block_checksums()
    except MocapvizError as exc:
        return pd.DataFrame([{"file": "manifest.json", "what": "MotionDB", "ok": False, "detail": str(exc)}],
                            columns=COLUMNS)  # fmt: skip
    files = [*db.manifest["arrays"].values(), db.manifest["documents"]]
    rows += [{"file": f, "what": "MotionDB", "ok": True, "detail": ""} for f in files]
    for f in sorted((path / "index").glob("*.npz")):
        rows.append(_row(f, path, "relational index", lambda f=f: _current_index(InvertedIndex.load(f), db, f)))
    features = path / "features"
    for f in sorted(features.glob("numeric-*.json")):
        name = f.stem.removeprefix("numeric-")
        rows.append(_row(f.with_suffix(".npy"), path, f"numeric set {name}",
                         lambda name=name: _numeric(db, name)))  # fmt: skip
    if (features / "pca.npz").exists():
        rows.append(_row(features / "pca.npz", path, "PCA model", lambda: numeric_mod.PCAModel.load(features / "pca.npz")))
    for f in sorted((path / TEMPLATES).glob("*.npz")):
        rows.append(_row(f, path, f"motion template {f.stem}", lambda f=f: MotionTemplate.load(f)))
    by_sha = dict(zip(db.documents["sha256"], db.documents["doc_id"]))
    for f in sorted((path / "markers").glob("*.npz")):
        doc = by_sha.get(f.stem)
        rows.append(_row(f, path, f"markers of document {doc}", lambda doc=doc, f=f: _markers(db, doc, f)))
    return pd.DataFrame(rows, columns=COLUMNS)


def _numeric(db: MotionDB, name: str) -> None:
    from .features import numeric as numeric_mod

    numeric_mod.load_numeric(db, name, full_check=True)
    numeric_mod.add_block_checksums(db, name)  # (a set stored before block hashes were kept)


def _markers(db: MotionDB, doc, f: Path) -> None:
    from .db.markers import load_markers

    if doc is None:
        raise MotionDBError(f"{f}: markers of no document of the database (left from a file no longer in it)")
    load_markers(db, doc)


def _current_index(index, db: MotionDB, f: Path) -> None:
    if (index.meta.get("generation"), index.meta.get("n_frames")) != (db.manifest["generation"], db.n_frames):
        raise MotionDBError(f"{f}: stale: built before the database last changed; rebuild it with `mocapviz index DB`")


def _row(f: Path, root: Path, what: str, read) -> dict:
    try:
        read()
    except MocapvizError as exc:
        return {"file": str(f.relative_to(root)), "what": what, "ok": False, "detail": str(exc)}
    return {"file": str(f.relative_to(root)), "what": what, "ok": True, "detail": ""}
