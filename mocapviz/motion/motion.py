"""The Motion: one clip's joint positions (and rotations) over time, as every reader returns it."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import ParameterError, UnknownKeyError

FPS_RANGE = (1.0, 10_000.0)
"""Frame rates (frames per second) mocapviz reads from files and resamples to: a clip outside them is a broken
header (``Frame Time: 1e308``), not a capture."""
_RESAMPLE_BLOCK = 1 << 16  # joint-frames per block of Motion.resample: about 25 MB of float64 temporaries


def fps_problem(fps: float) -> str | None:
    """Why ``fps`` is not a frame rate mocapviz accepts (outside :data:`FPS_RANGE`, not finite), or None.

    Parameters
    ----------
    fps : float
        Frames per second.

    Returns
    -------
    str or None
        The reason in words; None for an accepted rate.

    Examples
    --------
    >>> fps_problem(120) is None, fps_problem(0.5)
    (True, '0.5 frames per second is outside 1 to 10,000 frames per second')
    """
    low, high = FPS_RANGE
    if not (np.isfinite(fps) and low <= fps <= high):
        return f"{fps:g} frames per second is outside {low:g} to {high:,g} frames per second"
    return None


@dataclass(frozen=True, eq=False)
class Motion:
    """One motion clip.

    Every reader returns one (:func:`mocapviz.io.load`), and so does :meth:`mocapviz.MotionDB.motion`. The
    parameters are its attributes, with ``n_frames`` (T), ``n_joints`` (J) and ``duration`` (seconds).

    Parameters
    ----------
    positions : np.ndarray [shape=(T, J, 3)], float32
        Joint positions in centimetres, y up (right-handed).
    fps : float
        Frames per second.
    joint_names : tuple of str [length J]
        Joint names: the source skeleton's (ASF bone tips, BVH joints and end sites), a C3D file's marker names
        or, after :meth:`canonical`, the 24 canonical joints of ``mocapviz.motion.skeleton.CANONICAL_JOINTS``.
    parents : np.ndarray [shape=(J,)], int64
        Parent joint index, -1 for the root; parents come before their children. A marker clip has no skeleton:
        all -1, no quaternions, NaN positions in its gaps (``mocapviz.motion.markers``).
    quaternions : np.ndarray [shape=(T, J, 4)], float32, or None
        Local joint rotations ``(w, x, y, z)`` relative to the parent, where the source has them.
    source : str or None
        The file the clip was read from.
    labels : dict
        Annotations that travel with the clip (class, actor, style, ...).
    euler : np.ndarray [shape=(T, C)], float32, or None
        The source file's C rotation channel values in degrees, translation channels left out (AMC: the
        root's rotation channels, then each bone's DOFs, bones in skeleton order; BVH: the rotation channels
        in file order). They describe the source skeleton, so :meth:`canonical` keeps them unchanged
        (needed for Krüger et al. 2010 §3.1 Deuler, ``mocapviz.features.distances``).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> m = MotionDB.sample().motion(7)
    >>> m.n_frames, m.n_joints, m.fps, m.duration
    (129, 24, 120.0, 1.075)
    >>> m[0:60].n_frames, m.resample(30).n_frames, m.joint("lankle").shape
    (60, 33, (129, 3))
    """

    positions: np.ndarray
    fps: float
    joint_names: tuple
    parents: np.ndarray
    quaternions: np.ndarray | None = None
    source: str | None = None
    labels: dict = field(default_factory=dict)
    euler: np.ndarray | None = None

    def __post_init__(self):
        pos = np.asarray(self.positions, dtype=np.float32)
        if pos.ndim != 3 or pos.shape[2] != 3:
            raise ParameterError(f"Motion.positions must have shape (T, J, 3), got {pos.shape}")
        names = tuple(self.joint_names)
        parents = np.asarray(self.parents, dtype=np.int64)
        if len(names) != pos.shape[1] or parents.shape != (pos.shape[1],):
            raise ParameterError(
                f"Motion has {pos.shape[1]} joints in positions, {len(names)} names, {parents.shape} parents"
            )
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ParameterError(f"Motion.fps must be a positive number, got {self.fps}")
        quat = self.quaternions
        if quat is not None:
            quat = np.asarray(quat, dtype=np.float32)
            if quat.shape != pos.shape[:2] + (4,):
                raise ParameterError(f"Motion.quaternions must have shape {pos.shape[:2] + (4,)}, got {quat.shape}")
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "joint_names", names)
        object.__setattr__(self, "parents", parents)
        euler = self.euler
        if euler is not None:
            euler = np.asarray(euler, dtype=np.float32)
            if euler.ndim != 2 or euler.shape[0] != pos.shape[0]:
                raise ParameterError(f"Motion.euler must have shape ({pos.shape[0]}, C), got {euler.shape}")
        object.__setattr__(self, "quaternions", quat)
        object.__setattr__(self, "euler", euler)
        object.__setattr__(self, "fps", float(self.fps))

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def n_joints(self) -> int:
        return self.positions.shape[1]

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.n_frames / self.fps

    def joint(self, name: str) -> np.ndarray:
        """Trajectory of one joint.

        Parameters
        ----------
        name : str
            One of :attr:`joint_names`.

        Returns
        -------
        np.ndarray [shape=(T, 3)], float32
            Its positions, cm (a view).

        Raises
        ------
        KeyError
            No such joint (an UnknownKeyError listing the joints).
        """
        try:
            return self.positions[:, self.joint_names.index(name)]
        except ValueError:
            raise UnknownKeyError(f"{self.source or 'motion'} has no joint {name!r}; it has {', '.join(self.joint_names)}")

    def canonical(self, mapping: dict | None = None) -> Motion:
        """This clip on the 24 canonical joints (``mocapviz.motion.skeleton``), in their fixed order.

        Parameters
        ----------
        mapping : dict, optional
            Canonical name -> this motion's joint name, overriding the automatic rules
            (:func:`mocapviz.motion.skeleton.guess_mapping`). A marker clip (a C3D file's: markers without a
            skeleton) is turned into joints by :func:`mocapviz.motion.markers.marker_joints`; for it, ``mapping``
            is marker of the marker set -> this clip's marker name (``{"LFWT": "L_FWT"}``).

        Returns
        -------
        Motion
            Positions [shape=(T, 24, 3)] in cm, local rotations on the canonical tree where the source has them,
            the same ``fps``, ``source``, ``labels`` and ``euler``.

        Raises
        ------
        SkeletonMappingError
            A rig that cannot be mapped; the message holds a template for ``mapping``.
        """
        from .skeleton import to_canonical

        return to_canonical(self, mapping)

    def resample(self, fps: float) -> Motion:
        """The same clip at another frame rate.

        Frame k of the result is at time k / fps; the last frame is the last one at or before the end of
        the clip. Positions are interpolated linearly, rotations by slerp between the two nearest frames,
        Euler angles linearly along the shorter way round (so 179 and -179 degrees meet at 180).

        Parameters
        ----------
        fps : float
            The new frame rate, frames per second.

        Returns
        -------
        Motion
            floor((T - 1) / self.fps x fps) + 1 frames: every frame time up to the time of the last frame. Computed
            a block of frames at a time into its float32 arrays: peak memory is the arrays returned plus a few MB.

        Raises
        ------
        ParameterError
            ``fps`` or the clip's own frame rate is outside :data:`FPS_RANGE` (1 to 10,000 frames per second).
        """
        try:
            fps = float(fps)
        except (TypeError, ValueError):
            raise ParameterError(f"target fps must be a number, got {fps!r}") from None
        for what, rate in (("target fps", fps), (f"the frame rate of {self.source or 'the clip'}", self.fps)):
            problem = fps_problem(rate)
            if problem:
                raise ParameterError(f"cannot resample: {what}: {problem}")
        if fps == self.fps:
            return self
        n_out = int(np.floor((self.n_frames - 1) * fps / self.fps + 1e-9)) + 1
        pos = np.empty((n_out, self.n_joints, 3), dtype=np.float32)
        quat = None if self.quaternions is None else np.empty((n_out, self.n_joints, 4), dtype=np.float32)
        euler = None if self.euler is None else np.empty((n_out, self.euler.shape[1]), dtype=np.float32)
        # a block of output frames at a time: the float64 temporaries (slerp's) stay a few MB whatever the length
        step = max(1, _RESAMPLE_BLOCK // max(1, self.n_joints))
        for a in range(0, n_out, step):
            self._resample_block(np.arange(a, min(n_out, a + step)) * (self.fps / fps), pos, quat, euler, a)
        return replace(self, positions=pos, quaternions=quat, euler=euler, fps=fps)

    def _resample_block(self, x: np.ndarray, pos: np.ndarray, quat: np.ndarray | None, euler: np.ndarray | None,
                        at: int) -> None:
        """Frames at times ``x`` (in source frames) written to ``pos``, ``quat``, ``euler`` from row ``at`` on."""
        i0 = np.minimum(np.floor(x + 1e-9).astype(np.int64), self.n_frames - 1)
        i1 = np.minimum(i0 + 1, self.n_frames - 1)
        w = np.clip(x - i0, 0.0, 1.0)
        out = slice(at, at + x.shape[0])
        p0 = self.positions[i0]
        pos[out] = p0 + (self.positions[i1] - p0) * w[:, None, None].astype(np.float32)
        if quat is not None:
            from . import rotations  # numba: loaded by the first resampling, not by every import of Motion

            quat[out] = rotations.slerp(self.quaternions[i0], self.quaternions[i1], w[:, None])
        if euler is not None:
            e0 = self.euler[i0]
            turn = np.remainder(self.euler[i1] - e0 + 180.0, 360.0) - 180.0
            euler[out] = e0 + turn * w[:, None].astype(np.float32)

    def __getitem__(self, frames) -> Motion:
        """Frames ``frames`` (a slice or an index array) of this clip as a new Motion."""
        if isinstance(frames, (int, np.integer)):
            k = range(self.n_frames)[frames]  # negative from the end; IndexError when out of range
            frames = slice(k, k + 1)
        quat = None if self.quaternions is None else self.quaternions[frames]
        euler = None if self.euler is None else self.euler[frames]
        return replace(self, positions=self.positions[frames], quaternions=quat, euler=euler)

    def __repr__(self) -> str:
        return (
            f"Motion({self.n_frames} frames at {self.fps:g} fps, {self.n_joints} joints, "
            f"source={self.source!r})"
        )
