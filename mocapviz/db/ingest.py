"""Ingest: motion files read in parallel into new documents of a MotionDB (:meth:`MotionDB.ingest`).

expand_paths    files, folders and glob patterns -> the motion files they name, once each.
file_checksum   the sha256 that identifies a file in a database (an AMC with its ASF).
held_documents  what a database holds, as ingest skips it: each file's sha256 -> its takes held.
read_document   one file (one take of an FBX file) -> a canonical Motion at the target rate, and its document row.
IngestOptions   what an ingest was asked to do (rate, labels, mapping, skip_bad, threads, progress, scheduler).
read_new        the files a database does not hold yet, read on threads or Dask workers, in input order.

A document is a file, or one take of an FBX file: without the load option ``take``, every take of an FBX file
becomes a document (named ``<stem>`` when the file has one take, ``<stem>#<take>`` when it has several; the take in
the column ``fbx_take``, docs/fbx.md); its identity is the file's sha256 and its take, so a file's takes not held
yet are read again and those held are skipped.

Each file is read in an independent task (:func:`read_document` per document), run in chunks of files on threads of this
process or as Dask tasks (``scheduler=``, see :mod:`mocapviz.parallel`) by :func:`mocapviz.parallel.map_ordered`;
the commit is done by :class:`~mocapviz.db.database.MotionDB`, in input order, once every file has been read.
See ``docs/architecture.md`` (the db layer).
"""
from __future__ import annotations

import contextlib
import glob
import hashlib
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .. import errors as errors_module
from ..errors import LabelTableError, MocapFormatError, MocapFormatWarning, MocapvizError, SkeletonMappingError
from ..io import FORMATS, file_format, find_asf, load
from ..io.labels import MAIN_LABEL_COLUMNS, labels_for, read_labels_tsv
from ..motion import Motion
from ..parallel import map_ordered, optional_client, parallelism

__all__ = ["IngestOptions", "ReadJob", "expand_paths", "file_checksum", "held_documents", "read_document", "read_new"]

_CHUNK_MAX_BYTES = 64 << 20  # an ingest task reads at most this many bytes of motion files (or one file)
BASE_COLUMNS = ["doc_id", "name", "path", "format", "start", "n_frames", "fps", "source_fps", "sha256", "label"]
TAKE_COLUMN = "fbx_take"  # the take of an FBX file's document (a label-like column: missing for other formats)
_BASE_COLUMNS = BASE_COLUMNS


