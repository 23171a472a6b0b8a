"""Readers: one entry point, :func:`load`, for every supported motion file.

load          path -> Motion (ASF/AMC, BVH, C3D markers, FBX; ``.npy`` joint arrays of a layout), by extension.
file_format   the extension a file name ends in, as load reads it ('....bvh', '.x.bvh', '.bvh': '.bvh').
find_asf      the ASF skeleton of an AMC file, by the CMU and HDM05 folder conventions.
read_*        the format readers: read_asf, read_amc (``asfamc``), read_bvh, read_c3d, read_fbx (modules named so).
relabel       C3D labels renamed by a marker mapping file (``marker_mapping``: read_marker_mapping reads one).

The writers, for :mod:`mocapviz.export`: ``bvh_writer`` (a posed rig, an AMC on its ASF rig, a stretch of a BVH
file), ``amc_writer`` (a stretch of an AMC file), ``gltf_writer`` (a posed rig as glTF binary).

The readers (and numba, which they compile with; ezc3d, which reads C3D; ufbx, which reads FBX) are imported when
first used: opening a MotionDB, which imports this package through ingest, reads no motion file.
"""
from __future__ import annotations

import functools
import os
from pathlib import Path

from .._lazy import lazy_exports
from ..errors import MocapFormatError, ParameterError
from ..motion import Motion
from ..validation import one_of
from .humanml3d import LAYOUTS

_getattr, _readers = lazy_exports(__name__, {"AsfSkeleton": ".asfamc", "read_amc": ".asfamc", "read_asf": ".asfamc",
                                             "read_bvh": ".bvh", "read_c3d": ".c3d", "read_fbx": ".fbx",
                                             "read_marker_mapping": ".marker_mapping",
                                             "relabel": ".marker_mapping"})  # fmt: skip
__getattr__ = _getattr


def __dir__():
    return sorted({*globals(), *_readers()})


FORMATS = (".amc", ".bvh", ".c3d", ".fbx")
"""The motion files ingest finds in a folder. :func:`load` also reads ``.npy`` joint arrays of a layout it is told
(:data:`LAYOUTS`): an array's file does not say what its joints are."""
ARRAY = ".npy"


def file_format(path) -> str:
    """The extension ``path``'s name ends in, lower case, as :func:`load` reads the file: from its last dot on,
    whatever comes before it (``....bvh``, ``.x.bvh`` and ``.bvh`` are BVH files; ``os.path.splitext`` gives
    them no extension), ``""`` for a name without a dot.

    Parameters
    ----------
    path : str or os.PathLike
        A file.

    Returns
    -------
    str
        E.g. ``".bvh"``; one of :data:`FORMATS` for a motion file.

    Examples
    --------
    >>> [file_format(n) for n in ["a.BVH", "....bvh", ".bvh", "x.tar.gz", "README"]]
    ['.bvh', '.bvh', '.bvh', '.gz', '']
    """
    name = os.path.basename(os.fspath(path))
    return name[name.rfind("."):].lower() if "." in name else ""


@functools.lru_cache(maxsize=4096)
def _find_asf(amc: Path) -> Path:
    stem = amc.stem
    candidates = [stem]
    while "_" in stem:
        stem = stem.rsplit("_", 1)[0]
        candidates.append(stem)
    candidates.append(amc.parent.name)
    folders = []
    for up in [amc.parent, *list(amc.parents)[1:4]]:
        folders += [up, up / "asf"]
    for name in candidates:
        for folder in folders:
            for suffix in (".asf", ".ASF"):
                f = folder / (name + suffix)
                if f.is_file():
                    return f
    only = sorted(amc.parent.glob("*.asf")) + sorted(amc.parent.glob("*.ASF"))
    if len(only) == 1:
        return only[0]
    raise MocapFormatError(amc, "no ASF skeleton found beside it; pass asf=PATH")


def find_asf(amc_path) -> Path:
    """Locate the ASF skeleton of an AMC file.

    Tried in order, in the AMC's folder, its ancestors (up to three levels) and their ``asf/`` subfolders:
    a file named after the AMC's stem, then after its stem cut at each ``_`` from the right
    (``HDM_bd_kick_001_120`` -> ``HDM_bd``, ``131_01`` -> ``131``), then after the AMC's folder
    (``amc/mjackson/131_01.amc`` -> ``asf/mjackson.asf``); last, the only ``.asf`` in the AMC's folder.

    Parameters
    ----------
    amc_path : str or os.PathLike
        An ``.amc`` file.

    Returns
    -------
    pathlib.Path
        The ASF file (absolute).

    Raises
    ------
    MocapFormatError
        No skeleton found; the message says to pass ``asf=``.

    Examples
    --------
    >>> from mocapviz.io import datasets
    >>> find_asf(datasets.sample() / "hdm05-cut/amc/HDM_mm_kickLFront1Reps_023_120.amc").name
    'HDM_mm.asf'
    >>> find_asf(datasets.sample() / "cmu-asfamc/amc/mjackson/131_01.amc").name
    'mjackson.asf'
    """
    return _find_asf(Path(amc_path).resolve())  # found paths are cached; failures are looked up again


