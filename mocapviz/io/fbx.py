"""Autodesk FBX skeletal animation (binary FBX 6.x and 7.x, ASCII FBX), read with ufbx.

read_fbx      FBX file -> Motion of one take (animation stack): the skeleton's joints, world positions, local
              quaternions, as a BVH file gives them.
take_names    the names of an FBX file's takes, in the file's order (ingest makes a document of each).

Conventions:

- Joints: the scene's skeleton nodes (nodes with a LimbNode / Limb / Root skeleton attribute), in the scene's node
  order (parents first). A file without skeleton nodes (a rig of plain nodes) gives the nodes its take animates.
  Each joint's parent is its nearest ancestor among the joints (-1: none); nodes between them (Blender's
  ``Armature`` empty, a scene root carrying the unit or axis conversion) still move the joints below them. A name
  repeated in one file keeps its first node under its name; the later ones are named ``NAME#2``, ``NAME#3``...
- Takes: every animation stack of the file is a take; ``take=None`` reads the first, ``take="NAME"`` the one of that
  name. Frames are sampled at the file's frame rate (its time mode, ``GlobalSettings`` ``TimeMode`` /
  ``CustomFrameRate``) from the take's start to its end: frame k at ``start + k / fps``, ``round((end - start) *
  fps) + 1`` frames, so that the first and the last frame are the take's first and last key when its keys are on
  frames.
- Positions: each joint's world position in centimetres (the file's unit, ``UnitScaleFactor``, converted; ``scale``
  overrides it), y up: the file's axes (``UpAxis``, ``FrontAxis``, ``CoordAxis`` and their signs) are turned to x
  right, y up, z front (``up`` overrides it). Positions within ±1e7 cm (:mod:`mocapviz.io.checks`).
- Rotations: local quaternions relative to the rest pose, as BVH's: a joint at rest has the identity, and its
  quaternion is the turn of its world frame from rest, expressed in its parent's rest frame (the parent's turn
  taken out). The rest pose is the file's bind pose where it lists the joint, else the scene's own transform of
  the node (its properties without animation).
- Damaged files: ufbx reads in a helper process (:func:`mocapviz.io.isolated.read_isolated`), so that a crash
  inside it is a MocapFormatError naming the file, not the end of the calling process.
- ufbx 0.0.5's Python binding hands back an object it has handed out before without counting the new reference,
  and its garbage-collector hook visits objects already freed; the helper therefore counts those references
  itself and keeps the collector off while a scene is open (:class:`_Handles`), which makes reading reliable (a
  plain loop over a scene's nodes and their parents crashed the interpreter, docs/fbx.md).
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import MocapFormatError, ParameterError
from ..motion import Motion, rotations
from .checks import (
    DISTANCE_LIMIT_CM,
    FIGURE_UNITS,
    check_frame_rate,
    describe,
    first_outside,
    format_warning,
    numbered,
)
from .isolated import read_isolated

# ufbx in its helper process: at most this memory and time (it needs about 10 times the file's size, and reads the
# 1.7 MB CMU take, 2,752 frames of 38 joints, in about 2 s: one transform evaluation per joint and frame)
_MEMORY_FIXED, _MEMORY_PER_BYTE = 512 * 2**20, 64
_TIMEOUT_FIXED_S, _TIMEOUT_BYTES_PER_S = 60.0, 2**17
_AXIS_VECTORS = {0: (1, 0, 0), 1: (-1, 0, 0), 2: (0, 1, 0), 3: (0, -1, 0), 4: (0, 0, 1), 5: (0, 0, -1)}  # ufbx axes
_MAX_FRAMES = 1_000_000  # a take longer than this (2.3 hours at 120 fps) is a damaged time span, not a capture
_IGNORE_PARENT_SCALE = 1  # ufbx.InheritMode: the node ignores its parent's own scale (Maya's segment scale compensate)


def read_fbx(path, take: str | None = None, up: str = "auto", scale: float | None = None) -> Motion:
    """Read one take of an FBX file's skeletal animation.

    Parameters
    ----------
    path : str or os.PathLike
        A binary (6.x, 7.x) or ASCII ``.fbx`` file.
    take : str, optional
        The animation stack to read; default the file's first.
    up : {"auto", "y", "z"}
        The file's up axis: "auto" reads it from the file's axis settings; "y" or "z" override them (a file
        whose settings are wrong). The Motion is always y up.
    scale : float, optional
        Centimetres per file unit; default the file's unit (``UnitScaleFactor``: centimetres per unit).

    Returns
    -------
    Motion
        The skeleton's J joints (module docstring), positions [shape=(T, J, 3)] float32 in cm, y up, local
        quaternions [shape=(T, J, 4)] relative to the rest pose; ``fps`` the file's frame rate;
        ``labels["take"]`` the take read.

    Raises
    ------
    MocapFormatError
        Naming the file: not an FBX file, damaged (ufbx's reason, or it crashed, hung or ran out of its memory),
        an unknown ``take`` (the message lists the file's takes), no take, no skeleton nodes nor animated nodes,
        a frame rate outside 1 to 10,000 fps, or a position beyond ±1e7 cm or not finite (frame and joint named).
    ParameterError
        A bad ``take``, ``up`` or ``scale``.

    Examples
    --------
    >>> from mocapviz.io import datasets
    >>> m = read_fbx(datasets.fetch("peer-readers") / "fbx/isaac_01_01_cmu.fbx")  # doctest: +SKIP
    >>> m.n_frames, m.fps, m.joint_names[:3], m.labels["take"]  # doctest: +SKIP
    (2752, 120.0, ('Hips', 'LHipJoint', 'LeftUpLeg'), '01_01|01_01')
    """
    path = os.fspath(path)
    if take is not None and not isinstance(take, str):
        raise ParameterError(f"take must be the name of an animation stack (a str) or None, got {take!r}")
    if up not in ("auto", "y", "z"):
        raise ParameterError(f"up must be 'auto', 'y' or 'z', got {up!r}")
    if scale is not None and not (isinstance(scale, (int, float, np.number)) and 0 < scale < float("inf")):
        raise ParameterError(f"scale (centimetres per file unit) must be a positive number, got {scale!r}")
    scene = _in_helper(_ufbx_take, path, take)
    if "problem" in scene:
        raise MocapFormatError(path, scene["problem"])
    fps = check_frame_rate(scene["fps"], path, None, f"the file's frame rate {describe(scene['fps'])} fps")
    turn = _turn(scene["axes"], up)
    cm = scale if scale is not None else scene["unit_meters"] * 100.0
    if not (np.isfinite(cm) and cm > 0):
        raise MocapFormatError(path, f"UnitScaleFactor {describe(cm)} cm per unit is not a positive number")
    world = scene["world"]  # (T, J, 3, 4): rotation-scale and translation of each joint, file axes and units
    positions = np.einsum("ij,tkj->tki", turn * cm, world[..., 3])
    bad = first_outside(positions.reshape(len(positions), -1), DISTANCE_LIMIT_CM)
    names = scene["names"]
    if bad is not None:
        t, k = bad
        raise MocapFormatError(path, f"frame {t}: joint {names[k // 3]!r} at {describe(positions[t, k // 3, k % 3])} "
                                     f"cm, beyond ±{DISTANCE_LIMIT_CM:g} cm or not finite")  # fmt: skip
    parents = np.asarray(scene["parents"], dtype=np.int64)
    if scale is None:
        _say_an_odd_size(path, positions[0, parents >= 0] if (parents >= 0).sum() > 1 else positions[0], cm)
    quaternions = _rest_relative(world[..., :3], scene["rest"], parents, turn)
    return Motion(positions=positions.astype(np.float32), fps=fps, joint_names=names, parents=parents,
                  quaternions=quaternions.astype(np.float32), source=path, labels={"take": scene["take"]})


def take_names(path) -> tuple[str, ...]:
    """The takes (animation stacks) of an FBX file, in the file's order: what ``read_fbx(path, take=NAME)`` reads.

    Only the file's structure is read, no frame evaluated, in the helper process that :func:`read_fbx` uses: 11 ms
    for the CMU file of the peer files (1.2 s to read its take), 8 ms for a file of two 30 Hz takes of 22 joints
    (23 ms to read its first take of 128 frames); docs/fbx.md.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.fbx`` file.

    Returns
    -------
    tuple of str
        The takes' names (at least one).

    Raises
    ------
    MocapFormatError
        Naming the file: no such file, not an FBX file, damaged (ufbx crashed, hung or ran out of its memory), or
        no take in it.

    Examples
    --------
    >>> from mocapviz.io import datasets
    >>> take_names(datasets.fetch("peer-readers") / "fbx/isaac_01_01_cmu.fbx")  # doctest: +SKIP
    ('01_01|01_01',)
    """
    path = os.fspath(path)
    names = _in_helper(_ufbx_take_names, path)
    if not names:
        raise MocapFormatError(path, "no take (animation stack) in the file")
    return tuple(names)


def _in_helper(function, path: str, *args):
    """``function(path, *args)`` run by ufbx in the helper process, within its memory and time for the file's size
    (MocapFormatError naming the file when it is missing or the reader fails)."""
    if not os.path.isfile(path):
        raise MocapFormatError(path, "no such file")
    size = os.path.getsize(path)
    return read_isolated(function, path, *args, reader="the FBX reader (ufbx)", preload=("ufbx",),
                         memory=_MEMORY_FIXED + _MEMORY_PER_BYTE * size,
                         timeout=_TIMEOUT_FIXED_S + size / _TIMEOUT_BYTES_PER_S)  # fmt: skip


def _say_an_odd_size(path: str, first: np.ndarray, cm: float) -> None:
    """Warn when the figure, in the unit the file states, is no person's size (:data:`FIGURE_UNITS`' centimetre
    range): an exporter's unit slip (the CMU FBX of the peer files says centimetres and is 26 m tall), or not a
    person. ``first``: the first frame's joints without a root [shape=(J, 3)], cm."""
    size = float(np.ptp(first, axis=0).max())
    low, high = next((low, high) for name, unit, low, high in FIGURE_UNITS if unit == 1.0)
    if not low <= size <= high:
        shown = f"{size:,.0f}" if size >= 10 else f"{size:.2g}"
        format_warning(path, f"a figure {shown} cm tall in the unit the file states ({cm:g} cm): no person's size; "
                             "pass scale= (cm per file unit) if that unit is wrong")


def _turn(axes: tuple, up: str) -> np.ndarray:
    """The matrix [shape=(3, 3)] taking the file's axes (ufbx's right, up, front axis codes) to x right, y up, z
    front; ``up`` "y" or "z" overrides the file's (identity, or -90 degrees about x)."""
    if up == "y" or (up == "auto" and not all(a in _AXIS_VECTORS for a in axes)):
        return np.eye(3)
    if up == "z":
        axes = (0, 4, 3)  # right +x, up +z, front -y
    return np.array([_AXIS_VECTORS[a] for a in axes], dtype=np.float64)


def _rest_relative(world: np.ndarray, rest: np.ndarray, parents: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """Local quaternions [shape=(T, J, 4)] relative to the rest pose.

    Parameters
    ----------
    world : np.ndarray [shape=(T, J, 3, 3)]
        Each joint's world rotation-scale matrix per frame (file axes).
    rest : np.ndarray [shape=(J, 3, 3)]
        The same at rest.
    parents : np.ndarray [shape=(J,)]
    turn : np.ndarray [shape=(3, 3)]
        File axes to the Motion's (a rotation, or a reflection for a left-handed file).

    Returns
    -------
    np.ndarray
        ``G_p^-1 G_j`` with ``G_j = turn F_j F0_j^-1 turn^-1`` (F: world rotation, F0: at rest): the turn of each
        joint's frame from rest in the Motion's axes, its parent's turn taken out; a proper rotation also when
        ``turn`` reflects.
    """
    f, f0 = _orthonormal(world), _orthonormal(rest)
    turned = np.einsum("ij,tkjl,kml,nm->tkin", turn, f, f0, turn)  # turn F F0^T turn^T
    parent_turned = np.where((parents >= 0)[None, :, None, None], turned[:, np.maximum(parents, 0)], np.eye(3))
    local = np.einsum("tkji,tkjl->tkil", parent_turned, turned)  # G_p^T G_j
    return rotations.from_matrix(local)


def _orthonormal(m: np.ndarray) -> np.ndarray:
    """Rotation-scale matrices [shape=(..., 3, 3)] with their columns scaled to unit length (the scale taken out);
    a zero column stays zero."""
    norm = np.linalg.norm(m, axis=-2, keepdims=True)
    return np.divide(m, norm, out=np.zeros_like(m), where=norm > 0)


# ------------------------------------------------------------------------------------------------ helper-process side
class _Handles:
    """Keeps every object ufbx's binding hands out alive until the scene is freed, and counts the references the
    binding forgets: ufbx 0.0.5 returns an object it has handed out before (a node's parent, a bone pose's node)
    without adding a reference to it, and its collector hook visits the objects it handed out even after they are
    freed. Used with the garbage collector off, and dropped only after :meth:`ufbx.Scene.free`."""

    def __init__(self):
        self.kept: dict[int, object] = {}

    def __call__(self, obj):
        if obj is None:
            return None
        if id(obj) in self.kept:
            import ctypes

            ctypes.pythonapi.Py_IncRef(ctypes.py_object(obj))  # the reference the binding did not count
        else:
            self.kept[id(obj)] = obj
        return obj


def _ufbx_take_names(path: str) -> list[str]:
    """The names of the file's animation stacks: what runs in the helper process for :func:`take_names`."""
    return _with_scene(path, lambda scene, handle: [handle(s).name for s in scene.anim_stacks])


def _ufbx_take(path: str, take: str | None) -> dict:
    """One take of an FBX file as plain arrays: what runs in the helper process.

    Returns
    -------
    dict
        ``names`` (tuple), ``parents`` (list), ``fps``, ``unit_meters``, ``axes`` (ufbx's right, up, front codes),
        ``take`` (its name), ``world`` [shape=(T, J, 3, 4)] (each joint's world matrix per frame, file axes and
        units), ``rest`` [shape=(J, 3, 3)] (the rest pose's world rotation-scale); or ``problem``: why the file
        gives no Motion (no take, an unknown take, no joints, a bad time span).
    """
    return _with_scene(path, lambda scene, handle: _take_of(scene, take, handle))


def _with_scene(path: str, read):
    """``read(scene, handle)`` of the file's ufbx scene (geometry skipped), with the collector off and a
    :class:`_Handles` kept until the scene is freed."""
    import gc

    import ufbx

    enabled = gc.isenabled()
    gc.disable()
    try:
        scene = ufbx.load_file(path, ignore_geometry=True, ignore_embedded=True)
        try:
            return read(scene, _Handles())
        finally:
            scene.free()
    finally:
        if enabled:
            gc.enable()


def _take_of(scene, take: str | None, handle: _Handles) -> dict:
    import ufbx

    settings = handle(scene.settings)
    stacks = [handle(s) for s in scene.anim_stacks]
    names = [s.name for s in stacks]
    if not stacks:
        return {"problem": "no take (animation stack) in the file"}
    if take is not None and take not in names:
        return {"problem": f"no take {take!r}; the file's takes: {', '.join(map(repr, names))}"}
    stack = stacks[0 if take is None else names.index(take)]
    anim = handle(stack.anim)
    nodes = [handle(n) for n in scene.nodes]
    index = {id(n): i for i, n in enumerate(nodes)}
    parent = [index.get(id(handle(n.parent)), -1) if not n.is_root else -1 for n in nodes]
    joints = [i for i, n in enumerate(nodes) if handle(n.bone) is not None]
    if not joints:  # a rig of plain nodes: the nodes the take animates
        animated = {handle(p.element).element_id for layer in map(handle, stack.layers)
                    for p in map(handle, layer.anim_props)}  # fmt: skip
        joints = [i for i, n in enumerate(nodes) if n.element_id in animated]
    if not joints:
        return {"problem": "no skeleton: neither skeleton nodes (LimbNode) nor nodes the take animates"}
    fps = float(settings.frames_per_second)
    start, end = float(stack.time_begin), float(stack.time_end)
    span = (end - start) * fps if fps > 0 else float("nan")
    if not (np.isfinite(span) and 0 <= span < _MAX_FRAMES):
        return {"problem": f"take {stack.name!r} spans {describe(start)} s to {describe(end)} s at "
                           f"{describe(fps)} fps"}  # fmt: skip
    times = start + np.arange(round(span) + 1) / fps
    # the joints and every node above them, parents first (ufbx lists a node after its parent)
    needed = set()
    for j in joints:
        while j >= 0 and j not in needed:
            needed.add(j)
            j = parent[j]
    order = sorted(needed)
    world = {}  # node -> (T, 4, 4)
    for i in order:
        local = _matrices([ufbx.evaluate_transform(anim, nodes[i], t) for t in times])
        p = parent[i]
        if p < 0:
            world[i] = local
            continue
        above = world[p]
        if nodes[i].inherit_mode == _IGNORE_PARENT_SCALE:
            above = above @ np.linalg.inv(_scale_matrix(nodes[p].local_transform.scale))
        world[i] = above @ local
    rest = _rest(scene, nodes, joints, index, handle)
    joint_set = set(joints)

    def joint_parent(j: int) -> int:
        j = parent[j]
        while j >= 0 and j not in joint_set:
            j = parent[j]
        return joints.index(j) if j >= 0 else -1

    return {
        "names": numbered(nodes[j].name for j in joints),
        "parents": [joint_parent(j) for j in joints],
        "fps": fps,
        "unit_meters": float(settings.unit_meters),
        "axes": (int(settings.axes.right), int(settings.axes.up), int(settings.axes.front)),
        "take": stack.name,
        "world": np.stack([world[j][:, :3, :] for j in joints], axis=1),
        "rest": rest,
    }


def _rest(scene, nodes: list, joints: list, index: dict, handle: _Handles) -> np.ndarray:
    """The rest pose's world rotation-scale [shape=(J, 3, 3)]: the bind pose's where it lists the joint, else the
    node's own (its properties without animation)."""
    rest = np.array([_columns(nodes[j].node_to_world)[:3, :3] for j in joints])
    position = {j: k for k, j in enumerate(joints)}
    for pose in map(handle, scene.poses):
        if not pose.is_bind_pose:
            continue
        for bone in map(handle, pose.bone_poses):
            k = position.get(index.get(id(handle(bone.bone_node)), -1))
            if k is not None:
                rest[k] = _columns(bone.bone_to_world)[:3, :3]
    return rest


def _matrices(transforms: list) -> np.ndarray:
    """The 4x4 matrices [shape=(N, 4, 4)] of ufbx Transforms (translation, rotation quaternion x y z w, scale)."""
    values = np.array([(*t.translation, t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z, *t.scale)
                       for t in transforms], dtype=np.float64).reshape(-1, 10)  # fmt: skip
    m = np.zeros((len(values), 4, 4))
    for axis in range(3):  # column i: the rotated, scaled unit vector i
        unit = np.zeros(3)
        unit[axis] = 1.0
        m[:, :3, axis] = rotations.rotate(values[:, 3:7], unit) * values[:, 7 + axis, None]
    m[:, :3, 3] = values[:, :3]
    m[:, 3, 3] = 1.0
    return m


def _scale_matrix(scale) -> np.ndarray:
    return np.diag([*tuple(scale), 1.0])


def _columns(matrix) -> np.ndarray:
    """A ufbx Matrix (four columns) as a 4x4 array."""
    m = np.eye(4)
    m[:3, :] = np.array([tuple(matrix.c0), tuple(matrix.c1), tuple(matrix.c2), tuple(matrix.c3)]).T
    return m
