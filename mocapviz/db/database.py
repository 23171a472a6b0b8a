"""MotionDB: many motions on the canonical skeleton, concatenated on disk.

Layout of a MotionDB directory (format version 1; the names are :mod:`mocapviz.db.layout`'s)::

    manifest.json                  format, version, generation, frame count, joints, file names
    positions.g<G>.npy             (N, 24, 3) float32, cm, y up -- all frames of all documents
    quaternions.g<G>.npy           (N, 24, 4) float32 local rotations (w, x, y, z); NaN where none
    documents.g<G>.parquet         one row per document: doc_id, name, path, start, n_frames, fps, labels, ...

Every write produces the files of a new generation G under their final names and then replaces
``manifest.json`` atomically (:mod:`mocapviz.store`); readers only follow the manifest. A write that fails or is
killed therefore leaves the previous generation, and the database, exactly as they were. A new database is built
beside its folder and renamed into place complete, so a killed first ingest leaves nothing to clean up. A commit
deletes only the files of generations older than the previous one, so a reader that read the previous manifest
still finds its files; one that has opened them keeps reading its memory maps after they are deleted; and one that
finds a file gone (two commits since it read the manifest) reads the new manifest and opens that generation.

The manifest is checked against one schema (``_MANIFEST``: every key, its type, file names plain names inside the
folder). It records each file's size, sha256 and the xxh3 of each 16 MiB block: opening checks the sizes and the
documents table's sha256, each block of a frame array is verified by its xxh3 when first read in the process
(:mod:`mocapviz.checked_map`: opening stays instant, a search reads and checks only the blocks it touches), and
``MotionDB.open(path, verify=True)`` (``mocapviz check DB``) every sha256, so a damaged file is a MotionDBError
naming it, never an answer. One writer at a time: the writer lock (``.lock``) is held for a whole append (what
is held is read, the files are read, the documents committed), so a second writer waits and then skips what the
first added; a failed first ingest removes only the empty database it created, never what another committed.

Ingest reads the files in parallel (:mod:`mocapviz.db.ingest`); the commit is done here, in input order, once
every file has been read. See ``docs/architecture.md`` (the db layer).
"""
from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

from .. import store
from ..checked_map import open_checked
from ..errors import MotionDBError, ParameterError, StaleDataError, UnknownKeyError
from ..motion import Motion
from ..motion.skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS
from ..store import atomic_file, atomic_write, check_format, stamp
from ..validation import MARKERS_ONLY, one_of, renamed
from .ingest import BASE_COLUMNS as _BASE_COLUMNS
from .ingest import IngestOptions, expand_paths, held_documents, read_new
from .layout import generation_file, generation_of, manifest_file
from .marker_documents import MarkerDocuments, add_marker_documents, read_marker_documents

__all__ = ["FORMAT", "VERSION", "MotionDB"]

