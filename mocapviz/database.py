"""MotionDB: many motions on the canonical skeleton, concatenated on disk.

Layout of a MotionDB directory (format version 1)::

    manifest.json                  format, version, generation, frame count, joints, file names
    positions.g<G>.npy             (N, 24, 3) float32, cm, y up -- all frames of all documents
    quaternions.g<G>.npy           (N, 24, 4) float32 local rotations (w, x, y, z); NaN where none
    documents.g<G>.parquet         one row per document: doc_id, name, path, start, n_frames, fps, labels, ...

Every write produces the files of a new generation G under their final names and then replaces
``manifest.json`` atomically (:mod:`mocapviz.store`); readers only follow the manifest. A write that fails or is
killed therefore leaves the previous generation, and the database, exactly as they were. A new database is built
beside its folder and renamed into place complete, so a killed first ingest leaves nothing to clean up.

The manifest records each file's size and sha256: opening checks the sizes and the documents table's sha256,
``MotionDB.open(path, verify=True)`` (``mocapviz check DB``) every sha256, so a damaged file is a MotionDBError
naming it, never an answer. One writer at a time: the writer lock (``.lock``) is held for a whole append (what
is held is read, the files are read, the documents committed), so a second writer waits and then skips what the
first added; a failed first ingest removes only the empty database it created, never what another committed.

Ingest reads each file in an independent task (:func:`read_document`), run in chunks of files on threads of this
process or as Dask tasks (``scheduler=``, see :mod:`mocapviz.cluster`) by :func:`mocapviz.batch.map_ordered`; the
commit is done by the caller, in input order, once every file has been read.
"""
from __future__ import annotations

import contextlib
import glob
import hashlib
import json
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from . import store
from .cluster import optional_client
from .errors import (
    LabelTableError,
    MocapFormatError,
    MocapvizError,
    MotionDBError,
    ParameterError,
    UnknownKeyError,
)
from .io import FORMATS, find_asf, load
from .labels import MAIN_LABEL_COLUMNS, labels_for, read_labels_tsv
from .motion import Motion
from .skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS
from .store import atomic_file, atomic_write, check_format, stamp
from .validation import renamed

FORMAT = "mocapviz.MotionDB"
VERSION = 1
_ARRAYS = {"positions": 3, "quaternions": 4}
_CHUNK_MAX_BYTES = 64 << 20  # an ingest task reads at most this many bytes of motion files (or one file)
_RESTORE = "restore it from a backup or ingest the files again into a new database"
_BASE_COLUMNS = ["doc_id", "name", "path", "format", "start", "n_frames", "fps", "source_fps", "sha256", "label"]


def expand_paths(paths) -> list[Path]:
    """Motion files named by ``paths``: files, folders (searched recursively) and glob patterns.

    Returns the absolute paths of the ``.amc`` / ``.bvh`` files, folders' contents sorted, duplicates removed.

    Raises
    ------
    FileNotFoundError
        A path or pattern that names nothing.
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    out: list[Path] = []
    for p in paths:
        p = os.fspath(p)
        if os.path.isdir(p):
            found = sorted(f for f in Path(p).rglob("*") if f.suffix.lower() in FORMATS and f.is_file())
        elif os.path.isfile(p):
            found = [Path(p)]
        else:
            found = sorted(Path(f) for f in glob.glob(p, recursive=True) if Path(f).suffix.lower() in FORMATS)
        if not found:
            raise FileNotFoundError(f"{p}: no .amc or .bvh files there")
        out += [f.resolve() for f in found]
    return list(dict.fromkeys(out))


def file_checksum(path, asf=None) -> str:
    """sha256 of a motion file's bytes (an AMC together with its ASF skeleton: ``asf`` or :func:`find_asf`)."""
    h = hashlib.sha256()
    parts = [Path(path)]
    if Path(path).suffix.lower() == ".amc":
        parts.append(Path(asf) if asf is not None else find_asf(path))
    for part in parts:
        try:
            with open(part, "rb") as fh:
                for chunk in iter(lambda: fh.read(1 << 20), b""):
                    h.update(chunk)
        except OSError as exc:  # unreadable or vanished since it was listed: a file to skip under --skip-bad
            raise MocapFormatError(part, f"cannot read the file ({exc.strerror or exc})") from None
    return h.hexdigest()


