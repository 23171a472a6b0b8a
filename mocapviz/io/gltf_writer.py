"""Writing glTF 2.0 binary (``.glb``) with pygltflib: a posed rig as a node tree and one animation.

pose_glb    a :class:`mocapviz.motion.rig.Pose` -> the bytes of a ``.glb`` file.

The file holds one scene whose nodes are the rig's joints (named as the joints, each the child of its parent's node,
its ``translation`` the rest offset), no mesh and no skin, and one animation at the clip's frame rate: a rotation
sampler per joint and a translation sampler per moving joint (the root and every joint whose offset varies), linear
interpolation, key times ``k / fps`` seconds. Units: metres, y up, right-handed (glTF's), from the rig's centimetres.
"""
from __future__ import annotations

import numpy as np

from .._version import __version__
from ..motion.rig import Pose

_FLOAT = 5126  # GL_FLOAT, the componentType of every accessor written


def pose_glb(names, parents, pose: Pose, fps: float, extras: dict | None = None) -> bytes:
    """A posed rig as a glTF binary.

    Parameters
    ----------
    names : sequence of str [length J]
        Joint names (the nodes' names).
    parents : array_like [shape=(J,)], int
        Parents, -1 for the root.
    pose : Pose
        Rotations and translations (cm) of every frame (:func:`mocapviz.motion.rig.fit_pose`).
    fps : float
        Frames per second.
    extras : dict, optional
        JSON-serialisable metadata, written as ``asset.extras`` and the scene's ``extras``.

    Returns
    -------
    bytes
        The ``.glb`` file.

    Examples
    --------
    >>> import pygltflib
    >>> from mocapviz import MotionDB
    >>> from mocapviz.motion.rig import fit_pose
    >>> m = MotionDB.sample().motion(7)[:30]
    >>> pose = fit_pose(m.positions, m.parents, m.positions[0] - m.positions[0, np.maximum(m.parents, 0)])
    >>> gltf = pygltflib.GLTF2.load_from_bytes(pose_glb(m.joint_names, m.parents, pose, m.fps, {"doc_id": 7}))
    >>> len(gltf.nodes), gltf.asset.extras, len(gltf.animations[0].channels) > 24
    (24, {'doc_id': 7}, True)
    """
    import pygltflib as g

    parents = np.asarray(parents, dtype=np.int64)
    n_frames = pose.rotations.shape[0]
    blob = bytearray()
    accessors, views = [], []

    def add(values: np.ndarray, kind: str, bounds: bool = False) -> int:
        data = np.ascontiguousarray(values, dtype="<f4")
        views.append(g.BufferView(buffer=0, byteOffset=len(blob), byteLength=data.nbytes))
        blob.extend(data.tobytes())
        extra = {"min": data.reshape(len(data), -1).min(0).tolist(), "max": data.reshape(len(data), -1).max(0).tolist()}
        accessors.append(g.Accessor(bufferView=len(views) - 1, componentType=_FLOAT, count=len(data), type=kind,
                                    **(extra if bounds else {})))  # fmt: skip
        return len(accessors) - 1

    times = add(np.arange(n_frames) / fps, g.SCALAR, bounds=True)
    rest = np.where(pose.moving[:, None], pose.translations[0], pose.offsets) / 100.0
    nodes = [g.Node(name=str(n), translation=rest[j].tolist(), children=np.flatnonzero(parents == j).tolist())
             for j, n in enumerate(names)]  # fmt: skip
    samplers, channels = [], []
    for j in range(len(names)):
        q = pose.rotations[:, j]
        tracks = [("rotation", q[:, [1, 2, 3, 0]] / np.linalg.norm(q, axis=-1, keepdims=True), g.VEC4)]
        if pose.moving[j]:
            tracks.append(("translation", pose.translations[:, j] / 100.0, g.VEC3))
        for path, values, kind in tracks:
            samplers.append(g.AnimationSampler(input=times, output=add(values, kind), interpolation="LINEAR"))
            channels.append(g.AnimationChannel(sampler=len(samplers) - 1, target=g.AnimationChannelTarget(node=j,
                                                                                                          path=path)))
    roots = np.flatnonzero(parents < 0).tolist()
    gltf = g.GLTF2(
        asset=g.Asset(version="2.0", generator=f"mocapviz {__version__}", extras=extras or {}),
        scene=0,
        scenes=[g.Scene(nodes=roots, extras=extras or {})],
        nodes=nodes,
        animations=[g.Animation(name="motion", samplers=samplers, channels=channels)],
        accessors=accessors,
        bufferViews=views,
        buffers=[g.Buffer(byteLength=len(blob))],
    )
    gltf.set_binary_blob(bytes(blob))
    return b"".join(gltf.save_to_bytes())