FORMAT = "mocapviz.MotionDB"
VERSION = 1
_ARRAYS = {"positions": 3, "quaternions": 4}
_RESTORE = "restore it from a backup or ingest the files again into a new database"
_OPEN_ATTEMPTS = 5  # manifests read again when a writer deleted the files of the one read (two commits meanwhile)
_KEEP_GENERATIONS = 2  # a commit deletes the files of older generations: a reader that read the previous manifest
#                        still finds its files, and one that has mapped them keeps reading them after deletion
DEMO_FPS = 30.0  # the demo's rate: the rate of Krüger et al. 2010 and of every figure of the docs


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

    Parameters
    ----------
    path : str or os.PathLike
        The database folder.
    manifest : dict
        Its parsed ``manifest.json``.
    documents : pandas.DataFrame
        The documents table.
    arrays : dict
        ``"positions"`` and ``"quaternions"`` arrays of all frames. (The constructor takes what :meth:`open` has
        read and checked; call :meth:`open`, :meth:`ingest`, :meth:`create` or :meth:`sample` instead.)

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §5: the database as one long document, the documents concatenated, their boundaries kept.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> len(db), db.n_frames, db.fps
    (24, 5543, 120.0)
    >>> db.select(label="squat1Reps")[["doc_id", "actor"]].to_numpy().tolist()
    [[11, 'dg'], [22, 'mm']]
    >>> m = db.motion(7)[0:120]  # a Motion on the 24 canonical joints; frames 0:120 of document 7
    >>> m.positions.shape, m.fps, m.labels["label"]
    ((120, 24, 3), 120.0, 'kickLFront1Reps')
    >>> sl = db.frames(7)  # document 7's rows of db.positions
    >>> sl.stop - sl.start, int(db.document(7)["n_frames"])
    (129, 129)
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

        Parameters
        ----------
        path : str or os.PathLike
            The database folder (holding ``manifest.json``).
        verify : bool
            Also check the sha256 of the frame arrays (slow on large databases).

        Returns
        -------
        MotionDB
            The frame arrays memory-mapped read-only, the documents table in memory.

        Raises
        ------
        MotionDBError
            No such folder, not a MotionDB, another format version, or a file missing, damaged (size or checksum) or inconsistent
            with the manifest; the message names the file.

        Examples
        --------
        >>> db = MotionDB.open(MotionDB.sample().path, verify=True)
        >>> len(db), db.positions.shape
        (24, (5543, 24, 3))
        """
        path = Path(path)
        for attempt in range(_OPEN_ATTEMPTS):
            manifest = _read_manifest(path)
            try:
                return cls._open_generation(path, manifest, verify)
            except _Gone:  # a file of this generation deleted meanwhile: a writer committed twice since the read
                if attempt == _OPEN_ATTEMPTS - 1 or _read_manifest(path)["generation"] == manifest["generation"]:
                    raise
        raise AssertionError("unreachable")  # pragma: no cover

    @classmethod
    def _open_generation(cls, path: Path, manifest: dict, verify: bool) -> MotionDB:
        n = manifest["n_frames"]
        fingerprints = manifest["checksums"]
        arrays = {}
        for name, width in _ARRAYS.items():
            f = path / manifest["arrays"][name]
            _exists(f)
            store.verify(f, fingerprints.get(f.name), full=verify, rebuild=_RESTORE)
            try:
                arr = (open_checked(f, fingerprints.get(f.name), _RESTORE) if n
                       else np.zeros((0, len(CANONICAL_JOINTS), width), np.float32))
            except FileNotFoundError:
                raise _Gone(f"{f}: deleted while opening") from None
            except (OSError, ValueError) as exc:
                raise MotionDBError(f"{f}: cannot read ({exc})") from None
            if arr.shape != (n, len(CANONICAL_JOINTS), width) or arr.dtype != np.float32:
                raise MotionDBError(f"{f}: shape {arr.shape} {arr.dtype}, the manifest says ({n}, 24, {width}) float32")
            arrays[name] = arr
        table = path / manifest["documents"]
        _exists(table)
        store.verify(table, fingerprints.get(table.name), full=True, rebuild=_RESTORE)
        try:
            documents = pd.read_parquet(table)
        except FileNotFoundError:
            raise _Gone(f"{table}: deleted while opening") from None
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
        """The document table's row of ``doc_id``.

        Parameters
        ----------
        doc_id : int
            A value of ``documents.doc_id``.

        Returns
        -------
        pandas.Series
            The row: ``name``, ``path``, ``start``, ``n_frames``, ``fps``, labels, ...

        Raises
        ------
        KeyError
            No such document (an UnknownKeyError naming the valid ids).
        """
        rows = self.documents[self.documents["doc_id"] == doc_id]
        if rows.empty:
            only = self.marker_documents.documents
            if doc_id in set(only["doc_id"]):  # marker-only: searched by its markers (mocapviz.similarity.marker_search)
                raise UnknownKeyError(f"{self.path}: document {doc_id} is a marker-only document (no canonical joints): "
                                      "search it with Engine.marker_stretches (mocapviz markers)")
            raise UnknownKeyError(f"{self.path}: no document {doc_id} (doc ids {self.documents['doc_id'].min()}..{self.documents['doc_id'].max()})")
        return rows.iloc[0]

    def frames(self, doc_id: int) -> slice:
        """The slice of the concatenated arrays that holds document ``doc_id``.

        Parameters
        ----------
        doc_id : int
            A value of ``documents.doc_id``.

        Returns
        -------
        slice
            Rows ``start:start + n_frames`` of :attr:`positions` (database-wide frame numbers).

        Examples
        --------
        >>> db = MotionDB.sample()
        >>> sl = db.frames(7)
        >>> db.positions[sl].shape
        (129, 24, 3)
        """
        row = self.document(doc_id)
        return slice(int(row["start"]), int(row["start"] + row["n_frames"]))

    def motion(self, doc_id: int) -> Motion:
        """Document ``doc_id`` as a canonical Motion (arrays are views of the memory maps).

        Parameters
        ----------
        doc_id : int
            A value of ``documents.doc_id``.

        Returns
        -------
        Motion
            Positions [shape=(n_frames, 24, 3)] in cm on the canonical joints, quaternions (None when the source
            had no rotations), the document's ``fps``, ``source`` (its file) and ``labels`` (``label``, None for an
            unlabelled document, and the label columns it has a value in).

        Examples
        --------
        >>> db = MotionDB.sample()
        >>> m = db.motion(11)
        >>> m.n_frames, m.fps, m.labels["label"], m.labels["actor"]
        (159, 120.0, 'squat1Reps', 'dg')
        >>> m[0:60].n_frames  # a span of frames is a Motion too
        60
        """
        row = self.document(doc_id)
        sl = self.frames(doc_id)
        quat = self.quaternions[sl]
        labels = {"label": None if pd.isna(row["label"]) else row["label"],
                  **{c: row[c] for c in self.label_columns[1:] if not pd.isna(row[c])}}  # fmt: skip
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
    def marker_documents(self) -> MarkerDocuments:
        """The marker-only documents stored beside the database (:mod:`mocapviz.db.marker_documents`): C3D files
        whose markers match no marker set, ingested with ``markers_only="keep"``; never in :attr:`documents`."""
        return read_marker_documents(self.path)

    @property
    def label_columns(self) -> list[str]:
        """The documents' label columns: ``label`` and those of the label tables (``actor``, ``class``, ...), not
        the bookkeeping columns (path, start, fps, ...) nor ``frames`` (a label table's own frame count, at the
        source's rate)."""
        return ["label"] + [c for c in self.documents.columns if c not in _BASE_COLUMNS and c != "frames"]

    def document_of(self, frames) -> np.ndarray:
        """Document id of each database frame.

        Parameters
        ----------
        frames : array_like of int
            Rows of :attr:`positions` (database-wide frame numbers, e.g. kNN neighbours).

        Returns
        -------
        np.ndarray
            The doc id of each frame, in the shape of ``frames``.

        Examples
        --------
        >>> db = MotionDB.sample()
        >>> db.document_of([0, db.frames(7).start]).tolist()
        [0, 7]
        """
        starts = self.documents["start"].to_numpy()
        idx = np.searchsorted(starts, np.asarray(frames), side="right") - 1
        return self.documents["doc_id"].to_numpy()[idx]

    def prefix_digest(self, n_documents: int) -> str:
        """sha256 of the first ``n_documents`` documents in storage order (their ids, frame counts, rates and the
        sha256 of their files): what derived data record of the documents they were computed from, so that after
        an ingest (which only appends documents) they can be extended with the new ones rather than rebuilt.

        Parameters
        ----------
        n_documents : int
            Documents counted from the first, 0 <= n_documents <= len(self).

        Returns
        -------
        str
            64 hex digits; equal for two generations whose first ``n_documents`` documents are the same.

        Examples
        --------
        >>> db = MotionDB.sample()
        >>> db.prefix_digest(3) == db.prefix_digest(3) != db.prefix_digest(4)
        True
        """
        docs = self.documents.sort_values("start").iloc[: int(n_documents)]
        h = hashlib.sha256()
        for row in docs[["doc_id", "n_frames", "fps", "sha256"]].itertuples(index=False):
            h.update(f"{int(row.doc_id)}|{int(row.n_frames)}|{float(row.fps)!r}|{row.sha256}\n".encode())
        return h.hexdigest()

    def added_since(self, n_documents, n_frames, digest) -> np.ndarray:
        """The documents appended after those derived data were computed from (their :meth:`prefix_digest`).

        Parameters
        ----------
        n_documents, n_frames : int
            The documents and frames the derived data cover (as recorded with them).
        digest : str
            Their :meth:`prefix_digest` as recorded.

        Returns
        -------
        np.ndarray [shape=(n,)], int64
            The doc ids after the first ``n_documents``, in storage order (empty when nothing was added).

        Raises
        ------
        StaleDataError
            The derived data were not computed from the first documents of this database (another database, an
            older record without the digest, or more documents than it holds): they must be computed again whole.
        """
        docs = self.documents.sort_values("start")
        if not isinstance(n_documents, int) or not 0 <= n_documents <= len(docs) or digest is None \
                or int(docs["n_frames"].iloc[:n_documents].sum()) != n_frames or self.prefix_digest(n_documents) != digest:
            raise StaleDataError(f"{self.path}: derived data computed from other documents than the first "
                                 f"{n_documents} of the database; compute them again")  # fmt: skip
        return docs["doc_id"].to_numpy(np.int64)[n_documents:]

    def select(self, **criteria) -> pd.DataFrame:
        """Documents whose columns match: ``db.select(label="kickLFront1Reps", actor=["bd", "mm"])``.

        A value may be a scalar or a list of accepted values.

        Parameters
        ----------
        **criteria
            Column of :attr:`documents` -> accepted value or list of values; all criteria must hold.

        Returns
        -------
        pandas.DataFrame
            The matching rows of :attr:`documents`, in their order.

        Raises
        ------
        KeyError
            A column the documents table does not have.

        Examples
        --------
        >>> db = MotionDB.sample()
        >>> db.select(label=["squat1Reps", "kickLFront1Reps"], actor="mm")["doc_id"].tolist()
        [18, 22]
        """
        mask = np.ones(len(self.documents), dtype=bool)
        for col, want in criteria.items():
            if col not in self.documents:
                raise UnknownKeyError(f"no column {col!r}; the documents have {', '.join(self.documents.columns)}")
            values = want if isinstance(want, (list, tuple, set, np.ndarray, pd.Index)) else [want]
            mask &= self.documents[col].isin(list(values)).to_numpy()
        return self.documents[mask]

    def summary(self) -> pd.DataFrame:
        """Documents, frames and minutes per label (and a total row).

        Returns
        -------
        pandas.DataFrame
            Indexed by label (``"(none)"`` for unlabelled documents, last ``"total"``); columns ``documents``,
            ``frames`` and ``minutes`` (each document at its own rate).

        Examples
        --------
        >>> per = MotionDB.sample().summary()
        >>> [int(per.loc[row, "documents"]) for row in ("squat1Reps", "total")]
        [2, 24]
        """
        d = self.documents.assign(minutes=self.documents["n_frames"] / self.documents["fps"] / 60.0)
        per = d.groupby(d["label"].fillna("(none)")).agg(documents=("doc_id", "size"), frames=("n_frames", "sum"),
                                                         minutes=("minutes", "sum"))
        per.loc["total"] = [len(d), int(d["n_frames"].sum()), float(d["minutes"].sum())]
        return per

    @classmethod
    def sample(cls) -> MotionDB:
        """The embedded sample as a MotionDB: 22 HDM05 clips (actors dg, mm) and 2 CMU trials at their own 120 Hz.

        Built once beside the unpacked sample (:func:`mocapviz.io.datasets.sample`, under ``$MOCAPVIZ_HOME``) and
        opened from there afterwards; the database of every Examples section of this package.

        Returns
        -------
        MotionDB

        Examples
        --------
        >>> db = MotionDB.sample()
        >>> len(db), db.fps, db.positions.shape[1:]
        (24, 120.0, (24, 3))
        >>> db.documents.loc[db.documents.doc_id == 7, ["name", "label", "actor"]].to_numpy().tolist()
        [['HDM_dg_kickLFront1Reps_017_120', 'kickLFront1Reps', 'dg']]
        """
        from ..io import datasets

        folder = datasets.sample()
        out = folder.parent / "sample.mdb"
        if not manifest_file(out).exists():
            cls.ingest(folder, out, progress=False)
        return cls.open(out).add_block_checksums()  # (a sample built by an older mocapviz)

    @classmethod
    def demo(cls) -> MotionDB:
        """The embedded demo as a MotionDB at 30 Hz: 44 HDM05 clips (4 actors x 11 classes), 8 CMU martial-arts
        trials and 2 C3D takes, document ids in the order of
        :data:`mocapviz.io.datasets.DEMO_ORDER` (the HDM05 clips first); what ``make demo`` serves.

        Built once beside the unpacked demo (:func:`mocapviz.io.datasets.demo`, under ``$MOCAPVIZ_HOME``) and opened
        from there afterwards, without indexes or numeric feature sets (``mocapviz index`` and ``mocapviz
        features``, or the engine, build them).

        Returns
        -------
        MotionDB

        Examples
        --------
        >>> db = MotionDB.demo()
        >>> len(db), db.fps, int((db.documents["label"] == "kickLFront1Reps").sum())
        (54, 30.0, 4)
        """
        from ..io import datasets

        folder = datasets.demo()
        out = folder.parent / "demo.mdb"
        if not manifest_file(out).exists():
            cls.ingest([folder / name for name in datasets.DEMO_ORDER], out, fps=DEMO_FPS, progress=False)
        return cls.open(out)

    # ------------------------------------------------------------------ writing
    def add_block_checksums(self) -> MotionDB:
        """Record the per-block xxh3 of the frame arrays in a manifest written before they were kept, after
        checking each file against its recorded sha256 (``mocapviz check DB`` does this). From then on every block
        is verified when first read (:mod:`mocapviz.checked_map`).

        Returns
        -------
        MotionDB
            The database reopened (this one, when nothing was missing).

        Raises
        ------
        MotionDBError
            A file differs from its recorded sha256 (nothing is written), or another writer holds the database.
        """
        if all("xxh3" in c for c in self.manifest["checksums"].values()):
            return self
        with _locked(self.path):
            manifest = _read_manifest(self.path)
            for name, recorded in manifest["checksums"].items():
                if "xxh3" not in recorded:
                    now = store.fingerprint(self.path / name)
                    if (now["size"], now["sha256"]) != (recorded.get("size"), recorded.get("sha256")):
                        raise MotionDBError(f"{self.path / name}: its sha256 differs from the one recorded when it "
                                            f"was written: the file is damaged; {_RESTORE}")  # fmt: skip
                    manifest["checksums"][name] = now
            atomic_write(manifest_file(self.path), json.dumps(manifest, indent=2).encode())
        return MotionDB.open(self.path)

    @classmethod
    def create(cls, path) -> MotionDB:
        """An empty MotionDB at ``path`` (which must not exist or be an empty directory).

        Parameters
        ----------
        path : str or os.PathLike
            The new database folder.

        Returns
        -------
        MotionDB
            Generation 0, no documents.

        Raises
        ------
        MotionDBError
            ``path`` exists and is not an empty directory (a lock file and temporary files left by a killed ingest
            do not count).
        """
        path = Path(path)
        leftovers = [f for f in path.iterdir() if f.name == store.LOCK_FILE or f.name.endswith(".tmp")] \
            if path.is_dir() else []  # (of a killed ingest that was removing the database it created)
        if path.exists() and (not path.is_dir() or len(leftovers) < len(list(path.iterdir()))):
            raise MotionDBError(f"{path}: exists and is not an empty directory")
        with contextlib.suppress(OSError):
            for f in leftovers:
                f.unlink()
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
               markers_only: str = "refuse", **load_options) -> MotionDB:
        """Read motion files into the MotionDB at ``out``, creating it or appending to it.

        Every take of an FBX file is a document (only ``take`` if given; docs/fbx.md). Documents already in the
        database (same file sha256, and same take of an FBX file) are skipped, so re-running an interrupted ingest
        continues where it stopped. Nothing is written until every file has been read; then the new
        documents are committed at once (atomically).

        Parameters
        ----------
        paths : str, os.PathLike or list of them
            Files, folders (searched recursively for .amc / .bvh / .c3d / .fbx) or glob patterns.
        out : str or os.PathLike
            The database directory.
        fps : float, optional
            Resample every document to this rate (e.g. 120 for relational indexing, 30 for kNN).
        labels : path, DataFrame or dict, optional
            A label table (``file`` or ``path`` column plus label columns; TSV or CSV) or
            {path or file name: {column: value}}. Default: the label tables found beside the data
            (``labels.tsv``, Bandai Namco ``.json``), see :func:`mocapviz.io.labels.labels_for`.
        mapping : dict, optional
            Canonical joint -> joint name for rigs the automatic rules cannot map; for C3D marker files, marker
            of the marker set -> the files' marker name (:func:`mocapviz.motion.markers.marker_joints`).
        skip_bad : bool
            Skip files that fail to read (with a warning) instead of stopping.
        threads : int, optional
            Threads reading files in this process (the parsers' compiled kernels release the GIL); None:
            :func:`mocapviz.parallel.default_threads` (on 2 cores the 287 HDM05 clips take 0.90 s on 2 threads, 0.99 s
            on 1). Ignored when ``scheduler`` is given. (Formerly ``n_jobs``, reader processes: still accepted, with
            a FutureWarning.)
        progress : bool
            Show a progress bar.
        scheduler : None, "local", str or dask.distributed.Client
            Read the files as Dask tasks, a few files each (:func:`mocapviz.parallel.dask_client`): ``"local"``
            starts a local cluster of worker processes for this call, an address connects to a running scheduler
            (its workers must see the same paths), a Client is used as it is. None (default): on ``threads``
            threads in this process. The results are committed here, in input order, whatever order the tasks
            finish in.
        markers_only : {"refuse", "keep"}
            A C3D file whose markers match no marker set: refused like any unmappable file (default), or kept as a
            marker-only document (:mod:`mocapviz.db.marker_documents`: its markers stored at the file's rate, a row
            in their own table, no canonical frames; :attr:`marker_documents`).
        **load_options
            Passed to :func:`mocapviz.load` (``asf``, ``up``, ``scale``, ``take``: that take of each FBX file).

        Returns
        -------
        MotionDB

        Raises
        ------
        MocapFormatError, SkeletonMappingError
            A file fails to read and ``skip_bad`` is false; the database is left as it was.
        MotionDBError
            ``out`` exists but is not a MotionDB, or its frame rate differs from ``fps``.

        Warns
        -----
        MocapFormatWarning
            A file read with a part left out (an AMC cut off inside its last frame), naming the file and the line.

        Examples
        --------
        >>> import tempfile
        >>> from mocapviz.io import datasets
        >>> amc = datasets.sample() / "hdm05-cut" / "amc"
        >>> files = [amc / "HDM_dg_squat1Reps_033_120.amc", amc / "HDM_mm_squat1Reps_037_120.amc"]
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     db = MotionDB.ingest(files, f"{tmp}/squats.mdb", progress=False)
        ...     again = db.append(files[0], progress=False)  # already held (same sha256): skipped
        ...     print(db.documents[["doc_id", "label", "actor", "n_frames"]].to_string(index=False))
        ...     print(len(again), again.n_frames, again.fps)
         doc_id      label actor  n_frames
              0 squat1Reps    dg       159
              1 squat1Reps    mm       189
        2 348 120.0
        """
        out = Path(out)
        files = expand_paths(paths)
        options = IngestOptions(fps, labels, mapping, skip_bad, threads, progress, scheduler, load_options,
                                one_of(markers_only, "markers_only", MARKERS_ONLY))
        retries = 2  # again when a concurrent failed ingest removed the empty database it created
        while True:
            created = False
            if not manifest_file(out).exists():
                try:
                    cls.create(out)
                    created = True
                except MotionDBError:
                    if not manifest_file(out).exists():  # (not another ingest that created it first)
                        raise
            try:
                return cls.open(out)._append_files(files, options)
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
               markers_only: str = "refuse", **load_options) -> MotionDB:
        """Add motion files to this database; see :meth:`ingest`.

        The writer lock is held for the whole transaction (what the database holds is read, the files are read,
        the new documents are committed), so a second writer waits; when it goes on, it sees the documents the
        first committed and skips those files.

        Parameters
        ----------
        paths : str, os.PathLike or list of them
            Files, folders or glob patterns, as for :meth:`ingest`.
        fps, labels, mapping, skip_bad, threads, progress, scheduler, markers_only, **load_options
            As for :meth:`ingest`.

        Returns
        -------
        MotionDB
            The database reopened at its new generation (this object is left as it was).
        """
        options = IngestOptions(fps, labels, mapping, skip_bad, threads, progress, scheduler, load_options,
                                one_of(markers_only, "markers_only", MARKERS_ONLY))
        return self._append_files(expand_paths(paths), options)

    def _append_files(self, files: list[Path], options: IngestOptions) -> MotionDB:
        with _locked(self.path):
            current = _reopen(self.path)
            fps = options.fps
            if fps is not None and len(current) and current.fps != float(fps):
                raise MotionDBError(f"{current.path}: documents are at {current.fps} fps; cannot append at {fps} fps")
            if fps is None and current.fps is not None and len(current):
                options = dataclasses.replace(options, fps=current.fps)
            known = held_documents(current.documents)
            for sha256 in current.marker_documents.documents["sha256"]:  # marker-only documents: files held whole
                known.setdefault(sha256, set()).add(None)
            positions, quaternions, metas = read_new(files, known, options)
            only = {i for i, meta in enumerate(metas) if meta.get("markers_only")}
            if only:  # their own table, never the frame arrays (mocapviz.db.marker_documents)
                add_marker_documents(current.path, [_marker_motion(positions[i], metas[i]) for i in sorted(only)],
                                     [metas[i] for i in sorted(only)])  # fmt: skip
                positions, quaternions, metas = ([x for i, x in enumerate(xs) if i not in only]
                                                 for xs in (positions, quaternions, metas))  # fmt: skip
            if positions:
                _commit(current.path, current.manifest, positions, quaternions, metas)
        db = MotionDB.open(self.path)
        if any(m.get("format") == "c3d" for m in metas):  # the raw markers beside the joints (mocapviz.db.markers)
            from .markers import store_markers

            new = {m["sha256"] for m in metas}
            store_markers(db, db.documents.loc[db.documents["sha256"].isin(new), "doc_id"])
        return db

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
        MotionDB
            The database reopened at its new generation.

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


