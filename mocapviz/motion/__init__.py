"""The motion layer: one clip in memory and the skeleton it is drawn on (no files, no database).

motion.py    :class:`Motion` (positions in cm, y up, local quaternions, frame rate, labels), ``FPS_RANGE``.
joints.py    the 24 canonical joints and their tree (below skeleton.py and markers.py, which both use them).
skeleton.py  the structural mapping of any humanoid rig onto the canonical joints (a marker clip: markers.py),
             body frames.
markers.py   the 24 canonical joints estimated from marker trajectories (C3D: CMU/HDM05 set, Plug-in Gait), gaps.
rotations.py quaternion and Euler-angle arithmetic.

See ``docs/architecture.md``.
"""
from .motion import FPS_RANGE, Motion, fps_problem

__all__ = ["FPS_RANGE", "Motion", "fps_problem"]