def read_document(path, fps: float | None = None, labels: dict | None = None, mapping: dict | None = None,
                  sha256: str | None = None, **load_options) -> tuple[Motion, dict]:
    """One ingest task: read a file, map it to the canonical skeleton, resample, describe it.

    Parameters
    ----------
    path : str or os.PathLike
    fps : float, optional
        Target frame rate; default: keep the file's.
    labels : dict, optional
        Labels of this file; default :func:`mocapviz.labels.labels_for` (label tables beside the data).
    mapping : dict, optional
        Canonical joint -> joint name, overriding the automatic mapping.
    sha256 : str, optional
        The file's :func:`file_checksum`, if the caller has it already.
    **load_options
        Passed to :func:`mocapviz.load`.

    Returns
    -------
    motion : Motion
        Canonical joints, at ``fps``.
    meta : dict
        name, path, format, n_frames, fps, source_fps, sha256 and the labels.
    """
    path = Path(path)
    motion = load(path, **load_options)
    source_fps = motion.fps
    motion = motion.canonical(mapping)
    if fps is not None:
        motion = motion.resample(fps)
    labels = labels_for(path) if labels is None else dict(labels)
    meta = {
        "name": path.stem,
        "path": str(path),
        "format": path.suffix.lower().lstrip("."),
        "n_frames": motion.n_frames,
        "fps": motion.fps,
        "source_fps": source_fps,
        "sha256": sha256 or file_checksum(path, load_options.get("asf")),
        "label": labels.pop("label", None),
        **{k: v for k, v in labels.items() if k not in _BASE_COLUMNS},
    }
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
        from . import errors

        if self.kind == "MocapFormatError":
            return MocapFormatError(self.path, self.reason, self.line)
        return getattr(errors, self.kind, MocapvizError)(self.message)


def _read_task(args) -> tuple[np.ndarray, np.ndarray | None, dict] | _ReadFailure:
    """Reading one file (on a thread of this process or a Dask worker).

    ``args`` = (path, sha256, fps, labels, mapping, load_options). Returns (positions [shape=(T, 24, 3)] cm,
    quaternions [shape=(T, 24, 4)] or None, meta) of :func:`read_document`, or a :class:`_ReadFailure` for a
    file that fails to read, so that the caller decides (raise it, or skip it with ``skip_bad``).
    """
    path, sha256, fps, labels, mapping, load_options = args
    try:
        motion, meta = read_document(path, fps, labels, mapping, sha256, **load_options)
    except MocapvizError as exc:  # a malformed file, an unmappable rig, a bad label file beside the data, ...
        return _ReadFailure.of(exc)
    return motion.positions, motion.quaternions, meta


def _read_chunk(chunk: list) -> list:
    """An ingest task: :func:`_read_task` of each file of a chunk, in order (files fail one by one)."""
    return [_read_task(args) for args in chunk]


def _chunks(todo: list, parts: int, max_bytes: int = _CHUNK_MAX_BYTES) -> list[list]:
    """``todo`` (:func:`_read_task` arguments, path first) cut into about ``parts`` contiguous chunks of similar size
    on disk, none above ``max_bytes`` unless it is one file: a task per file costs more than reading a small file."""
    sizes = np.array([os.path.getsize(args[0]) for args in todo], dtype=np.float64)
    target = min(max(sizes.sum() / max(1, parts), 1.0), max_bytes)
    out, chunk, held = [], [], 0.0
    for args, size in zip(todo, sizes):
        if chunk and held + size > target:
            out.append(chunk)
            chunk, held = [], 0.0
        chunk.append(args)
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