def expand_paths(paths) -> list[Path]:
    """Motion files named by ``paths``: files, folders (searched recursively) and glob patterns.

    What is picked, by the name's ending as :func:`mocapviz.io.file_format` reads it (``.amc``, ``.bvh``, ``.c3d``,
    any case):

    - a file named: always (``load`` reads ``....bvh`` or ``.x.bvh`` as BVH, or says what is wrong with it);
    - a folder: its motion files at any depth, except hidden ones: a name starting with a dot, of the file or of a
      folder below the one given (``.x.bvh``, ``....bvh``, macOS's ``._x.bvh``, ``.git/``, a writer's ``.x.tmp``);
    - a glob pattern: its motion files, hidden ones only where the pattern's part starts with a dot (glob's rule).

    Parameters
    ----------
    paths : str, os.PathLike or list of them
        Files, folders and glob patterns (``**`` recursive).

    Returns
    -------
    list of pathlib.Path
        The absolute paths of the motion files, folders' contents sorted, duplicates removed.

    Raises
    ------
    FileNotFoundError
        A path that does not exist, a folder that holds no motion file, a pattern that matches none (the message
        says which).

    Examples
    --------
    >>> from mocapviz.io import datasets
    >>> files = expand_paths(datasets.sample() / "hdm05-cut")
    >>> len(files), files[0].name
    (22, 'HDM_dg_depositFloorR_013_120.amc')
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    out: list[Path] = []
    for p in paths:
        p = os.fspath(p)
        if os.path.isdir(p):
            found = sorted(f for f in Path(p).rglob("*") if file_format(f) in FORMATS and f.is_file()
                           and not any(part.startswith(".") for part in f.relative_to(p).parts))
        elif os.path.isfile(p):
            found = [Path(p)]
        else:
            found = sorted(Path(f) for f in glob.glob(p, recursive=True) if file_format(f) in FORMATS
                           and os.path.isfile(f))
        if not found:
            raise FileNotFoundError(_nothing_found(p))
        out += [f.resolve() for f in found]
    return list(dict.fromkeys(out))


def _nothing_found(p: str) -> str:
    """Why the path or pattern ``p`` names no motion file: it does not exist, or holds or matches none."""
    formats = f"{', '.join(FORMATS[:-1])} or {FORMATS[-1]}"
    if os.path.isdir(p):
        return f"{p}: no {formats} files in this folder (names starting with a dot are not searched)"
    if glob.has_magic(p):
        return f"{p}: no {formats} file matches this pattern"
    return f"{p}: does not exist" if not os.path.lexists(p) else f"{p}: neither a file nor a folder"


def file_checksum(path, asf=None) -> str:
    """sha256 of a motion file's bytes (an AMC together with its ASF skeleton: ``asf`` or :func:`find_asf`).

    Parameters
    ----------
    path : str or os.PathLike
        An ``.amc`` or ``.bvh`` file.
    asf : str or os.PathLike, optional
        An AMC's skeleton (default :func:`mocapviz.io.find_asf`).

    Returns
    -------
    str
        64 hex digits: the file's identity in a MotionDB (``documents.sha256``).
    """
    h = hashlib.sha256()
    parts = [Path(path)]
    if file_format(path) == ".amc":
        parts.append(Path(asf) if asf is not None else find_asf(path))
    for part in parts:
        try:
            with open(part, "rb") as fh:
                for chunk in iter(lambda: fh.read(1 << 20), b""):
                    h.update(chunk)
        except OSError as exc:  # unreadable or vanished since it was listed: a file to skip under --skip-bad
            raise MocapFormatError(part, f"cannot read the file ({exc.strerror or exc})") from None
    return h.hexdigest()


def held_documents(documents: pd.DataFrame) -> dict[str, set]:
    """What a database holds, as ingest skips it: the sha256 of each document's file -> the takes held of it.

    A document's identity is its file's sha256 and, for an FBX file's take, the take (column ``fbx_take``); a
    document without a take (another format, or an FBX file ingested before documents recorded their take) holds
    its whole file: its take is None.

    Parameters
    ----------
    documents : pandas.DataFrame
        ``db.documents``.

    Returns
    -------
    dict
        sha256 -> set of takes (str), or {None} for a file held whole.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> docs = MotionDB.sample().documents
    >>> held = held_documents(docs)
    >>> len(held) == len(docs), held[docs["sha256"].iloc[0]]
    (True, {None})
    """
    takes = documents[TAKE_COLUMN] if TAKE_COLUMN in documents else [None] * len(documents)
    held: dict[str, set] = {}
    for sha256, take in zip(documents["sha256"], takes):
        held.setdefault(sha256, set()).add(None if pd.isna(take) else str(take))
    return held


def read_document(path, fps: float | None = None, labels: dict | None = None, mapping: dict | None = None,
                  sha256: str | None = None, name: str | None = None, markers_only: str = "refuse",
                  **load_options) -> tuple[Motion, dict]:
    """One ingest task: read a file (one take of an FBX file), map it to the canonical skeleton, resample, describe it.

    Parameters
    ----------
    path : str or os.PathLike
    fps : float, optional
        Target frame rate; default: keep the file's.
    labels : dict, optional
        Labels of this file; default :func:`mocapviz.io.labels.labels_for` (label tables beside the data).
    mapping : dict, optional
        Canonical joint -> joint name, overriding the automatic mapping.
    sha256 : str, optional
        The file's :func:`file_checksum`, if the caller has it already.
    name : str, optional
        The document's name; default the file's name without its extension.
    markers_only : {"refuse", "keep"}
        A C3D file whose markers match no marker set: refused (SkeletonMappingError), or kept as it was read (a
        marker-only document, :mod:`mocapviz.db.marker_documents`: at the file's rate, NaN in gaps).
    **load_options
        Passed to :func:`mocapviz.load` (``take``: the FBX take to read, default the file's first).

    Returns
    -------
    motion : Motion
        Canonical joints, at ``fps``; or, for a marker-only document, the markers.
    meta : dict
        name, path, format, n_frames, fps, source_fps, sha256, the labels, for an FBX file ``fbx_take``: the
        take read; ``markers_only`` True for a marker-only document.
    """
    path = Path(path)
    motion = load(path, **load_options)
    source_fps = motion.fps
    take = motion.labels.get("take") if file_format(path) == ".fbx" else None
    try:
        motion = motion.canonical(mapping)
    except SkeletonMappingError:
        if markers_only != "keep" or file_format(path) != ".c3d" or not np.isfinite(motion.positions).all(axis=2).any():
            raise  # (a file whose markers are never seen has nothing to keep)
        only = {"markers_only": True}
    else:
        only = {}
        if fps is not None:
            motion = motion.resample(fps)
    labels = labels_for(path) if labels is None else dict(labels)
    meta = {
        "name": path.stem if name is None else name,
        "path": str(path),
        "format": file_format(path).lstrip("."),
        "n_frames": motion.n_frames,
        "fps": motion.fps,
        "source_fps": source_fps,
        "sha256": sha256 or file_checksum(path, load_options.get("asf")),
        "label": labels.pop("label", None),
        **{k: v for k, v in labels.items() if k not in _BASE_COLUMNS},
        **only,
    }
    if take is not None:
        meta[TAKE_COLUMN] = take
    return motion, meta


@dataclass(frozen=True)
class _ReadFailure:
    """A file that failed to read, as a task returns it (MocapFormatError itself does not survive pickling)."""

    kind: str  # the class name of the typed error (mocapviz.errors)
    message: str
    path: str | None = None
    reason: str = ""
    line: int | None = None

    @classmethod
    def of(cls, exc: MocapvizError) -> _ReadFailure:
        if isinstance(exc, MocapFormatError):
            return cls("MocapFormatError", str(exc), exc.path, exc.reason, exc.line)
        return cls(type(exc).__name__, str(exc))

    def error(self) -> Exception:
        """The exception the reader raised, rebuilt (same type and message)."""
        if self.kind == "MocapFormatError":
            return MocapFormatError(self.path, self.reason, self.line)
        return getattr(errors_module, self.kind, MocapvizError)(self.message)


@dataclass(frozen=True)
class ReadJob:
    """One file to read in an ingest (small and picklable: a Dask task carries a chunk of these).

    Parameters
    ----------
    path : str
        The motion file.
    sha256 : str
        Its :func:`file_checksum`.
    fps : float or None
        The target frame rate (None: the file's own).
    labels : dict or None
        Its label columns, if known.
    mapping : dict or None
        Canonical joint -> joint name overrides.
    load_options : dict
        Passed to :func:`mocapviz.io.load`.
    held : frozenset of str
        The takes of this (FBX) file the database holds already (not read again).
    markers_only : {"refuse", "keep"}
        A C3D file that matches no marker set (:func:`read_document`).
    """

    path: str
    sha256: str
    fps: float | None
    labels: dict | None
    mapping: dict | None
    load_options: dict
    held: frozenset = frozenset()
    markers_only: str = "refuse"


def _documents_of(job: ReadJob) -> list[tuple[str | None, str | None]]:
    """(take, name) of each document to read from ``job``'s file: ``(None, None)`` for a file of another format (one
    document, named after the file); for an FBX file the take the load option ``take`` asks for, else each take the
    database does not hold, named ``<stem>`` when the file has one take, ``<stem>#<take>`` when it has several."""
    if file_format(job.path) != ".fbx":
        return [(None, None)]
    from ..io.fbx import take_names  # here, not at import: opening a MotionDB loads no reader

    takes = take_names(job.path)
    asked = job.load_options.get("take")
    stem = Path(job.path).stem
    return [(take, stem if len(takes) == 1 else f"{stem}#{take}")
            for take in ([asked] if asked is not None else takes) if take not in job.held]  # fmt: skip


def _read_task(job: ReadJob) -> list[tuple[np.ndarray, np.ndarray | None, dict, list[tuple]]] | _ReadFailure:
    """Reading one file (on a thread of this process or a Dask worker): each of its documents (:func:`_documents_of`).

    Returns, per document, (positions [shape=(T, 24, 3)] cm, quaternions [shape=(T, 24, 4)] or None, meta) of
    :func:`read_document` and its format warnings (``(path, reason, line)`` of each
    :class:`~mocapviz.errors.MocapFormatWarning`, for the caller to issue, naming the file); or a
    :class:`_ReadFailure` for a file that fails to read (any of its takes), so that the caller decides (raise it,
    or skip the file with ``skip_bad``).
    """
    from ..io.checks import collect_format_warnings  # here, not at import: opening a MotionDB loads no reader

    out = []
    try:
        for take, name in _documents_of(job):
            options = job.load_options if take is None else {**job.load_options, "take": take}
            with collect_format_warnings() as notes:
                motion, meta = read_document(job.path, job.fps, job.labels, job.mapping, job.sha256, name,
                                             job.markers_only, **options)
            if meta.get("markers_only"):
                meta["markers"] = list(motion.joint_names)
            out.append((motion.positions, motion.quaternions, meta, notes))
    except MocapvizError as exc:  # a malformed file, an unmappable rig, a bad label file beside the data, ...
        return _ReadFailure.of(exc)
    return out


def _read_chunk(chunk: list[ReadJob]) -> list:
    """An ingest task: :func:`_read_task` of each file of a chunk, in order (files fail one by one)."""
    return [_read_task(job) for job in chunk]


def _chunks(todo: list[ReadJob], parts: int, max_bytes: int = _CHUNK_MAX_BYTES) -> list[list[ReadJob]]:
    """``todo`` cut into about ``parts`` contiguous chunks of similar size on disk, none above ``max_bytes`` unless it
    is one file: a task per file costs more than reading a small file."""
    sizes = np.array([os.path.getsize(job.path) for job in todo], dtype=np.float64)
    target = min(max(sizes.sum() / max(1, parts), 1.0), max_bytes)
    out, chunk, held = [], [], 0.0
    for job, size in zip(todo, sizes):
        if chunk and held + size > target:
            out.append(chunk)
            chunk, held = [], 0.0
        chunk.append(job)
        held += size
    if chunk:
        out.append(chunk)
    return out


def _labels_table(labels) -> dict[str, dict] | None:
    """Labels given to ingest -> {absolute path or file name: {column: value}}."""
    if labels is None:
        return None
    if isinstance(labels, dict):
        return {str(k): dict(v) for k, v in labels.items()}
    if isinstance(labels, (str, os.PathLike)):
        p = Path(labels)
        if not p.is_file():
            raise FileNotFoundError(f"{p}: no such label table")
        table = read_labels_tsv(p) if p.suffix.lower() in (".tsv", ".txt") else pd.read_csv(p)
        if "path" not in table:
            table["path"] = [str((p.parent / f).resolve()) for f in table["file"]]
    else:
        table = pd.DataFrame(labels)
    if "file" not in table and "path" not in table:
        raise LabelTableError("a label table needs a 'file' or 'path' column")
    out = {}
    for row in table.to_dict("records"):
        key = row.pop("path", None) or row.get("file")
        row.pop("file", None)
        row = {k: v for k, v in row.items() if not (isinstance(v, float) and np.isnan(v))}
        if row.get("label") is None:  # the main class, as labels_for gives it for tables found automatically
            row["label"] = next((row[c] for c in MAIN_LABEL_COLUMNS if c in row), None)
        out[str(Path(key).resolve()) if os.path.isabs(str(key)) else str(key)] = row
        out.setdefault(Path(str(key)).name, row)
    return out


@dataclass(frozen=True)
class IngestOptions:
    """What an ingest was asked to do (the parameters of :meth:`MotionDB.ingest`, checked there).

    Parameters
    ----------
    fps : float, optional
        The target frame rate.
    labels : path, DataFrame or dict, optional
        A label table.
    mapping : dict, optional
        Canonical joint -> joint name overrides.
    skip_bad : bool
        Skip files that fail to read.
    threads : int, optional
        Reader threads.
    progress : bool
        Show a progress bar.
    scheduler : None, "local", str or dask.distributed.Client
        Read as Dask tasks.
    load_options : dict
        Passed to :func:`mocapviz.io.load`. (See :meth:`mocapviz.db.database.MotionDB.ingest` for each in full.)
    markers_only : {"refuse", "keep"}
        A C3D file whose markers match no marker set: refused, or kept as a marker-only document.
    """

    fps: float | None = None
    labels: object = None
    mapping: dict | None = None
    skip_bad: bool = False
    threads: int | None = None
    progress: bool = True
    scheduler: object = None
    load_options: dict = field(default_factory=dict)
    markers_only: str = "refuse"


def read_new(files: list[Path], known: dict, options: IngestOptions) -> tuple[list, list, list[dict]]:
    """Read the documents of ``files`` that ``known`` does not hold, in parallel, results in input order.

    Parameters
    ----------
    files : list of pathlib.Path
        Motion files (:func:`expand_paths`).
    known : dict
        What the database holds (:func:`held_documents`): a file held whole is skipped; of an FBX file, the takes
        held are (the file is listed for its other takes).
    options : IngestOptions
        ``fps`` is the rate to resample to (already reconciled with the database's).

    Returns
    -------
    positions, quaternions : list of np.ndarray
        Per new document: (T, 24, 3) float32 cm and (T, 24, 4) float32 or None; for a marker-only document (its
        meta's ``markers_only``, with ``markers``: its labels) the markers (T, M, 3), NaN in gaps, and None.
    metas : list of dict
        Per new document: its row (:func:`read_document`), a file's documents in the order of its takes.

    Raises
    ------
    MocapFormatError, SkeletonMappingError, ...
        The first file (in input order) that fails to read, unless ``options.skip_bad`` (then a warning).

    Warns
    -----
    MocapFormatWarning
        Each file read with a part left out (an AMC cut off inside its last frame), in input order, naming the file
        and line (read on threads or Dask workers, the warnings of each file are collected there and issued here).
    """
    table = _labels_table(options.labels)
    load_options = options.load_options
    todo = []
    for f in files:
        try:
            sha256 = file_checksum(f, load_options.get("asf"))
        except MocapFormatError as exc:  # e.g. an AMC without its ASF
            if not options.skip_bad:
                raise
            warnings.warn(f"skipped {exc}", stacklevel=3)
            continue
        held = known.get(sha256, set())
        if None in held or load_options.get("take") in held:
            continue
        labels = None if table is None else table.get(str(f), table.get(f.name, {}))
        todo.append(ReadJob(str(f), sha256, options.fps, labels, options.mapping, load_options, frozenset(held),
                            options.markers_only))
    positions, quaternions, metas = [], [], []
    with optional_client(options.scheduler if todo else None) as client:
        chunks = _chunks(todo, 4 * parallelism(options.threads, client))
        results = map_ordered(_read_chunk, chunks, options.threads, client, name="mocapviz-read")
        from tqdm.auto import tqdm  # here, not at import: opening a MotionDB does not load it

        bar = tqdm(total=len(todo), desc="ingest", unit="file", disable=not options.progress or not todo)
        # results in input order; the first file that fails (in that order) stops the run before any write, and
        # closing the results cancels what is pending (before the client closes)
        with bar, contextlib.closing(results):
            for res in (res for chunk in results for res in chunk):
                bar.update()
                if isinstance(res, _ReadFailure):
                    if not options.skip_bad:
                        raise res.error()
                    warnings.warn(f"skipped {res.message}", stacklevel=3)
                    continue
                for document in res:
                    for note in document[3]:
                        warnings.warn(MocapFormatWarning(*note), stacklevel=3)
                    positions.append(document[0])
                    quaternions.append(document[1])
                    metas.append(document[2])
    return positions, quaternions, metas
