"""Two BVH clips of one rig made one FBX file with two takes, by Blender (for tests/test_takes.py; run with Blender's
Python, not the project's).

    .cache/blender/bin/python tests/blender_takes.py OUT.fbx FIRST.bvh NAME1 SECOND.bvh NAME2

An empty factory scene imports FIRST with ``bpy.ops.import_anim.bvh`` (the scene takes its rate) and SECOND the
same way; SECOND's action is renamed NAME2 and given to FIRST's armature too, FIRST's renamed NAME1, and SECOND's
armature deleted. ``bpy.ops.export_scene.fbx`` with ``bake_anim_use_all_actions`` writes one animation stack per
action of the armature; stdout ends with a JSON line: the actions' names and frame ranges.
"""
from __future__ import annotations

import json
import sys

import bpy


def imported(path: str):
    """The armature object ``import_anim.bvh`` made of ``path`` (its action holds the file's frames from frame 1)."""
    before = set(bpy.data.objects)
    bpy.ops.import_anim.bvh(filepath=path, update_scene_fps=True, update_scene_duration=True, frame_start=1,
                            global_scale=0.01)  # the files' centimetres as metres, Blender's unit
    (arm,) = set(bpy.data.objects) - before
    return arm


def main(out: str, first: str, name1: str, second: str, name2: str) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    arm = imported(first)
    other = imported(second)
    arm.animation_data.action.name = name1
    other.animation_data.action.name = name2
    bpy.data.objects.remove(other)
    ranges = {a.name: list(a.frame_range) for a in bpy.data.actions}
    bpy.ops.export_scene.fbx(filepath=out, object_types={"ARMATURE"}, bake_anim=True, bake_anim_use_all_actions=True,
                             bake_anim_use_nla_strips=False, add_leaf_bones=False)
    print(json.dumps({"actions": ranges, "fps": bpy.context.scene.render.fps}))


if __name__ == "__main__":
    main(*sys.argv[1:6])