# ---------------------------------------------------------------------- storage helpers
def _marker_motion(positions: np.ndarray, meta: dict) -> Motion:
    """A marker-only document as ingest read it (:func:`mocapviz.db.ingest.read_new`): a marker Motion."""
    return Motion(positions=positions, fps=float(meta["fps"]), joint_names=tuple(meta["markers"]),
                  parents=np.full(positions.shape[1], -1, dtype=np.int64), source=meta["path"])  # fmt: skip


def _locked(path: Path):
    """The database's writer lock (:func:`mocapviz.store.locked`): one writer at a time, a second one waits."""
    if not manifest_file(path).is_file():
        raise MotionDBError(f"{path}: not a MotionDB (no manifest.json); it may have been removed by a failed ingest")
    return store.locked(path)


class _Gone(MotionDBError):
    """A file the manifest names is not there (deleted by a writer after the manifest was read, or lost)."""


def _exists(f: Path) -> None:
    if not f.is_file():
        raise _Gone(f"{f}: missing; {_RESTORE}")


class _Vanished(MotionDBError):
    """The database was removed while this writer waited for its lock (a concurrent fresh ingest failed)."""


def _reopen(path: Path) -> MotionDB:
    """The database as it is now (called under the writer lock: another writer may have committed meanwhile)."""
    if not manifest_file(path).is_file():
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
    f = manifest_file(path)
    if not f.is_file():
        if not Path(path).exists():
            raise MotionDBError(f"{path}: does not exist (a MotionDB is a folder holding a manifest.json)")
        raise MotionDBError(f"{path}: not a MotionDB (no manifest.json)")
    try:
        manifest = json.loads(f.read_text())
    except (OSError, ValueError) as exc:
        raise MotionDBError(f"{f}: unreadable ({exc})") from None
    return _check_manifest(check_format(manifest, FORMAT, VERSION, f), f)


