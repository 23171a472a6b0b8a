"""One stretch of one document as files: its source cut on its own rig, or the database's frames on the canonical rig.

stretch_files     (doc_id, start, end) -> {file name: bytes}: the export of one hit, in memory.
export_stretch    the same written into a folder (all or nothing, :func:`write_files`); returns the paths.
source_frames     a stretch at the database's rate -> the same seconds in frames of its source file.
write_files       files made one group at a time written into a folder, all or nothing.

What each combination writes (docs/export.md):

========= ============ =================================================================================================
format    rig          file(s)
========= ============ =================================================================================================
bvh       source       BVH source: its header and exactly its frame lines; AMC source: a BVH on the ASF rig; FBX
                       source: its joints posed to the document's take (as glb)
amc       source       the AMC's header and frame blocks (renumbered from 1), beside a copy of its ASF
glb       source       the source file's joints posed to the source's positions (glTF binary; FBX: the document's
                       take, ``fbx_take``)
bvh, glb  canonical    the 24 canonical joints (upright T-pose at rest) posed to the database's positions (0.01 cm)
humanml3d canonical    HumanML3D's 22 joints, (T, 22, 3) float32 ``.npy`` at 20 fps in metres, and ``manifest.csv``
                       (:mod:`mocapviz.export.joint_arrays`)
========= ============ =================================================================================================
"""
from __future__ import annotations

import contextlib
import fcntl
import json
import os
import re
import shutil
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from .. import store
from .._version import __version__
from ..errors import ParameterError, SourceFileError
from ..validation import frame_span, one_of
from .formats import CANONICAL_ONLY, EXTENSIONS, FORMATS, RIGS, default_rig

STAGING = ".export"  # the suffix of the hidden folder an export is written into before it is moved into place


def source_frames(row, start: int, end: int) -> tuple[int, int]:
    """Frames ``start:end`` of a document at the database's rate as frames of its source file (the same seconds).

    A database resampled at ingest (``fps`` other than ``source_fps``) holds frame ``k`` at ``k / fps`` seconds; the
    source frame at that time is ``k * source_fps / fps``. The stretch becomes source frames ``round(start * r)`` to
    ``round((end - 1) * r) + 1`` (``r = source_fps / fps``, half-open): from the first frame's time to the last's.

    Parameters
    ----------
    row : pandas.Series
        The document's row of ``db.documents`` (``fps``, ``source_fps``).
    start, end : int
        Frames at the database's rate, half-open.

    Returns
    -------
    (int, int)
        Source frames, half-open.

    Examples
    --------
    >>> source_frames({"fps": 30.0, "source_fps": 120.0}, 10, 20)
    (40, 77)
    """
    r = float(row["source_fps"]) / float(row["fps"])
    if r == 1.0:
        return int(start), int(end)
    return round(start * r), round((end - 1) * r) + 1


def _checked_source(row) -> Path:
    """The document's source file, or a SourceFileError when it is gone or is not the file that was ingested."""
    from ..db.ingest import file_checksum

    path = Path(row["path"])
    doc = f"document {int(row['doc_id'])} ({row['name']})"
    way_out = "export it with --rig canonical (rig='canonical': from the database's own frames) or restore the file"
    if not path.is_file():
        raise SourceFileError(f"{path}: the source file of {doc} is gone; {way_out}")
    digest = file_checksum(path)
    if digest != row["sha256"]:
        raise SourceFileError(f"{path}: the source file of {doc} has changed since it was ingested (sha256 "
                              f"{digest[:12]}..., the database has {str(row['sha256'])[:12]}...); {way_out}")
    return path


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", str(name)).strip("_") or "document"