class MotionDB:
    """A motion database on disk (see the module docstring for the layout).

    Open one with :meth:`open`, build or extend one with :meth:`ingest`.

    Attributes
    ----------
    path : pathlib.Path
    documents : pandas.DataFrame
        One row per document: ``doc_id``, ``name``, ``path``, ``format``, ``start`` (first frame in the
        concatenated arrays), ``n_frames``, ``fps``, ``source_fps``, ``sha256``, ``label`` and the label
        columns of the sources (HDM05 ``actor``/``class``/``take``/``split``, CMU ``description``..., Bandai
        ``content``/``style``).
    positions : np.ndarray [shape=(N, 24, 3)], float32 memory map, cm, canonical joints
    quaternions : np.ndarray [shape=(N, 24, 4)], float32 memory map, NaN for documents without rotations
    """

    def __init__(self, path, manifest: dict, documents: pd.DataFrame, arrays: dict):
        self.path = Path(path)
        self.manifest = manifest
        self.documents = documents
        self.positions = arrays["positions"]
        self.quaternions = arrays["quaternions"]

    # ------------------------------------------------------------------ reading
    @classmethod
    def open(cls, path, verify: bool = False) -> MotionDB:
        """Open a MotionDB directory.

        Every file is checked against the size recorded in the manifest when it was written, the documents table
        also against its sha256 (it is small); with ``verify`` the frame arrays' sha256 too (a few seconds per GB;
        ``mocapviz check DB`` does this).

        Raises
        ------
        MotionDBError
            Not a MotionDB, another format version, or a file missing, damaged (size or checksum) or inconsistent
            with the manifest; the message names the file.
        """
        path = Path(path)
        manifest = _read_manifest(path)
        n = manifest["n_frames"]
        fingerprints = manifest.get("checksums") or {}
        arrays = {}
        for name, width in _ARRAYS.items():
            f = path / manifest["arrays"][name]
            store.verify(f, fingerprints.get(f.name), full=verify, rebuild=_RESTORE)
            try:
                arr = np.load(f, mmap_mode="r") if n else np.zeros((0, len(CANONICAL_JOINTS), width), np.float32)
            except (OSError, ValueError) as exc:
                raise MotionDBError(f"{f}: cannot read ({exc})") from None
            if arr.shape != (n, len(CANONICAL_JOINTS), width) or arr.dtype != np.float32:
                raise MotionDBError(f"{f}: shape {arr.shape} {arr.dtype}, the manifest says ({n}, 24, {width}) float32")
            arrays[name] = arr
        table = path / manifest["documents"]
        store.verify(table, fingerprints.get(table.name), full=True, rebuild=_RESTORE)
        try:
            documents = pd.read_parquet(table)
        except (OSError, ValueError) as exc:
            raise MotionDBError(f"{table}: cannot read ({exc})") from None
        _check_documents(documents, table, n)
        return cls(path, manifest, documents, arrays)

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def fps(self) -> float | None:
        """The frame rate shared by all documents, or None if they differ (or the DB is empty)."""
        rates = self.documents["fps"].unique()
        return float(rates[0]) if len(rates) == 1 else None

    @property
    def typical_fps(self) -> float | None:
        """The frame rate of most of the database's frames (:attr:`fps` when all documents share one; None when
        empty): the rate a query file is resampled to. Durations of a hit use its own document's ``fps``."""
        if self.documents.empty:
            return None
        return float(self.documents.groupby("fps")["n_frames"].sum().idxmax())

    def __len__(self) -> int:
        return len(self.documents)

    def __repr__(self) -> str:
        fps = f"{self.fps:g} fps" if self.fps else "mixed fps"
        return f"MotionDB({str(self.path)!r}: {len(self)} documents, {self.n_frames} frames, {fps})"

    def document(self, doc_id: int) -> pd.Series:
        """The document table's row of ``doc_id`` (KeyError naming the valid ids when there is none)."""
        rows = self.documents[self.documents["doc_id"] == doc_id]
        if rows.empty:
            raise UnknownKeyError(f"{self.path}: no document {doc_id} (ids {self.documents['doc_id'].min()}..{self.documents['doc_id'].max()})")
        return rows.iloc[0]

    def frames(self, doc_id: int) -> slice:
        """The slice of the concatenated arrays that holds document ``doc_id``."""
        row = self.document(doc_id)
        return slice(int(row["start"]), int(row["start"] + row["n_frames"]))

    def motion(self, doc_id: int) -> Motion:
        """Document ``doc_id`` as a canonical Motion (arrays are views of the memory maps)."""
        row = self.document(doc_id)
        sl = self.frames(doc_id)
        quat = self.quaternions[sl]
        labels = {"label": row["label"], **{c: row[c] for c in self.label_columns[1:] if not pd.isna(row[c])}}
        return Motion(
            positions=self.positions[sl],
            fps=float(row["fps"]),
            joint_names=CANONICAL_JOINTS,
            parents=CANONICAL_PARENTS,
            quaternions=None if quat.shape[0] and np.isnan(quat[0, 0, 0]) else quat,
            source=row["path"],
            labels=labels,
        )

    @property
    def label_columns(self) -> list[str]:
        """The documents' label columns: ``label`` and those of the label tables (``actor``, ``class``, ...), not
        the bookkeeping columns (path, start, fps, ...) nor ``frames`` (a label table's own frame count, at the
        source's rate)."""
        return ["label"] + [c for c in self.documents.columns if c not in _BASE_COLUMNS and c != "frames"]

    def document_of(self, frames) -> np.ndarray:
        """Document id of each frame index (array in, array out)."""
        starts = self.documents["start"].to_numpy()
        idx = np.searchsorted(starts, np.asarray(frames), side="right") - 1
        return self.documents["doc_id"].to_numpy()[idx]

    def select(self, **criteria) -> pd.DataFrame:
        """Documents whose columns match: ``db.select(label="kickLFront1Reps", actor=["bd", "mm"])``.

        A value may be a scalar or a list of accepted values.

        Raises
        ------
        KeyError
            A column the documents table does not have.
        """
        mask = np.ones(len(self.documents), dtype=bool)
        for col, want in criteria.items():
            if col not in self.documents:
                raise UnknownKeyError(f"no column {col!r}; the documents have {', '.join(self.documents.columns)}")
            values = want if isinstance(want, (list, tuple, set, np.ndarray, pd.Index)) else [want]
            mask &= self.documents[col].isin(list(values)).to_numpy()
        return self.documents[mask]

    def summary(self) -> pd.DataFrame:
        """Documents, frames and minutes per label (and a total row)."""
        d = self.documents.assign(minutes=self.documents["n_frames"] / self.documents["fps"] / 60.0)
        per = d.groupby(d["label"].fillna("(none)")).agg(documents=("doc_id", "size"), frames=("n_frames", "sum"),
                                                         minutes=("minutes", "sum"))
        per.loc["total"] = [len(d), int(d["n_frames"].sum()), float(d["minutes"].sum())]
        return per

    # ------------------------------------------------------------------ writing
    @classmethod
    def create(cls, path) -> MotionDB:
        """An empty MotionDB at ``path`` (which must not exist or be an empty directory)."""
        path = Path(path)
        if path.exists() and (not path.is_dir() or any(path.iterdir())):
            raise MotionDBError(f"{path}: exists and is not an empty directory")
        with contextlib.suppress(OSError):
            path.rmdir()  # (an empty folder the user made: replaced by the new database below)
        # built beside the target and renamed into place complete: a killed create leaves no half database, and
        # when another process created it first, that one is kept
        with store.atomic_folder(path, replace=False) as tmp:
            _commit(tmp, None, [], [], [])
        return cls.open(path)

    @classmethod
    @renamed(n_jobs="threads")
    def ingest(cls, paths, out, fps: float | None = None, labels=None, mapping: dict | None = None,
               skip_bad: bool = False, threads: int | None = None, progress: bool = True, scheduler=None,
               **load_options) -> MotionDB:
        """Read motion files into the MotionDB at ``out``, creating it or appending to it.

        Files already in the database (same sha256) are skipped, so re-running an interrupted ingest
        continues where it stopped. Nothing is written until every file has been read; then the new
        documents are committed at once (atomically).

        Parameters
        ----------
        paths : str, os.PathLike or list of them
            Files, folders (searched recursively for .amc / .bvh) or glob patterns.
        out : str or os.PathLike
            The database directory.
        fps : float, optional
            Resample every document to this rate (e.g. 120 for relational indexing, 30 for kNN).
        labels : path, DataFrame or dict, optional
            A label table (``file`` or ``path`` column plus label columns; TSV or CSV) or
            {path or file name: {column: value}}. Default: the label tables found beside the data
            (``labels.tsv``, Bandai Namco ``.json``), see :func:`mocapviz.labels.labels_for`.
        mapping : dict, optional
            Canonical joint -> joint name for rigs the automatic rules cannot map.
        skip_bad : bool
            Skip files that fail to read (with a warning) instead of stopping.
        threads : int, optional
            Threads reading files in this process (the parsers' compiled kernels release the GIL); None:
            :func:`mocapviz.batch.default_threads` (on 2 cores the 287 HDM05 clips take 0.90 s on 2 threads, 0.99 s
            on 1). Ignored when ``scheduler`` is given. (Formerly ``n_jobs``, reader processes: still accepted, with
            a FutureWarning.)
        progress : bool
            Show a progress bar.
        scheduler : None, "local", str or dask.distributed.Client
            Read the files as Dask tasks, a few files each (:func:`mocapviz.cluster.dask_client`): ``"local"``
            starts a local cluster of worker processes for this call, an address connects to a running scheduler
            (its workers must see the same paths), a Client is used as it is. None (default): on ``threads``
            threads in this process. The results are committed here, in input order, whatever order the tasks
            finish in.
        **load_options
            Passed to :func:`mocapviz.load` (``asf``, ``up``, ``scale``).

        Returns
        -------
        MotionDB

        Raises
        ------
        MocapFormatError, SkeletonMappingError
            A file fails to read and ``skip_bad`` is false; the database is left as it was.
        MotionDBError
            ``out`` exists but is not a MotionDB, or its frame rate differs from ``fps``.
        """
        out = Path(out)
        files = expand_paths(paths)
        retries = 2  # again when a concurrent failed ingest removed the empty database it created
        while True:
            created = False
            if not (out / "manifest.json").exists():
                try:
                    cls.create(out)
                    created = True
                except MotionDBError:
                    if not (out / "manifest.json").exists():  # (not another ingest that created it first)
                        raise
            try:
                return cls.open(out).append(files, fps=fps, labels=labels, mapping=mapping, skip_bad=skip_bad,
                                            threads=threads, progress=progress, scheduler=scheduler, **load_options)
            except _Vanished:
                if not retries:
                    raise
                retries -= 1
            except BaseException:
                if created:
                    _remove_if_untouched(out)
                raise

    def append(self, paths, fps: float | None = None, labels=None, mapping: dict | None = None,
               skip_bad: bool = False, threads: int | None = None, progress: bool = True, scheduler=None,
               **load_options) -> MotionDB:
        """Add motion files to this database; see :meth:`ingest`. Returns the reopened database.

        The writer lock is held for the whole transaction (what the database holds is read, the files are read,
        the new documents are committed), so a second writer waits; when it goes on, it sees the documents the
        first committed and skips those files.
        """
        with _locked(self.path):
            current = _reopen(self.path)
            return current._append_locked(paths, fps, labels, mapping, skip_bad, threads, progress, scheduler,
                                          load_options)  # fmt: skip

    def _append_locked(self, paths, fps, labels, mapping, skip_bad, threads, progress, scheduler,
                       load_options) -> MotionDB:  # fmt: skip
        if fps is not None and len(self) and self.fps != float(fps):
            raise MotionDBError(f"{self.path}: documents are at {self.fps} fps; cannot append at {fps} fps")
        if fps is None and self.fps is not None and len(self):
            fps = self.fps
        table = _labels_table(labels)
        known = set(self.documents["sha256"])
        todo = []
        for f in expand_paths(paths):
            try:
                sha256 = file_checksum(f, load_options.get("asf"))
            except MocapFormatError as exc:  # e.g. an AMC without its ASF
                if not skip_bad:
                    raise
                warnings.warn(f"skipped {exc}", stacklevel=2)
                continue
            if sha256 in known:
                continue
            lab = None if table is None else table.get(str(f), table.get(f.name, {}))
            todo.append((str(f), sha256, fps, lab, mapping, load_options))
        from .batch import map_ordered, parallelism  # (mocapviz.batch imports this module)

        positions, quaternions, metas = [], [], []
        with optional_client(scheduler if todo else None) as client:
            chunks = _chunks(todo, 4 * parallelism(threads, client))
            results = map_ordered(_read_chunk, chunks, threads, client, name="mocapviz-read")
            bar = tqdm(total=len(todo), desc="ingest", unit="file", disable=not progress or not todo)
            # results in input order; the first file that fails (in that order) stops the run before any write, and
            # closing the results cancels what is pending (before the client closes)
            with bar, contextlib.closing(results):
                for res in (res for chunk in results for res in chunk):
                    bar.update()
                    if isinstance(res, _ReadFailure):
                        if not skip_bad:
                            raise res.error()
                        warnings.warn(f"skipped {res.message}", stacklevel=2)
                        continue
                    positions.append(res[0])
                    quaternions.append(res[1])
                    metas.append(res[2])
        if positions:
            _commit(self.path, self.manifest, positions, quaternions, metas)
        return MotionDB.open(self.path)

    def append_motions(self, motions, metas=None) -> MotionDB:
        """Add clips held in memory (derived data: mirrored, resampled or edited copies of documents).

        Unlike :meth:`append`, nothing is read and nothing is skipped: a clip equal to one already held is added
        again. All clips are committed at once, atomically.

        Parameters
        ----------
        motions : list of Motion
            Clips on the 24 canonical joints (``Motion.canonical()``), at the database's frame rate.
        metas : list of dict, optional
            One per clip: any document columns (``name``, ``label``, ``path``, ``sha256``, ``source_fps``, label
            columns such as ``actor``). Defaults: the clip's labels; name = the source file's stem; path = the
            source; format "memory"; sha256 of the positions' bytes.

        Returns
        -------
        MotionDB, reopened.

        Raises
        ------
        ValueError
            A clip not on the canonical joints, at another frame rate than the database's, or metas of another
            length than motions.
        """
        motions = list(motions)
        metas = [{} for _ in motions] if metas is None else [dict(m) for m in metas]
        if len(metas) != len(motions):
            raise ParameterError(f"{len(motions)} motions but {len(metas)} metas")
        rows = []
        for i, (m, meta) in enumerate(zip(motions, metas)):
            if tuple(m.joint_names) != tuple(CANONICAL_JOINTS):
                raise ParameterError(f"motion {i} ({m.source}): not on the canonical joints; use Motion.canonical()")
            if len(self) and self.fps is not None and m.fps != self.fps:
                raise ParameterError(f"motion {i} ({m.source}) is at {m.fps:g} fps; the database at {self.fps:g} fps")
            labels = {k: v for k, v in m.labels.items() if k not in _BASE_COLUMNS or k == "label"}
            rows.append({
                "name": Path(m.source).stem if m.source else f"motion{i}", "path": m.source or "",
                "format": "memory", "source_fps": m.fps,
                "sha256": hashlib.sha256(np.ascontiguousarray(m.positions).tobytes()).hexdigest(),
                **labels, **meta, "n_frames": m.n_frames, "fps": m.fps,
            })  # fmt: skip
        return self._commit_motions(motions, rows)

    def _commit_motions(self, motions: list, metas: list[dict]) -> MotionDB:
        return self._commit_arrays([m.positions for m in motions], [m.quaternions for m in motions], metas)

    def _commit_arrays(self, positions: list, quaternions: list, metas: list[dict]) -> MotionDB:
        if positions:
            with _locked(self.path):
                _commit(self.path, _reopen(self.path).manifest, positions, quaternions, metas)
        return MotionDB.open(self.path)


