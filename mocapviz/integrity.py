"""Checking a MotionDB on disk and its derived data, file by file (``mocapviz check DB``).

check             path -> one row per stored file: what it is, "ok", "stale" or "damaged", why, and the command
                  that computes derived data again.
rebuild_commands  the commands that rebuild the derived data of a report that is not ok, one per command.

Every stored file carries a fingerprint written with it: the frame arrays and documents table their size and
sha256 in the manifest, a relational index the sha256 of its arrays in its header, a numeric feature set its data
file's size and sha256 in its header, an Fp set the sha256 of the PCA model it used, a motion template the sha256
of its values in its header, a C3D document's stored markers the sha256 of their arrays in their header. Opening a database checks the sizes (and the documents table's sha256); :func:`check`
reads everything and checks every sha256 (and records the per-block xxh3 of frame arrays written before they were
kept, :meth:`MotionDB.add_block_checksums`); between checks, every block of a frame array or numeric feature set is
verified by its xxh3 when first read in a process (:mod:`mocapviz.checked_map`).

Two ways derived data can be unusable are told apart. **Damaged**: it does not read back as written (size,
checksum, format), or the database itself does not open. **Stale**: it reads back exactly as written but was
computed for an earlier state of the database (another generation or frame count, a PCA model since replaced), or
written in an older version of its format (:mod:`mocapviz.db.arrays`): :class:`~mocapviz.errors.StaleDataError`, as
every index and feature set is after an ingest adds documents; the row names the command that computes it again.
The check reads the database as of its opening: derived data written by a command that ran meanwhile for a newer
generation is compared with the database as it is then (so a check beside a running ingest or ``mocapviz index``
never calls intact data damaged).
"""

from __future__ import annotations

import contextlib
import shlex
from pathlib import Path

import pandas as pd

from .engine import MotionDB, layout
from .errors import MocapvizError, StaleDataError

COLUMNS = ["file", "what", "status", "ok", "detail", "rebuild"]
STATUSES = ("ok", "stale", "damaged")


def check(path) -> pd.DataFrame:
    """Read every file of the MotionDB at ``path`` and its derived data back and compare it with what was written
    and with the database's current state.

    Parameters
    ----------
    path : str or os.PathLike
        The database folder.

    Returns
    -------
    pandas.DataFrame
        One row per file: ``file`` (relative to the database), ``what``, ``status`` (``"ok"``; ``"stale"``:
        intact derived data computed for an earlier state of the database; ``"damaged"``: does not read back as
        written, or unreadable), ``ok`` (``status == "ok"``), ``detail`` (why, when not ok) and ``rebuild`` (for
        derived data that is not ok: the command that computes it again, with this database's path; else
        ``""``). When the database itself does not open, one damaged row saying why.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> report = check(MotionDB.sample().path)
    >>> report[report["what"] == "MotionDB"][["file", "status"]].values.tolist()  # and a row per derived file
    [['positions.g1.npy', 'ok'], ['quaternions.g1.npy', 'ok'], ['documents.g1.parquet', 'ok']]
    """
    from .engine import MotionTemplate, PCAModel

    path = Path(path)
    try:
        db = MotionDB.open(path, verify=True).add_block_checksums()
    except MocapvizError as exc:
        manifest = layout.manifest_file(path).name
        return pd.DataFrame([_row_of(manifest, "MotionDB", "damaged", str(exc))], columns=COLUMNS)
    rows = [_row_of(f, "MotionDB") for f in (*db.manifest["arrays"].values(), db.manifest["documents"])]
    where = shlex.quote(str(path))
    for f, relational_set in layout.index_files(path).items():
        option = "" if relational_set == "2005" else f" --relational-set {relational_set}"
        rows.append(_row(f, path, "relational index", lambda db, f=f: _current_index(f, db),
                         db, f"mocapviz index {where}{option}"))  # fmt: skip
    for name in layout.numeric_sets(path):
        rows.append(_row(layout.numeric_data(path, name), path, f"numeric set {name}",
                         lambda db, name=name: _numeric(db, name), db,
                         f"mocapviz features {where} --numeric-sets {name}"))  # fmt: skip
    pca = layout.pca_file(path)
    if pca.exists():
        rows.append(_row(pca, path, "PCA model", lambda db: PCAModel.load(pca), db))
    for name, f in layout.template_files(path).items():
        rows.append(_row(f, path, f"motion template {name}", lambda db, f=f: MotionTemplate.load(f), db))
    only = {}  # marker-only documents (mocapviz.db.marker_documents): their table, then each one's markers
    if layout.marker_documents_file(path).is_file():
        rows.append(_row(layout.marker_documents_file(path), path, "marker-only documents",
                         lambda db: db.marker_documents, db))  # fmt: skip
        with contextlib.suppress(MocapvizError):  # (a damaged table is the row above)
            only = dict(zip(db.marker_documents.documents["sha256"], db.marker_documents.documents["doc_id"]))
    by_sha = dict(zip(db.documents["sha256"], db.documents["doc_id"]))
    for sha, f in layout.markers_files(path).items():
        if sha in only:
            rows.append(_row(f, path, f"markers of marker-only document {only[sha]}",
                             lambda db, doc=only[sha]: db.marker_documents.motion(doc), db))  # fmt: skip
            continue
        if sha not in by_sha:  # (a document an ingest added since the check opened the database?)
            documents = MotionDB.open(path).documents
            by_sha.update(zip(documents["sha256"], documents["doc_id"]))
        what = f"markers of document {by_sha[sha]}" if sha in by_sha else "markers of no document"
        rows.append(_row(f, path, what, lambda db, f=f, sha=sha: _markers(db, f, sha), db))
    return pd.DataFrame(rows, columns=COLUMNS)