def file_stem(rank: int, digits: int, doc_id: int, name: str, start: int, end: int, format: str) -> str:
    """``<rank>_doc<doc_id>_<name>_<start>-<end>``: one name per hit (rank, document and frames), the document's
    name cleaned to ``A-Z a-z 0-9 . _ -`` and cut so that the stem and ``.<format>`` fit
    :data:`mocapviz.store.NAME_MAX` bytes.

    Parameters
    ----------
    rank : int
        The hit's rank.
    digits : int
        Digits of the rank (at least; zero-padded).
    doc_id : int
        The document.
    name : str
        The document's name.
    start, end : int
        Its frames, half-open.
    format : str
        The extension without its dot (``bvh``, ``amc``, ``asf``, ``glb``, ``npy``: three letters).

    Returns
    -------
    str
        The file name without ``.<format>``.

    Examples
    --------
    >>> file_stem(1, 3, 4, "a b", 0, 70, "bvh"), file_stem(1, 3, 6, "a_b", 0, 70, "bvh")
    ('001_doc4_a_b_0-70', '001_doc6_a_b_0-70')
    >>> len(file_stem(1, 3, 9, "x" * 240, 0, 70, "bvh") + ".bvh")
    255
    """
    head, tail = f"{int(rank):0{digits}d}_doc{int(doc_id)}_", f"_{int(start)}-{int(end)}"
    room = store.NAME_MAX - len(f"{head}{tail}.{format}")  # ASCII: characters are bytes in any encoding
    return f"{head}{_safe(name)[:max(room, 1)]}{tail}"