# ---------------------------------------------------------------------- batches of documents
def document_batches(db: MotionDB, max_frames: int) -> tuple[pd.DataFrame, list[tuple[int, int]]]:
    """Cut a MotionDB into batches of whole documents, contiguous in the frame arrays, for per-batch feature work.

    Parameters
    ----------
    db : MotionDB
    max_frames : int
        A batch holds documents while their frames add up to at most this many (at least one document each).

    Returns
    -------
    docs : pandas.DataFrame
        The document table sorted by first frame.
    batches : list of (first, last)
        Positions in ``docs``: documents ``docs.iloc[first:last]`` form one batch; in frame order.
    """
    docs = db.documents.sort_values("start")
    starts = docs["start"].to_numpy(np.int64)
    lengths = docs["n_frames"].to_numpy(np.int64)
    batches, first = [], 0
    while first < len(docs):
        last = first + 1
        while (last < len(docs) and starts[last] == starts[last - 1] + lengths[last - 1]
               and starts[last] + lengths[last] - starts[first] <= max_frames):
            last += 1  # fmt: skip
        batches.append((first, last))
        first = last
    return docs, batches


@dataclass(frozen=True)
class FrameBatch:
    """The frames of documents ``docs.iloc[first:last]`` read from a MotionDB (:func:`read_batch`).

    Attributes
    ----------
    start, stop : int -- the batch is database frames ``start:stop``
    positions : np.ndarray [shape=(stop - start, 24, 3)], float32, cm
    bounds : np.ndarray [shape=(D + 1,)], int64 -- document d is rows ``bounds[d]:bounds[d + 1]`` of ``positions``
    fps : np.ndarray [shape=(D,)], float64 -- each document's frame rate
    """

    db_path: str
    docs: pd.DataFrame
    start: int
    stop: int
    positions: np.ndarray
    bounds: np.ndarray
    fps: np.ndarray

    def where(self, t: int) -> str:
        """Names row ``t`` of ``positions`` for an error: database, document id, source file and frame."""
        d = int(np.searchsorted(self.bounds, t, side="right")) - 1
        row = self.docs.iloc[d]
        return f"{self.db_path}: document {row['doc_id']} ({row['path']}), frame {t - int(self.bounds[d])}"


