"""The folder of a MotionDB: where each of its files is. The one module that names them; every other asks here.

::

    DB/manifest.json                        manifest_file
    DB/positions.g<G>.npy                   generation_file(DB, "positions", G)      (and generation_of a name)
    DB/quaternions.g<G>.npy                 generation_file(DB, "quaternions", G)
    DB/documents.g<G>.parquet               generation_file(DB, "documents", G)
    DB/index/relational-<set>-<group>.npz   index_file; index_files         (mocapviz.relational.index)
    DB/features/numeric-<set>.npy           numeric_data; numeric_sets      (mocapviz.features.numeric)
    DB/features/numeric-<set>.json          numeric_header
    DB/features/pca.npz                     pca_file
    DB/templates/<name>.npz                 template_file; template_files   (mocapviz.relational.templates)
    DB/markers/<sha256 of the file>.npz     markers_file; markers_files     (mocapviz.db.markers)
    DB/markers/documents.json               marker_documents_file           (mocapviz.db.marker_documents)
    DB/labels/changes.json                  labels_file                     (mocapviz.db.segments)

The folders (``index_folder``, ``features_folder``, ``templates_folder``, ``markers_folder``,
``labels_folder``) are created by the writers and hold the lock of their files (:func:`mocapviz.store.locked`).
The ``.npz`` files are written and read by :mod:`mocapviz.db.arrays`.

Examples
--------
>>> index_file("DB", "2005", "lower").as_posix(), pca_file("DB").as_posix()
('DB/index/relational-2005-lower.npz', 'DB/features/pca.npz')
>>> generation_file("DB", "documents", 3).name, generation_of("positions.g3.npy"), generation_of("pca.npz")
('documents.g3.parquet', 3, None)
"""

from __future__ import annotations

import os
import re
from pathlib import Path

__all__ = [
    "features_folder", "generation_file", "generation_of", "index_file", "index_files", "index_folder",
    "labels_file", "labels_folder", "manifest_file", "marker_documents_file", "markers_file", "markers_files", "markers_folder",
    "numeric_data", "numeric_header", "numeric_sets", "pca_file", "template_file", "template_files", "templates_folder",
]  # fmt: skip

_GENERATION = re.compile(r"(?:positions|quaternions|documents)\.g(?P<generation>\d+)\.(?:npy|parquet)")
_INDEX = re.compile(r"relational-(?P<set>[^-]+)-[^-]+\.npz")


def manifest_file(db_path: str | os.PathLike) -> Path:
    """``DB/manifest.json``: the database's manifest (its presence makes a folder a MotionDB)."""
    return Path(db_path) / "manifest.json"


def generation_file(db_path: str | os.PathLike, what: str, generation: int) -> Path:
    """The file of one generation of the frames or the documents table.

    Parameters
    ----------
    db_path : str or os.PathLike
        The database folder.
    what : {"positions", "quaternions", "documents"}
        The frame array or the documents table.
    generation : int
        The manifest's generation.

    Returns
    -------
    pathlib.Path
        ``DB/<what>.g<generation>.npy`` (``.parquet`` for the documents table).
    """
    return Path(db_path) / f"{what}.g{generation}.{'parquet' if what == 'documents' else 'npy'}"


def generation_of(name: str) -> int | None:
    """The generation of a file named by :func:`generation_file` (``name`` a plain file name), else None."""
    found = _GENERATION.fullmatch(name)
    return int(found["generation"]) if found else None


def index_folder(db_path: str | os.PathLike) -> Path:
    """``DB/index/``: the relational indexes."""
    return Path(db_path) / "index"


def index_file(db_path: str | os.PathLike, relational_set: str, group: str) -> Path:
    """``DB/index/relational-<set>-<group>.npz``: the inverted index of one feature group of a relational set."""
    return index_folder(db_path) / f"relational-{relational_set}-{group}.npz"


def index_files(db_path: str | os.PathLike) -> dict[Path, str]:
    """The ``.npz`` files of ``DB/index/`` in name order, each with its relational set (``"2005"`` for a name
    :func:`index_file` does not give: an older release's)."""
    return {f: found["set"] if (found := _INDEX.fullmatch(f.name)) else "2005"
            for f in sorted(index_folder(db_path).glob("*.npz"))}  # fmt: skip


def features_folder(db_path: str | os.PathLike) -> Path:
    """``DB/features/``: the numeric feature sets and the PCA model."""
    return Path(db_path) / "features"


def numeric_data(db_path: str | os.PathLike, numeric_set: str) -> Path:
    """``DB/features/numeric-<set>.npy``: the values of a numeric feature set, (N, d) float32."""
    return features_folder(db_path) / f"numeric-{numeric_set}.npy"


def numeric_header(db_path: str | os.PathLike, numeric_set: str) -> Path:
    """``DB/features/numeric-<set>.json``: the header of :func:`numeric_data` (what it was computed for)."""
    return features_folder(db_path) / f"numeric-{numeric_set}.json"


def numeric_sets(db_path: str | os.PathLike) -> list[str]:
    """The numeric sets whose header (:func:`numeric_header`) is stored, in name order."""
    return [f.stem.removeprefix("numeric-") for f in sorted(features_folder(db_path).glob("numeric-*.json"))]


def pca_file(db_path: str | os.PathLike) -> Path:
    """``DB/features/pca.npz``: the PCA model of the database's Fp sets."""
    return features_folder(db_path) / "pca.npz"


def templates_folder(db_path: str | os.PathLike) -> Path:
    """``DB/templates/``: the stored motion templates."""
    return Path(db_path) / "templates"


def template_file(db_path: str | os.PathLike, name: str) -> Path:
    """``DB/templates/<name>.npz`` (``name`` a filename-safe name: checked by the caller)."""
    return templates_folder(db_path) / f"{name}.npz"


def template_files(db_path: str | os.PathLike) -> dict[str, Path]:
    """The stored templates, name -> :func:`template_file`, in name order."""
    return dict(sorted((f.stem, f) for f in templates_folder(db_path).glob("*.npz")))


def markers_folder(db_path: str | os.PathLike) -> Path:
    """``DB/markers/``: the raw markers of C3D documents."""
    return Path(db_path) / "markers"


def markers_file(db_path: str | os.PathLike, sha256: str) -> Path:
    """``DB/markers/<sha256>.npz``: the markers of the document read from the file of that checksum."""
    return markers_folder(db_path) / f"{sha256}.npz"


def markers_files(db_path: str | os.PathLike) -> dict[str, Path]:
    """The stored markers, the checksum of their file -> :func:`markers_file`, in name order."""
    return dict(sorted((f.stem, f) for f in markers_folder(db_path).glob("*.npz")))


def marker_documents_file(db_path: str | os.PathLike) -> Path:
    """``DB/markers/documents.json``: the table of the marker-only documents (:mod:`mocapviz.db.marker_documents`)."""
    return markers_folder(db_path) / "documents.json"


def labels_folder(db_path: str | os.PathLike) -> Path:
    """``DB/labels/``: the segment labels (its lock serialises their writers)."""
    return Path(db_path) / "labels"


def labels_file(db_path: str | os.PathLike) -> Path:
    """``DB/labels/changes.json``: the log of every change to the segment labels (:mod:`mocapviz.db.segments`)."""
    return labels_folder(db_path) / "changes.json"