def rebuild_commands(report: pd.DataFrame) -> list[str]:
    """The commands that compute the derived data of a :func:`check` report that is not ok again, each once, the
    numeric sets of one database in one ``mocapviz features`` command.

    Parameters
    ----------
    report : pandas.DataFrame
        As :func:`check` returns it.

    Returns
    -------
    list of str
        In the order of the report.

    Examples
    --------
    >>> report = pd.DataFrame({"ok": [False, False, False], "rebuild": ["mocapviz index DB",
    ...     "mocapviz features DB --numeric-sets F15E", "mocapviz features DB --numeric-sets Fp8"]})
    >>> rebuild_commands(report)
    ['mocapviz index DB', 'mocapviz features DB --numeric-sets F15E,Fp8']
    """
    merged: dict[str, list[str]] = {}
    for command in report.loc[~report["ok"] & (report["rebuild"] != ""), "rebuild"]:
        head, sets = command.split(" --numeric-sets ") if " --numeric-sets " in command else (command, "")
        merged.setdefault(head, [])
        if sets and sets not in merged[head]:
            merged[head].append(sets)
    return [f"{head} --numeric-sets {','.join(sets)}" if sets else head for head, sets in merged.items()]


def _numeric(db: MotionDB, name: str) -> None:
    from .engine import add_block_checksums, load_numeric

    load_numeric(db, name, full_check=True)
    add_block_checksums(db, name)  # (a set stored before block hashes were kept)


def _markers(db: MotionDB, f: Path, sha256: str) -> None:
    """Read the markers file ``f`` back as the markers of the document of ``db`` it belongs to (``sha256``, the
    checksum of the document's file, :func:`mocapviz.db.layout.markers_files`)."""
    from .engine import load_markers

    doc = dict(zip(db.documents["sha256"], db.documents["doc_id"])).get(sha256)
    if doc is None:
        raise StaleDataError(f"{f}: markers of no document of the database (left from a file no longer in it); "
                             "nothing reads it")  # fmt: skip
    load_markers(db, doc)


def _current_index(f: Path, db: MotionDB) -> None:
    from .engine import InvertedIndex

    index = InvertedIndex.load(f)
    built, now = (index.meta.get("generation"), index.meta.get("n_frames")), (db.manifest["generation"], db.n_frames)
    if built != now:
        raise StaleDataError(f"{f}: stale: built for generation {built[0]} ({built[1]} frames); the database is at "
                             f"generation {now[0]} ({now[1]} frames)")  # fmt: skip


def _row(f: Path, root: Path, what: str, read, db: MotionDB, rebuild: str = "") -> dict:
    """The row of one derived file: ``read(db)`` raises nothing (ok), a StaleDataError (stale) or another
    MocapvizError (damaged). Stale against the database as the check opened it may be current against the database
    now (written meanwhile by a command that saw a newer generation): then it is read once more against the
    database as it is now."""
    file = str(f.relative_to(root))
    try:
        try:
            read(db)
        except StaleDataError:
            now = MotionDB.open(root)
            if now.manifest["generation"] == db.manifest["generation"]:
                raise
            read(now)
    except StaleDataError as exc:
        return _row_of(file, what, "stale", str(exc), rebuild)
    except MocapvizError as exc:
        return _row_of(file, what, "damaged", str(exc), rebuild)
    return _row_of(file, what)


def _row_of(file, what: str, status: str = "ok", detail: str = "", rebuild: str = "") -> dict:
    return {"file": str(file), "what": what, "status": status, "ok": status == "ok", "detail": detail,
            "rebuild": rebuild if status != "ok" else ""}  # fmt: skip


__all__ = ["COLUMNS", "STATUSES", "check", "rebuild_commands"]