def read_batch(db: MotionDB, docs: pd.DataFrame, first: int, last: int) -> FrameBatch:
    """The positions of documents ``docs.iloc[first:last]`` (one batch of :func:`document_batches`), in memory."""
    part = docs.iloc[first:last]
    lengths = part["n_frames"].to_numpy(np.int64)
    start = int(part["start"].iloc[0])
    stop = start + int(lengths.sum())
    return FrameBatch(str(db.path), part, start, stop, np.asarray(db.positions[start:stop]),
                      np.concatenate([[0], np.cumsum(lengths)]), part["fps"].to_numpy(np.float64))  # fmt: skip


# ---------------------------------------------------------------------- storage helpers
def _locked(path: Path):
    """The database's writer lock (:func:`mocapviz.store.locked`): one writer at a time, a second one waits."""
    if not (path / "manifest.json").is_file():
        raise MotionDBError(f"{path}: not a MotionDB (no manifest.json); it may have been removed by a failed ingest")
    return store.locked(path)


class _Vanished(MotionDBError):
    """The database was removed while this writer waited for its lock (a concurrent fresh ingest failed)."""


def _reopen(path: Path) -> MotionDB:
    """The database as it is now (called under the writer lock: another writer may have committed meanwhile)."""
    if not (path / "manifest.json").is_file():
        raise _Vanished(f"{path}: removed by a failed ingest while this one waited to write; run it again")
    return MotionDB.open(path)


