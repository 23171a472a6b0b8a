"""The raw marker trajectories of documents read from C3D files, kept with the MotionDB beside their joints.

A C3D document's joints are estimates (:mod:`mocapviz.motion.markers`); the markers they were made from are stored
too, so that nothing the file held is lost when the file is gone: one ``.npz`` per document under ``DB/markers/``,
named by the file's checksum (the document's ``sha256``, :func:`mocapviz.db.layout.markers_file`), at the file's own
rate, written atomically with a format header and a checksum of its arrays (:mod:`mocapviz.db.arrays`). Gaps are
stored as a mask, not as NaN (no non-finite value is stored), and come back as NaN.

store_markers   read the C3D documents' files once more and store their markers (ingest does it for new ones).
load_markers    a document's markers as a marker Motion (NaN in gaps), checked against its checksum.
has_markers     whether a document's markers are stored.
save_markers    write a marker Motion (also the marker-only documents', :mod:`mocapviz.db.marker_documents`).
read_markers    read one back.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import store
from ..errors import MotionDBError
from ..motion import Motion
from .arrays import load_arrays, save_arrays
from .layout import markers_file

__all__ = ["has_markers", "load_markers", "markers_path", "read_markers", "save_markers", "store_markers"]

FORMAT, VERSION = "mocapviz-markers", 1
_REBUILD = "delete it and store the markers again from the C3D file (mocapviz.db.markers.store_markers)"


def markers_path(db, doc_id: int) -> Path:
    """Where document ``doc_id``'s markers are stored: ``DB/markers/<sha256 of its file>.npz``."""
    return markers_file(db.path, db.document(doc_id)["sha256"])


def has_markers(db, doc_id: int) -> bool:
    """Whether document ``doc_id``'s markers are stored (C3D documents, once :func:`store_markers` ran)."""
    return markers_path(db, doc_id).is_file()


def store_markers(db, doc_ids=None) -> list[Path]:
    """Store the markers of C3D documents whose markers are not stored yet, read again from their files.

    Parameters
    ----------
    db : MotionDB
    doc_ids : sequence of int, optional
        The documents to consider (default all); documents not read from a ``.c3d`` file are skipped.

    Returns
    -------
    list of pathlib.Path
        The files written.

    Raises
    ------
    MotionDBError
        A C3D document whose file is gone or is not the file that was ingested (its checksum differs).
    """
    from ..io.c3d import read_c3d
    from .ingest import file_checksum

    docs = db.documents if doc_ids is None else db.documents[db.documents["doc_id"].isin(list(doc_ids))]
    written = []
    for row in docs[docs["format"] == "c3d"].itertuples():
        target = markers_path(db, row.doc_id)
        if target.is_file():
            continue
        path = Path(row.path)
        if not path.is_file() or file_checksum(path) != row.sha256:
            raise MotionDBError(f"{path}: the C3D file of document {row.doc_id} ({row.name}) is gone or changed since "
                                "it was ingested; its markers cannot be stored")  # fmt: skip
        motion = read_c3d(path)
        target.parent.mkdir(exist_ok=True)
        with store.locked(target.parent):
            save_markers(target, motion, row.name)
        written.append(target)
    return written


def save_markers(target: Path, motion: Motion, doc_name: str) -> None:
    """Write a marker Motion to ``target`` atomically, positions with gaps as a mask (the caller holds the markers
    folder's lock, :func:`mocapviz.store.locked`).

    Parameters
    ----------
    target : pathlib.Path
        ``DB/markers/<sha256>.npz`` (:func:`mocapviz.db.layout.markers_file`).
    motion : Motion
        A marker Motion [shape=(T, M, 3)], cm, NaN in gaps.
    doc_name : str
        The document's name, kept in the header.
    """
    present = np.isfinite(motion.positions).all(axis=2)
    arrays = {"positions": np.where(present[..., None], motion.positions, 0.0).astype(np.float32),
              "present": present}  # fmt: skip
    header = {"doc_name": doc_name, "source": str(motion.source), "fps": motion.fps,
              "markers": list(motion.joint_names), "labels": motion.labels}  # fmt: skip
    save_arrays(target, arrays, header, FORMAT, VERSION)


def load_markers(db, doc_id: int) -> Motion:
    """Document ``doc_id``'s stored markers.

    Parameters
    ----------
    db : MotionDB
    doc_id : int

    Returns
    -------
    Motion
        The marker Motion as :func:`mocapviz.io.c3d.read_c3d` read it: positions [shape=(T, M, 3)] float32 in cm,
        y up, NaN in gaps, at the file's own rate; ``joint_names`` the marker labels; ``source`` the file.

    Raises
    ------
    MotionDBError
        No markers stored for the document (not a C3D document), or the file is damaged (format, checksum).
    """
    path = markers_path(db, doc_id)
    what = f"document {doc_id} ({db.document(doc_id)['name']})"
    if not path.is_file():
        raise MotionDBError(f"{db.path}: no markers stored for {what}: only documents read from C3D files have "
                            "them (stored at ingest, or by mocapviz.db.markers.store_markers)")  # fmt: skip
    return read_markers(path, what)


def read_markers(path: Path, what: str) -> Motion:
    """The marker Motion stored in ``path`` by :func:`save_markers` (NaN in gaps), checked against its checksum;
    ``what``: the document, for the messages (MotionDBError when damaged)."""
    arrays, header = load_arrays(path, FORMAT, VERSION, f"markers file of {what}", _REBUILD)
    positions = np.where(arrays["present"][..., None], arrays["positions"], np.nan).astype(np.float32)
    n = positions.shape[1]
    return Motion(positions=positions, fps=float(header["fps"]), joint_names=tuple(header["markers"]),
                  parents=np.full(n, -1, dtype=np.int64), source=header["source"],
                  labels=header.get("labels", {}))  # fmt: skip
