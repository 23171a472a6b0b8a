"""A take of the user's own as the query of every query page (docs/dashboard.md, "Your take as the query").

:class:`UploadBox` is the one upload widget, shown beside the query-clip picker of the query pages: a BVH, an AMC
with its ASF (both files, or a zip holding both) or a C3D, at most :data:`MAX_UPLOAD_BYTES` and
:data:`MAX_UPLOAD_FRAMES`, read in a worker thread by :func:`read_upload` with the readers and rig mapping of ingest
(:meth:`mocapviz.engine.Engine.example`: resampled to the database's rate), kept in a temporary folder of the
session (:func:`session_folder`, deleted when the session ends). The take, an :class:`Upload`, becomes the session's
query clip (``Selection.upload``, ``use_upload``, ``upload_span``); the pickers offer it as "uploaded: NAME (T
frames)" (:data:`~mocapviz.app.documents.UPLOADED`). With the role to add takes, "Add to the database" ingests it
(:func:`add_to_database`).

A page's computation takes a query as a document id or an :class:`Upload`: :func:`example` is what the engine is
given, :func:`query_clip` the frames the player shows, :func:`cache_key` what the Backend keys answers by (an
upload by its checksum: the key holds no clip).
"""

from __future__ import annotations

import hashlib
import io
import logging
import shutil
import tempfile
import weakref
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePath

import numpy as np
import panel as pn

from ..engine import update_derived
from ..errors import MocapFormatError, ParameterError, SkeletonMappingError
from ..validation import plural
from .auth import can
from .progress import Task

LOG = logging.getLogger("mocapviz.app")
# the largest upload (all its files, a zip's content unpacked): a BVH of 100,000 frames of a 60-joint rig is about
# 50 MB; the file crosses the WebSocket in base64 (4/3 of it) and is held in memory while it is read
MAX_UPLOAD_BYTES = 50_000_000
# the most frames a take may hold: every use case compares each query frame with the database (DTW, the LNG's k
# nearest frames of every query frame), so a longer query takes minutes; 100,000 frames are 14 min at 120 Hz
MAX_UPLOAD_FRAMES = 100_000
# Bokeh's WebSocket message limit (20 MB by default) raised so that an upload over the limit still arrives and is
# refused by name, rather than closing the session's connection: base64 of twice the limit, and the message around it
UPLOAD_MESSAGE_BYTES = 3 * MAX_UPLOAD_BYTES
MOTION_SUFFIXES = (".bvh", ".c3d", ".amc")
ACCEPTED = (*MOTION_SUFFIXES, ".asf", ".zip")
LIMITS = (f"BVH, C3D, or an AMC with its ASF (both files, or a zip holding both); at most "
          f"{MAX_UPLOAD_BYTES / 1e6:g} MB and {MAX_UPLOAD_FRAMES:,} frames; kept for this session only")


@dataclass(frozen=True)
class Upload:
    """A take uploaded in a session, read as the use cases read an example.

    Attributes
    ----------
    name : str, the motion file's name as uploaded (an AMC's, its ASF beside it).
    sha256 : str, the checksum of the uploaded files' bytes (what answers of it are cached by).
    path : Path, the motion file in the session's folder.
    asf : Path or None, an AMC's skeleton, beside it.
    motion : Motion, the take at the database's rate, its source joints (:meth:`Engine.example`).
    positions : np.ndarray [shape=(T, 24, 3)], float32, cm: its canonical joints, as the player draws them.
    """

    name: str
    sha256: str
    path: Path = field(compare=False)
    asf: Path | None = field(compare=False)
    motion: object = field(compare=False, repr=False)
    positions: np.ndarray = field(compare=False, repr=False)

    @property
    def n_frames(self) -> int:
        return int(self.motion.n_frames)

    @property
    def fps(self) -> float:
        return float(self.motion.fps)

    @property
    def title(self) -> str:
        """The take as pickers list it: "uploaded: NAME (T frames)"."""
        return f"uploaded: {self.name} ({plural(self.n_frames, 'frame')})"


def _bytes_within_limit(files) -> None:
    total = sum(len(data) for _, data in files)
    if total > MAX_UPLOAD_BYTES:
        names = ", ".join(name for name, _ in files)
        raise ParameterError(f"{names}: {total / 1e6:.1f} MB is over the upload limit of {MAX_UPLOAD_BYTES / 1e6:g} MB")