def _plain(value):
    """A JSON value of a table cell (numpy scalars as Python numbers, NaN as None)."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value if isinstance(value, (int, float, str, bool, type(None))) else str(value)


def stretch_files(db, doc_id: int, start: int | None = None, end: int | None = None, format: str = "bvh",
                  rig: str | None = None, rank: int = 1, search: str | None = None, scores: dict | None = None,
                  digits: int = 3) -> dict[str, bytes]:
    """The files of one exported stretch, in memory.

    Parameters
    ----------
    db : MotionDB
        The database holding the document.
    doc_id : int
        The document.
    start, end : int, optional
        Frames within the document at the database's rate, half-open (default: all).
    format : {"bvh", "amc", "glb", "humanml3d"}
        BVH, AMC (with its ASF; an ASF/AMC source only), glTF binary or HumanML3D's joint array (canonical rig
        only; :mod:`mocapviz.export.joint_arrays`).
    rig : {"source", "canonical"}, optional
        The source file's own rig, or the 24 canonical joints; default
        :func:`~mocapviz.export.formats.default_rig`.
    rank : int
        The hit's rank: the file names start with it (``001_...``).
    search : str, optional
        What found the stretch (a query, a description, a hits file), written into the files.
    scores : dict, optional
        The search's own columns of the hit (``cost``, ``score``, ...), written into the files.
    digits : int
        Digits of the rank in the file names (at least; enough for ``rank``).

    Returns
    -------
    dict
        File name -> bytes: ``<rank>_doc<doc_id>_<name>_<start>-<end>.<format>`` (and the ``.asf`` of an AMC;
        ``.npy`` and ``manifest.csv`` for ``humanml3d``; :func:`file_stem`, at most 255 bytes). Each file names its
        source document, frames, rig and search: a ``# mocapviz export: {JSON}`` comment line (BVH, AMC), the same
        JSON object as ``asset.extras`` and scene ``extras`` (glTF), the manifest's row (HumanML3D).

    Raises
    ------
    ParameterError
        An unknown document, format or rig, frames outside the document, AMC asked of a BVH source or of the canonical
        rig, HumanML3D asked on the source rig.
    SourceFileError
        ``rig="source"`` and the source file is gone or changed since it was ingested.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> files = stretch_files(MotionDB.sample(), 7, 0, 60, format="amc", search="an example")
    >>> sorted(files)
    ['001_doc7_HDM_dg_kickLFront1Reps_017_120_0-60.amc', '001_doc7_HDM_dg_kickLFront1Reps_017_120_0-60.asf']
    """
    one_of(format, "export format", FORMATS)
    rig = default_rig(format) if rig is None else one_of(rig, "rig", RIGS)
    row = db.document(int(doc_id))
    start, end = frame_span((start, end), int(row["n_frames"]), f"document {int(doc_id)}", least=1)
    if format == "amc" and (rig == "canonical" or row["format"] != "amc"):
        raise ParameterError(f"format 'amc' copies the frames of an ASF/AMC source on its own rig; document "
                             f"{int(doc_id)} is {row['format']!r}{' on the canonical rig' if rig == 'canonical' else ''}: "
                             "export it as 'bvh' or 'glb'")  # fmt: skip
    if format in CANONICAL_ONLY and rig != "canonical":
        raise ParameterError(f"format {format!r} is made from the database's 24 canonical joints; export it with "
                             "rig='canonical' (--rig canonical, the default for it)")  # fmt: skip
    if format == "bvh" and rig == "source" and row["format"] == "c3d":
        raise ParameterError(f"document {int(doc_id)} was read from a C3D file: markers, no rig to write as BVH; "
                             "export it on the canonical rig (rig='canonical', --rig canonical) or as 'glb' on its "
                             "source (its markers as points)")  # fmt: skip
    a, b = source_frames(row, start, end)
    meta = {"exported_by": f"mocapviz {__version__}", "database": str(db.path), "doc_id": int(doc_id),
            "name": str(row["name"]), "source": str(row["path"]), "sha256": str(row["sha256"]),
            "frames": [start, end], "fps": float(row["fps"]), "source_frames": [a, b],
            "source_fps": float(row["source_fps"]), "format": format, "rig": rig, "rank": int(rank),
            "search": search, "scores": {k: _plain(v) for k, v in (scores or {}).items()}}  # fmt: skip
    stem = file_stem(rank, digits, doc_id, row["name"], start, end, EXTENSIONS[format])
    notes = [f"mocapviz export: {json.dumps(meta)}"]
    if format == "humanml3d":
        from .joint_arrays import array_files

        return array_files(db.motion(int(doc_id))[start:end], stem, meta)
    if rig == "canonical":
        return {f"{stem}.{format}": _canonical(db, int(doc_id), start, end, format, notes, meta)}
    take = row.get("fbx_take")  # an FBX document's take; a missing cell (another format) is no str
    return _source(_checked_source(row), take if isinstance(take, str) else None, stem, a, b, format, notes, meta)


def _posed(motion, a: int, b: int, rest: np.ndarray, format: str, notes: list, meta: dict) -> bytes:
    """Frames a:b of ``motion`` on its own joints with rest offsets ``rest`` (J, 3), cm, as BVH or glTF."""
    from ..io.bvh_writer import pose_bvh
    from ..io.gltf_writer import pose_glb
    from ..motion.rig import fit_pose

    pose = fit_pose(motion.positions[a:b], motion.parents, rest)
    if format == "bvh":
        return pose_bvh(motion.joint_names, motion.parents, pose, motion.fps, notes)
    return pose_glb(motion.joint_names, motion.parents, pose, motion.fps, meta)


def _canonical(db, doc_id: int, start: int, end: int, format: str, notes: list, meta: dict) -> bytes:
    """The canonical rig in its standard rest pose, bone lengths of the whole document (one rig for every stretch)."""
    from ..motion.rig import canonical_rest

    motion = db.motion(doc_id)
    return _posed(motion, start, end, canonical_rest(motion.positions), format, notes, meta)


def _source(path: Path, take: str | None, stem: str, a: int, b: int, format: str, notes: list,
            meta: dict) -> dict[str, bytes]:  # fmt: skip
    """The files of source frames a:b of ``path`` (of FBX take ``take``) on the source's own rig."""
    from ..io import find_asf, load, read_asf
    from ..io.amc_writer import cut_amc
    from ..io.bvh_writer import asf_bvh, cut_bvh
    from ..io.text import read_bytes

    amc = path.suffix.lower() == ".amc"
    if format == "amc":
        asf = find_asf(path)
        notes = notes + [f"frames renumbered from 1: frame 1 here is frame {a + 1} of {path.name}"]
        return {f"{stem}.amc": cut_amc(read_bytes(path), a, b, notes, path), f"{stem}.asf": read_bytes(asf)}
    if format == "bvh" and amc:
        return {f"{stem}.bvh": asf_bvh(load(path)[a:b], read_asf(find_asf(path)), notes)}
    if format == "bvh" and path.suffix.lower() == ".bvh":
        return {f"{stem}.bvh": cut_bvh(read_bytes(path), a, b, notes, path)}
    motion = load(path, take=take)
    rest = motion.positions[0] - motion.positions[0, np.maximum(motion.parents, 0)]  # the source's first frame
    return {f"{stem}.{format}": _posed(motion, a, b, rest, format, notes, meta)}