_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")  # a plain file name inside the database folder
_COUNT, _TEXT = ("a whole number >= 0", lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0), \
    ("a string", lambda v: isinstance(v, str))
_FILE = ("a plain file name inside the database folder", lambda v: isinstance(v, str) and bool(_NAME.fullmatch(v)))
_MANIFEST = {  # key: (what it must be, check); every key required but "checksums" (manifests before fingerprints)
    "format": _TEXT, "version": _COUNT, "written_by": _TEXT, "generation": _COUNT, "n_frames": _COUNT,
    "joint_names": ("the 24 canonical joint names", lambda v: v == list(CANONICAL_JOINTS)),
    "arrays": ("{\"positions\": FILE, \"quaternions\": FILE}",
               lambda v: isinstance(v, dict) and sorted(v) == sorted(_ARRAYS) and all(map(_FILE[1], v.values()))),
    "documents": _FILE,
    "checksums": ("{FILE: {\"size\": BYTES, \"sha256\": HEX, ...}}",
                  lambda v: isinstance(v, dict) and all(_FILE[1](k) and isinstance(c, dict) and _COUNT[1](c.get("size"))
                                                        and isinstance(c.get("sha256"), str) for k, c in v.items())),
}  # fmt: skip


def _check_manifest(manifest: dict, f: Path) -> dict:
    """The one check of a manifest's schema (:data:`_MANIFEST`): MotionDBError naming the key and what it must be
    for anything missing, mistyped or unknown; file names must be plain names inside the database folder."""
    unknown = sorted(set(manifest) - set(_MANIFEST))
    if unknown:
        raise MotionDBError(f"{f}: damaged manifest: unknown key {unknown[0]!r} (a manifest holds "
                            f"{', '.join(_MANIFEST)}); {_RESTORE}")  # fmt: skip
    for key, (what, ok) in _MANIFEST.items():
        if key not in manifest:
            if key == "checksums":
                continue
            raise MotionDBError(f"{f}: damaged manifest: no {key!r} (it must be {what}); {_RESTORE}")
        if not ok(manifest[key]):
            raise MotionDBError(f"{f}: damaged manifest: {key!r} is {json.dumps(manifest[key])[:80]}, it must be "
                                f"{what}; {_RESTORE}")  # fmt: skip
    manifest.setdefault("checksums", {})
    return manifest


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


