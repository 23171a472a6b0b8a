"""Blender's own reading of an exported file, for tests/test_clients.py (run with Blender's Python, not the project's).

    .cache/blender/bin/python tests/blender_probe.py IN.bvh OUT.npz
    .cache/blender/bin/python tests/blender_probe.py IN.glb OUT.npz FPS
    .cache/blender/bin/python tests/blender_probe.py IN.fbx OUT.npz

An empty factory scene imports the file with Blender's bundled importers and their default axis conversion (the
file's y up, -z forward -> Blender's z up, y forward: a file point ``(x, y, z)`` lands at ``(x, -z, y)``), at scale 1
(a BVH's centimetres become Blender units as numbers; a glTF's metres stay metres):

- BVH: ``bpy.ops.import_anim.bvh`` with ``update_scene_fps`` (the scene takes the file's rate, rounded to whole
  frames per second, the rest in ``fps_base``); the file's first frame at scene frame 1. Every bone of the armature
  is a joint: its world head ``matrix_world @ head``.
- glTF binary: ``bpy.ops.import_scene.gltf`` after the scene's rate is set to FPS (glTF keys are seconds, which the
  importer turns into frames at the scene's rate: key ``k / FPS`` at frame ``k``). A glTF without a skin is imported
  as empties, one per node: a joint's world position is its empty's ``matrix_world`` translation.

- FBX (files other tools wrote, to check mocapviz's FBX reader against another): ``bpy.ops.import_scene.fbx`` with
  its defaults (the file's unit scale and axes applied; the scene takes the file's rate). Every bone is a joint.

Every frame from the first key frame to the last is set in turn (``scene.frame_set``). OUT.npz holds ``positions``
[frames, joints, 3] (Blender world coordinates), ``tails`` (a BVH bone's tail, the End Site of a leaf; NaN for
glTF), ``names``, ``parents`` (index, -1 for a root), ``fps`` and ``fps_base`` (the scene's rate is fps /
fps_base), ``frames`` (the scene frames stepped through) and ``keys`` (every key frame of every animation curve,
distinct).
"""
from __future__ import annotations

import sys

import bpy
import numpy as np


def key_frames() -> np.ndarray:
    """Every key frame of every F-curve of every action (layered actions: layers, strips, channel bags)."""
    keys = [np.zeros(0)]
    for action in bpy.data.actions:
        for layer in action.layers:
            for strip in layer.strips:
                for bag in strip.channelbags:
                    for curve in bag.fcurves:
                        co = np.zeros(2 * len(curve.keyframe_points))
                        curve.keyframe_points.foreach_get("co", co)
                        keys.append(co[0::2])
    return np.unique(np.concatenate(keys))


def joints_of_bvh(path: str):
    """Import a BVH; (names, parents, a function returning the heads and tails of every bone now)."""
    bpy.ops.import_anim.bvh(filepath=path, global_scale=1.0, rotate_mode="NATIVE", update_scene_fps=True)
    return armature_joints()


def armature_joints():
    """The scene's one armature: (names, parents, a function returning the heads and tails of every bone now)."""
    [armature] = [o for o in bpy.context.scene.objects if o.type == "ARMATURE"]
    bones = list(armature.pose.bones)
    names = [b.name for b in bones]
    parents = [names.index(b.parent.name) if b.parent else -1 for b in bones]

    def now():
        world = armature.matrix_world
        return [tuple(world @ b.head) for b in bones], [tuple(world @ b.tail) for b in bones]

    return names, parents, now


def joints_of_fbx(path: str):
    """Import an FBX file (Blender's importer, its defaults: the file's unit and axes applied, the scene taking the
    file's rate); (names, parents, a function returning the heads and tails of every bone now)."""
    bpy.ops.import_scene.fbx(filepath=path, use_anim=True)
    return armature_joints()


def joints_of_glb(path: str, fps: float):
    """Import a glTF binary at ``fps`` (an integer rate); (names, parents, a function returning the empties' world
    positions now)."""
    scene = bpy.context.scene
    if fps != round(fps):
        sys.exit(f"blender_probe: a glTF rate must be a whole number of frames per second here, not {fps}")
    scene.render.fps, scene.render.fps_base = round(fps), 1.0
    bpy.ops.import_scene.gltf(filepath=path)
    objects = [o for o in scene.objects if o.type == "EMPTY"]
    names = [o.name for o in objects]
    parents = [names.index(o.parent.name) if o.parent else -1 for o in objects]

    def now():
        heads = [tuple(o.matrix_world.translation) for o in objects]
        return heads, [(np.nan,) * 3] * len(objects)

    return names, parents, now


def probe(path: str, out: str, fps: float | None = None) -> None:
    """Import ``path``, step through its frames, save what Blender shows into ``out`` (see the module's doc)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if path.lower().endswith(".bvh"):
        names, parents, now = joints_of_bvh(path)
    elif path.lower().endswith(".fbx"):
        names, parents, now = joints_of_fbx(path)
    else:
        names, parents, now = joints_of_glb(path, fps)
    scene = bpy.context.scene
    keys = key_frames()
    frames = np.arange(round(keys.min()), round(keys.max()) + 1)  # the frames the animation spans
    heads, tails = [], []
    for f in frames:
        scene.frame_set(int(f))
        h, t = now()
        heads.append(h)
        tails.append(t)
    np.savez(out, positions=np.array(heads, dtype=np.float64), tails=np.array(tails, dtype=np.float64),
             names=np.array(names), parents=np.array(parents), fps=scene.render.fps, fps_base=scene.render.fps_base,
             frames=frames, keys=keys)


if __name__ == "__main__":
    probe(sys.argv[1], sys.argv[2], float(sys.argv[3]) if len(sys.argv) > 3 else None)