def export_stretch(db, doc_id: int, out_dir, start: int | None = None, end: int | None = None, format: str = "bvh",
                   rig: str | None = None, search: str | None = None) -> list[Path]:
    """Frames ``start:end`` of document ``doc_id`` written into ``out_dir`` (:func:`stretch_files`).

    Parameters
    ----------
    db : MotionDB
        The database.
    doc_id : int
        The document.
    out_dir : str or os.PathLike
        The folder (created if missing), written all or nothing (:func:`write_files`).
    start, end : int, optional
        Frames at the database's rate, half-open (default: the whole document).
    format : {"bvh", "amc", "glb", "humanml3d"}
        See :func:`stretch_files`.
    rig : {"source", "canonical"}, optional
        See :func:`stretch_files`.
    search : str, optional
        What found the stretch, written into the files.

    Returns
    -------
    list of pathlib.Path
        The files written.

    Examples
    --------
    >>> import tempfile
    >>> from mocapviz import MotionDB, load
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     [bvh] = export_stretch(MotionDB.sample(), 7, folder, 10, 70, rig="canonical")
    ...     bvh.name, load(bvh).n_frames
    ('001_doc7_HDM_dg_kickLFront1Reps_017_120_10-70.bvh', 60)
    """
    return write_files([stretch_files(db, doc_id, start, end, format, rig, search=search)], out_dir)


def write_files(groups: Iterable[dict[str, bytes]], out_dir) -> list[Path]:
    """Files written into ``out_dir``, all or nothing: every file, or (on any error, a full disk, a signal that
    raises) none, ``out_dir`` as it was.

    The files are written into a new hidden folder, ``.<out_dir name>.<random>.export``, beside ``out_dir`` when it
    does not exist (renamed to ``out_dir`` at the end) or inside it when it does (its files renamed into ``out_dir``
    at the end; a file of ``out_dir`` with one of their names is replaced, and put back if a rename fails). The
    folder is removed when anything fails; one that a killed process left (its ``flock`` released) is removed by the
    next export into ``out_dir``.

    Parameters
    ----------
    groups : iterable of dict
        File name -> bytes, one dict at a time (e.g. a hit's files, made when the writer asks for them).
    out_dir : str or os.PathLike
        The folder; its parents are created if missing.

    Returns
    -------
    list of pathlib.Path
        The files written, in the order given.

    Raises
    ------
    ParameterError
        ``out_dir`` is a file, or holds a folder of a file's name.
    OSError
        Writing failed (nothing written); or ``out_dir`` was created and filled by another process meanwhile.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ParameterError(f"{out}: a file, not a folder; pass a folder to write the export into")
    place = out if out.is_dir() else out.parent
    place.mkdir(parents=True, exist_ok=True)
    for old in store.leftovers(out, STAGING) + store.leftovers(out / out.name, STAGING):  # beside it, in it
        _remove_if_abandoned(old)
    with store.temporary_folder(place / out.name, STAGING) as tmp, _held(tmp):
        names = [_written(tmp, name, data) for files in groups for name, data in files.items()]
        if place == out:
            _move_in(tmp, out, names)
        else:
            os.rename(tmp, out)  # onto nothing, or an empty folder made meanwhile; a filled one: OSError
            store.fsync_folder(place)
    return [out / name for name in names]


def _written(folder: Path, name: str, data: bytes) -> str:
    store.atomic_write(folder / name, data)
    return name


@contextlib.contextmanager
def _held(folder: Path) -> Iterator[None]:
    """An exclusive ``flock`` on ``folder`` (its inode: it holds across a rename) for the block; a process's locks
    end with it, however it ends."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _remove_if_abandoned(folder: Path) -> None:
    """Remove an export's hidden folder when no process holds its lock (its writer was killed)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # gone meanwhile
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        shutil.rmtree(folder, ignore_errors=True)
    except BlockingIOError:  # an export running now
        pass
    finally:
        os.close(fd)


def _move_in(tmp: Path, out: Path, names: list[str]) -> None:
    """Rename the files ``names`` of ``tmp`` into ``out``; the files of ``out`` they replace wait in ``tmp`` until
    every rename has succeeded and are put back if one fails."""
    taken = [n for n in names if (out / n).is_dir() and not (out / n).is_symlink()]
    if taken:
        raise ParameterError(f"{out / taken[0]}: a folder has the name of an exported file; move it or export into "
                             "another folder")  # fmt: skip
    aside = tmp / STAGING  # no exported name starts with a dot
    aside.mkdir()
    moved: list[str] = []
    try:
        for name in names:
            if os.path.lexists(out / name):
                os.rename(out / name, aside / name)
            moved.append(name)
            os.rename(tmp / name, out / name)
    except BaseException:
        for name in reversed(moved):
            with contextlib.suppress(FileNotFoundError):
                os.rename(out / name, tmp / name)
            if os.path.lexists(aside / name):
                os.rename(aside / name, out / name)
        raise
    store.fsync_folder(out)
