"""The 24 canonical joints every skeleton is mapped onto, and their tree: the bottom of the motion folder.

CANONICAL_JOINTS   the 24 joint names, in the fixed order of RELATIONAL_FEATURES.md §1.2.
CANONICAL_PARENTS  their tree: the parent's index of each joint, -1 for the root.

``mocapviz.motion.skeleton`` (mapping a rig onto them) and ``mocapviz.motion.markers`` (placing them from markers)
both build on these names, so they live below both; ``mocapviz.motion.skeleton`` re-exports them.

Examples
--------
>>> len(CANONICAL_JOINTS), CANONICAL_JOINTS[CANONICAL_PARENTS[CANONICAL_JOINTS.index("lknee")]]
(24, 'lhip')
"""
from __future__ import annotations

import numpy as np

CANONICAL_JOINTS = (
    "root", "lhip", "lknee", "lankle", "ltoes", "rhip", "rknee", "rankle", "rtoes",
    "belly", "chest", "neck", "head", "headtop",
    "lclavicle", "lshoulder", "lelbow", "lwrist", "lfingers",
    "rclavicle", "rshoulder", "relbow", "rwrist", "rfingers",
)  # fmt: skip
_PARENT_NAMES = {
    "lhip": "root", "lknee": "lhip", "lankle": "lknee", "ltoes": "lankle",
    "rhip": "root", "rknee": "rhip", "rankle": "rknee", "rtoes": "rankle",
    "belly": "root", "chest": "belly", "neck": "chest", "head": "neck", "headtop": "head",
    "lclavicle": "neck", "lshoulder": "lclavicle", "lelbow": "lshoulder", "lwrist": "lelbow", "lfingers": "lwrist",
    "rclavicle": "neck", "rshoulder": "rclavicle", "relbow": "rshoulder", "rwrist": "relbow", "rfingers": "rwrist",
}  # fmt: skip
CANONICAL_PARENTS = np.array([-1] + [CANONICAL_JOINTS.index(_PARENT_NAMES[j]) for j in CANONICAL_JOINTS[1:]])