def _unzipped(name: str, data: bytes) -> list[tuple[str, bytes]]:
    """The motion and skeleton files of a zip (folders inside it ignored), their unpacked sizes checked first."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            members = [m for m in archive.infolist() if not m.is_dir() and PurePath(m.filename).suffix.lower()
                       in (*MOTION_SUFFIXES, ".asf")]  # fmt: skip
            _bytes_within_limit([(m.filename, range(m.file_size)) for m in members])
            return [(PurePath(m.filename).name, archive.read(m)) for m in members]
    except zipfile.BadZipFile as exc:
        raise MocapFormatError(name, f"not a readable zip ({exc})") from None


def _motion_file(files) -> tuple[str, str | None]:
    """(the motion file's name, its ASF's name or None) among the uploaded names."""
    motions = [n for n in files if PurePath(n).suffix.lower() in MOTION_SUFFIXES]
    others = [n for n in files if PurePath(n).suffix.lower() not in (*MOTION_SUFFIXES, ".asf")]
    if others:
        raise MocapFormatError(others[0], f"unsupported file type; upload one of {', '.join(ACCEPTED)}")
    if len(motions) != 1:
        found = ", ".join(motions) or "none"
        raise ParameterError(f"upload one take: one BVH, C3D or AMC file (with its ASF); got {found}")
    motion = motions[0]
    asfs = [n for n in files if PurePath(n).suffix.lower() == ".asf"]
    if PurePath(motion).suffix.lower() != ".amc":
        return motion, None
    if len(asfs) != 1:
        raise MocapFormatError(motion, "an AMC needs its ASF skeleton: upload both files at once, or a zip holding "
                                       "both" if not asfs else f"one ASF skeleton, not {len(asfs)}")  # fmt: skip
    return motion, asfs[0]


def read_upload(engine, files, folder) -> Upload:
    """Read an uploaded take as the use cases read an example.

    Parameters
    ----------
    engine : mocapviz.engine.Engine
        The database's engine (its :meth:`~mocapviz.engine.Engine.example`: the readers of ingest, the database's
        rate).
    files : sequence of (str, bytes)
        The uploaded files' names and contents: one BVH or C3D; an AMC and its ASF; or one zip holding them.
    folder : str or os.PathLike
        An empty folder to write them to (the session's, :func:`session_folder`); the motion file goes into an
        ``uploads`` folder in it (the archive :func:`~mocapviz.app.documents.archive_of` names, once added).

    Returns
    -------
    Upload

    Raises
    ------
    ParameterError
        Over :data:`MAX_UPLOAD_BYTES` (the zip's content unpacked too) or :data:`MAX_UPLOAD_FRAMES`; not one take.
    MocapFormatError
        A file that cannot be read, named with its line (not the session's folder); an AMC without its ASF.
    SkeletonMappingError
        A rig whose joints cannot be mapped to the canonical ones, named with the file.
    """
    files = list(files)
    _bytes_within_limit(files)
    if len(files) == 1 and PurePath(files[0][0]).suffix.lower() == ".zip":
        files = _unzipped(*files[0])
    contents = {PurePath(name).name: data for name, data in files}  # names without any folder of the browser's
    motion_name, asf_name = _motion_file(contents)
    where = Path(folder) / "uploads"
    where.mkdir(parents=True, exist_ok=True)
    for name, data in contents.items():
        (where / name).write_bytes(data)
    path, asf = where / motion_name, (where / asf_name if asf_name else None)
    try:
        raw = engine.example(path)  # an AMC's ASF is found beside it: the one uploaded with it
    except MocapFormatError as exc:  # named by the file's own name, not the session's folder
        raise MocapFormatError(PurePath(exc.path).name if exc.path else motion_name, exc.reason, exc.line) from None
    if raw.n_frames > MAX_UPLOAD_FRAMES:
        raise ParameterError(f"{motion_name}: {raw.n_frames:,} frames at {raw.fps:g} fps is over the upload limit "
                             f"of {MAX_UPLOAD_FRAMES:,} frames")  # fmt: skip
    try:
        positions = raw.canonical().positions
    except SkeletonMappingError as exc:
        raise SkeletonMappingError(f"{motion_name}: {exc}") from None
    sha = hashlib.sha256(b"".join(contents[n] for n in sorted(contents))).hexdigest()
    return Upload(motion_name, sha, path, asf, raw, np.ascontiguousarray(positions, dtype=np.float32))


_FOLDERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # Selection -> its session's upload folder


def session_folder(selection) -> Path:
    """The temporary folder of ``selection``'s session for uploads, made the first time it is asked for and deleted
    when the session ends (``pn.state.on_session_destroyed``; outside a served session, when Python exits)."""
    folder = _FOLDERS.get(selection)
    if folder is None:
        folder = _FOLDERS[selection] = Path(tempfile.mkdtemp(prefix="mocapviz-upload-"))
        if pn.state.curdoc is not None and pn.state.curdoc.session_context is not None:
            pn.state.on_session_destroyed(lambda context, folder=folder: _remove(folder))
        else:
            weakref.finalize(selection, _remove, folder)
        LOG.info("uploads of a session in %s", folder)
    return folder


def _remove(folder: Path) -> None:
    shutil.rmtree(folder, ignore_errors=True)
    LOG.info("uploads of a session removed: %s", folder)


def example(query):
    """What the engine is given for a query: a document id as it is, an :class:`Upload`'s Motion."""
    return query.motion if isinstance(query, Upload) else int(query)


def cache_key(query):
    """A query as the Backend keys its answers: a document id, or ("upload", checksum) (no clip held by the key)."""
    return ("upload", query.sha256) if isinstance(query, Upload) else int(query)


def query_clip(backend, query, start: int, end: int) -> np.ndarray:
    """Frames start:end (half-open) of a query, on the canonical joints: (T, 24, 3) float32, cm."""
    from ..engine import database_frames

    if isinstance(query, Upload):
        return query.positions[start:end]
    return backend.db.positions[database_frames(backend.db, int(query), start, end)]


def query_frames(backend, query) -> int:
    """The frames of a query (a document's or an upload's)."""
    return query.n_frames if isinstance(query, Upload) else int(backend.db.document(int(query))["n_frames"])


def query_fps(backend, query) -> float:
    return query.fps if isinstance(query, Upload) else backend.fps_of(int(query))


def query_name(backend, query, named: bool = False) -> str:
    """A query as captions name it: "document 7" ("document 7 (NAME)" when ``named``) or "uploaded NAME"."""
    if isinstance(query, Upload):
        return f"uploaded {query.name}"
    return f"document {int(query)}" + (f" ({backend.db.document(int(query))['name']})" if named else "")


def add_to_database(backend, upload: Upload) -> list[int]:
    """Ingest an uploaded take into the served database (:meth:`MotionDB.append`, the database's rate), extend its
    stored derived data (:func:`mocapviz.engine.update_derived`) and switch the Backend to the new generation
    (:meth:`Backend.follow`: every session's pickers list the new document).

    Returns
    -------
    list of int
        The new document's id (empty when the database holds this file already: ingest skips it by checksum).
    """
    before = set(backend.db.documents["doc_id"].tolist())
    db = backend.db.append([upload.path], progress=False, **({"asf": upload.asf} if upload.asf else {}))
    update_derived(db)
    backend.follow()
    return sorted(set(db.documents["doc_id"].tolist()) - before)


class UploadBox(pn.viewable.Viewer):
    """The upload widget of a query page: a file input, the limits, the take read (or its typed error) and, with
    the role to add takes, "Add to the database". An upload becomes the session's query clip
    (``selection.upload``, ``use_upload`` and ``upload_span``: all of it)."""

    def __init__(self, backend, selection, css_prefix: str = "mv-upload"):
        super().__init__()
        self.backend, self.selection = backend, selection
        self.input = pn.widgets.FileInput(accept=",".join(ACCEPTED), multiple=True, css_classes=[f"{css_prefix}-input"])
        self.limits = pn.pane.Markdown(f"**Your take as the query** — {LIMITS}.", margin=(0, 10))
        self.task = Task()
        self.task.error.css_classes = [f"{css_prefix}-error"]  # told apart from the page's own task's error
        self.info = pn.pane.Markdown("", margin=(0, 10), css_classes=[f"{css_prefix}-info"])
        self.add = pn.widgets.Button(label="Add to the database", visible=False, width=180,
                                     css_classes=[f"{css_prefix}-add"])
        self.input.param.watch(self._on_files, "value")
        self.add.on_click(self._on_add)
        selection.param.watch(lambda event: self._show(), "upload")
        self._show()

    def __panel__(self):
        return pn.Column(self.limits, self.input, self.task, self.info, self.add, margin=0)

    def _show(self) -> None:
        upload = self.selection.upload
        self.info.object = "" if upload is None else (
            f"**{upload.title}** at {upload.fps:g} fps: the query clip of the query pages, until another clip is "
            "chosen")
        self.add.visible = upload is not None and can(None, "add takes")

    async def _on_files(self, event) -> None:
        values, names = self.input.value, self.input.filename
        if not values:
            return
        values = values if isinstance(values, list) else [values]
        names = names if isinstance(names, list) else [names]
        where = Path(tempfile.mkdtemp(dir=session_folder(self.selection)))
        upload = await self.task.run(f"Reading {', '.join(names)}", read_upload, self.backend.engine,
                                     list(zip(names, values)), where)
        previous = self.selection.upload
        if upload is None:  # refused: the take before stays the query, with its files
            shutil.rmtree(where, ignore_errors=True)
            return
        if previous is not None:  # one take kept per session: the one before goes
            shutil.rmtree(previous.path.parent.parent, ignore_errors=True)
        self.selection.param.update(upload=upload, use_upload=True, upload_span=(0, upload.n_frames))

    async def _on_add(self, event) -> None:
        upload = self.selection.upload
        if upload is None or not can(None, "add takes"):
            return
        added = await self.task.run(f"Adding {upload.name} to the database", add_to_database, self.backend, upload,
                                    busy=self.add)
        if added is not None:
            self.info.object = (f"**{upload.name}** added to the database as document {added[0]}." if added else
                                f"**{upload.name}** is in the database already (a file of the same checksum).")