def _check_documents(documents: pd.DataFrame, table: Path, n_frames: int) -> None:
    """The documents table's own consistency: the base columns, one row per document, starts that tile the
    frame arrays in order, positive frame counts and rates. MotionDBError naming the table, column and row."""
    missing = [c for c in ("doc_id", "start", "n_frames", "fps", "sha256") if c not in documents.columns]
    if missing:
        raise MotionDBError(f"{table}: damaged documents table: no column {', '.join(missing)}")
    if not len(documents):
        if n_frames:
            raise MotionDBError(f"{table}: no documents, but the arrays hold {n_frames} frames")
        return
    try:
        doc_id, start, count_, fps = (documents[c].to_numpy(np.float64) for c in ("doc_id", "start", "n_frames", "fps"))
    except (TypeError, ValueError):
        raise MotionDBError(f"{table}: damaged documents table: doc_id, start, n_frames or fps not numeric") from None
    tiled = np.concatenate([[0], np.cumsum(count_)[:-1]])
    bad = np.flatnonzero((count_ < 1) | (start != tiled) | ~np.isfinite(fps) | (fps <= 0))
    if len(bad):
        row = int(bad[0])
        raise MotionDBError(f"{table}: damaged documents table at row {row} (doc_id {documents['doc_id'].iloc[row]}): "
                            f"start {start[row]:g}, n_frames {count_[row]:g}, fps {fps[row]:g} do not tile the frames")
    if len(np.unique(doc_id)) != len(doc_id) or count_.sum() != n_frames:
        raise MotionDBError(f"{table}: damaged documents table: duplicate doc_ids, or {count_.sum():g} frames for "
                            f"arrays of {n_frames}")