def _stored(column: pd.Series) -> pd.Series:
    """A column of the documents table as written: whole numbers as int64, or as nullable Int64 where some documents
    have none (HDM05's ``take`` beside another archive's takes: 17 and a missing cell, not 17.0 and NaN), text as
    strings, other values as pandas infers them."""
    if column.dtype != object:
        return column
    if pd.api.types.infer_dtype(column, skipna=True) == "integer":
        return column.astype("Int64" if column.isna().any() else "int64")
    column = column.infer_objects()
    return column.astype("string") if column.dtype == object else column


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
        target = generation_file(path, name, gen)
        old = None if manifest is None else path / manifest["arrays"][name]
        _write_grown(old, n_old, positions if name == "positions" else quaternions, width, target)
        files[name] = target.name
    new_docs = pd.DataFrame(metas, dtype=object)  # typed by _stored with the old documents' values
    if len(new_docs):
        new_docs.insert(0, "doc_id", np.arange(len(new_docs)) + (int(old_docs["doc_id"].max()) + 1 if len(old_docs) else 0))
        new_docs["start"] = n_old + np.concatenate([[0], np.cumsum(new_docs["n_frames"].to_numpy(np.int64))[:-1]])
    docs = pd.concat([old_docs.astype(object), new_docs], ignore_index=True) if len(old_docs) else new_docs
    if docs.empty:
        docs = pd.DataFrame({c: pd.Series(dtype="int64" if c in ("doc_id", "start", "n_frames") else "float64" if "fps" in c else "object") for c in _BASE_COLUMNS})
    for c in _BASE_COLUMNS:  # a clip without a label (a derived copy, a take from memory) has no label column
        if c not in docs:
            docs[c] = None
    docs = docs[_BASE_COLUMNS + [c for c in docs.columns if c not in _BASE_COLUMNS]]
    for c in ("doc_id", "start", "n_frames"):
        docs[c] = docs[c].astype("int64")
    for c in docs.columns:
        docs[c] = _stored(docs[c])
    doc_file = generation_file(path, "documents", gen)
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
    atomic_write(manifest_file(path), json.dumps(new_manifest, indent=2).encode())
    for f in path.iterdir():
        older = generation_of(f.name)
        if (older is not None and older <= gen - _KEEP_GENERATIONS) or f.name.endswith(".tmp"):
            with contextlib.suppress(FileNotFoundError):
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
                if f in (manifest_file(path), path / store.LOCK_FILE) or generation_of(f.name) is not None \
                        or f.name.endswith(".tmp"):
                    f.unlink()
    except (MotionDBError, OSError):  # another writer is in it, or it is gone: leave it
        return
    with contextlib.suppress(OSError):
        path.rmdir()