def load(path, *, asf=None, fps: float | None = None, up: str = "auto", scale: float | None = None,
         take: str | None = None, marker_mapping=None, layout: str | None = None) -> Motion:
    """Read a motion file.

    Parameters
    ----------
    path : str or os.PathLike
        An ``.amc`` (with its ASF skeleton), ``.bvh``, ``.c3d`` or ``.fbx`` file, or a ``.npy`` joint array of
        ``layout``.
    asf : str or os.PathLike, optional
        The ASF skeleton of an AMC file; default :func:`find_asf`.
    fps : float, optional
        AMC: the capture rate in frames per second (default 120, as CMU and HDM05). ``.npy``: the array's (default
        20 for ``humanml3d``). BVH: ignored (the file states it).
    up : {"auto", "y", "z"}
        BVH, C3D and FBX: the file's up axis (:func:`mocapviz.io.bvh.read_bvh`, :func:`mocapviz.io.c3d.read_c3d`,
        :func:`mocapviz.io.fbx.read_fbx`); the Motion is always y up.
    scale : float, optional
        BVH and FBX: centimetres per file unit; default guessed from the figure's height (BVH), the file's unit
        (FBX).
    take : str, optional
        FBX only: the take (animation stack) to read; default the file's first.
    marker_mapping : str, os.PathLike or dict, optional
        C3D only: a mapping file renaming the file's marker labels onto a marker set's names
        (:mod:`mocapviz.io.marker_mapping`), or its dict.
    layout : {"humanml3d"}, optional
        ``.npy`` only, and needed there: what the array's joints are (:data:`LAYOUTS`). ``"humanml3d"``: (T, 22, 3)
        in metres, y up (:func:`mocapviz.io.humanml3d.read_joint_array`), read onto the 24 canonical joints.

    Returns
    -------
    Motion
        Source joints J, positions [shape=(T, J, 3)] float32 in cm, y up, local quaternions [shape=(T, J, 4)]
        (C3D: the markers as joints without a skeleton or rotations, NaN in gaps).
        ``Motion.canonical()`` maps it to the 24 canonical joints (C3D: joint-centre estimates,
        :mod:`mocapviz.motion.markers`).

    Raises
    ------
    MocapFormatError
        Unsupported extension, unreadable or malformed file (naming the file and line; for a malformed ASF, the
        AMC too), an FBX take the file does not have, or a value beyond the limits of :mod:`mocapviz.io.checks`.
    ParameterError
        ``fps`` outside 1 to 10,000, or a bad ``up`` or ``scale``; ``layout`` missing or unknown for a ``.npy`` file,
        or given for another file.

    See Also
    --------
    mocapviz.MotionDB.ingest : many files into a database.

    Examples
    --------
    >>> from mocapviz import load
    >>> from mocapviz.io import datasets
    >>> m = load(datasets.sample() / "hdm05-cut/amc/HDM_mm_kickLFront1Reps_023_120.amc")  # ASF found beside it
    >>> m.n_frames, m.fps, m.positions.shape, m.positions.dtype
    (130, 120.0, (130, 31, 3), dtype('float32'))
    >>> c = m.canonical()  # the 24 canonical joints
    >>> c.positions.shape, c.joint_names[:3]
    ((130, 24, 3), ('root', 'lhip', 'lknee'))
    """
    path = os.fspath(path)
    ext = file_format(path)
    if layout is not None and ext != ARRAY:
        raise ParameterError(f"{path}: layout={layout!r} is for {ARRAY} joint arrays; a {ext or '(none)'} file "
                             "says what its joints are")  # fmt: skip
    if ext == ARRAY:
        if layout is None:
            raise ParameterError(f"{path}: a {ARRAY} array does not say what its joints are; pass layout= one of "
                                 f"{', '.join(LAYOUTS)}")  # fmt: skip
        one_of(layout, "layout", LAYOUTS)
    if not os.path.isfile(path):
        raise MocapFormatError(path, "no such file")
    if ext == ".amc":
        from .asfamc import read_amc, read_asf

        asf = asf if asf is not None else find_asf(path)
        try:
            skeleton = read_asf(asf)
        except MocapFormatError as exc:  # name the AMC too: it is the file that could not be read
            raise MocapFormatError(exc.path, f"{exc.reason} (the skeleton of {os.path.basename(path)})", exc.line) from None
        return read_amc(path, skeleton, fps=120.0 if fps is None else fps)
    if ext == ".bvh":
        from .bvh import read_bvh

        return read_bvh(path, up=up, scale=scale)
    if ext == ".c3d":
        from .c3d import read_c3d

        return read_c3d(path, up=up, marker_mapping=marker_mapping)
    if ext == ".fbx":
        from .fbx import read_fbx

        return read_fbx(path, take=take, up=up, scale=scale)
    if ext == ARRAY:
        from .humanml3d import read_joint_array

        return read_joint_array(path, fps)
    raise MocapFormatError(path, f"unsupported file type {ext or '(none)'!r}; supported: {', '.join(FORMATS)} "
                           f"(and {ARRAY} joint arrays with layout=)")


__all__ = ["ARRAY", "FORMATS", "LAYOUTS", "AsfSkeleton", "file_format", "find_asf", "load", "read_amc", "read_asf",
           "read_bvh", "read_c3d", "read_fbx", "read_marker_mapping", "relabel"]