def _read_manifest(path: Path) -> dict:
    f = path / "manifest.json"
    if not f.is_file():
        raise MotionDBError(f"{path}: not a MotionDB (no manifest.json)")
    try:
        manifest = json.loads(f.read_text())
    except (OSError, ValueError) as exc:
        raise MotionDBError(f"{f}: unreadable ({exc})") from None
    return check_format(manifest, FORMAT, VERSION, f)


def _write_grown(old: Path | None, n_old: int, new: list[np.ndarray], width: int, target: Path) -> None:
    """Write ``target`` = the first n_old frames of ``old`` followed by ``new``, as one .npy file."""
    n_new = sum(a.shape[0] for a in new)
    with atomic_file(target) as tmp:
        arr = np.lib.format.open_memmap(tmp, mode="w+", dtype=np.float32, shape=(n_old + n_new, len(CANONICAL_JOINTS), width))
        if n_old:
            src = np.load(old, mmap_mode="r")
            for s in range(0, n_old, 1 << 18):
                arr[s : min(s + (1 << 18), n_old)] = src[s : min(s + (1 << 18), n_old)]
        at = n_old
        for a in new:
            arr[at : at + a.shape[0]] = a
            at += a.shape[0]
        arr.flush()
        del arr


def _commit(path: Path, manifest: dict | None, positions: list, quaternions: list, metas: list[dict]) -> None:
    """Write generation g+1 with the new documents appended, then switch the manifest to it."""
    gen = 0 if manifest is None else manifest["generation"] + 1
    n_old = 0 if manifest is None else manifest["n_frames"]
    old_docs = pd.read_parquet(path / manifest["documents"]) if manifest else pd.DataFrame(columns=_BASE_COLUMNS)
    quaternions = [
        np.full(p.shape[:2] + (4,), np.nan, np.float32) if q is None else q for p, q in zip(positions, quaternions)
    ]
    files = {}
    for name, width in _ARRAYS.items():
        target = path / f"{name}.g{gen}.npy"
        old = None if manifest is None else path / manifest["arrays"][name]
        _write_grown(old, n_old, positions if name == "positions" else quaternions, width, target)
        files[name] = target.name
    new_docs = pd.DataFrame(metas)
    if len(new_docs):
        new_docs.insert(0, "doc_id", np.arange(len(new_docs)) + (int(old_docs["doc_id"].max()) + 1 if len(old_docs) else 0))
        new_docs["start"] = n_old + np.concatenate([[0], np.cumsum(new_docs["n_frames"].to_numpy())[:-1]])
    docs = pd.concat([old_docs, new_docs], ignore_index=True) if len(old_docs) else new_docs
    if docs.empty:
        docs = pd.DataFrame({c: pd.Series(dtype="int64" if c in ("doc_id", "start", "n_frames") else "float64" if "fps" in c else "object") for c in _BASE_COLUMNS})
    docs = docs[_BASE_COLUMNS + [c for c in docs.columns if c not in _BASE_COLUMNS]]
    for c in ("doc_id", "start", "n_frames"):
        docs[c] = docs[c].astype("int64")
    for c in docs.columns:
        if docs[c].dtype == object:
            docs[c] = docs[c].astype("string")
    doc_file = path / f"documents.g{gen}.parquet"
    with atomic_file(doc_file) as tmp:
        docs.to_parquet(tmp, index=False)
    new_manifest = {
        **stamp(FORMAT, VERSION),
        "generation": gen,
        "n_frames": n_old + sum(p.shape[0] for p in positions),
        "joint_names": list(CANONICAL_JOINTS),
        "arrays": files,
        "documents": doc_file.name,
        "checksums": {f: store.fingerprint(path / f) for f in [*files.values(), doc_file.name]},
    }
    atomic_write(path / "manifest.json", json.dumps(new_manifest, indent=2).encode())
    keep = set(files.values()) | {doc_file.name, "manifest.json", ".lock"}
    for f in path.iterdir():
        if f.name not in keep and (f.name.endswith((".npy", ".parquet", ".tmp"))):
            f.unlink()


def _remove_if_untouched(path: Path) -> None:
    """Delete a database this process created for an ingest that failed, but only while it is still the empty
    generation 0 it created and no other writer holds it: what another process committed is never removed."""
    try:
        with store.locked(path, wait=False):
            manifest = _read_manifest(path)
            if manifest["generation"] != 0 or manifest["n_frames"] != 0:
                return
            for f in path.iterdir():
                if f.name in ("manifest.json", store.LOCK_FILE) or f.name.endswith((".npy", ".parquet", ".tmp")):
                    f.unlink()
    except (MotionDBError, OSError):  # another writer is in it, or it is gone: leave it
        return
    with contextlib.suppress(OSError):
        path.rmdir()
