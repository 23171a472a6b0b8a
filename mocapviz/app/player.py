"""The dashboard's 3D skeleton player: one or more clips sent to the browser once and animated there.

:class:`SkeletonPlayer` hands the clips' canonical joint positions to a small Panel ``JSComponent``
(:class:`PlayerView`, code in ``player.js`` beside this module, after the ``skeleton.js`` it shares with the gallery:
Canvas 2D, a perspective projection of the bones, no library, nothing fetched at run time). The browser plays them at
the clip's frame rate (0.25×-2×), scrubs with its slider, orbits (drag) and zooms (wheel) the camera over a floor grid,
and colours the bones by side. Several clips play in step through an alignment: row s of ``alignment`` names the frame
of every clip shown at step s (a DTW or LNG warping path plays two motions aligned; without one, clips play from their
first frames at the same rate, each holding its last frame); they are shown side by side or overlaid.

Wire format (one message per :meth:`SkeletonPlayer.load`): ``positions`` is the float32 little-endian bytes of every
clip's (T_i, 24, 3) positions in cm, concatenated (a Bokeh binary buffer on the server's WebSocket: 288 KB for 1,000
frames, base64 only in static exports); ``alignment`` the int32 bytes of the (S, n_clips) alignment; ``meta`` the
lengths, titles, frame rate, bone tree, sides and scene box. The shown step comes back to Python (``step``) when the
user pauses, steps or scrubs, and at most four times a second during playback.
"""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path
from typing import ClassVar

import numpy as np
import panel as pn
import param
from panel.custom import JSComponent

from ..engine import CANONICAL_PARENTS
from ..errors import ParameterError
from ..viz.palette import SIDE_NAMES, SIDES, joint_sides, legend

SPEEDS = (0.25, 0.5, 1.0, 2.0)
CONTROLS_HEIGHT = 60  # px under the canvas: the buttons, slider and caption


def scene_box(clips, margin_cm: float = 20.0) -> list[list[float]]:
    """(min, max) corners in cm of every frame of ``clips``, widened by ``margin_cm``, the floor (y = 0) inside."""
    lo = np.min([c.reshape(-1, 3).min(axis=0) for c in clips], axis=0) - margin_cm
    hi = np.max([c.reshape(-1, 3).max(axis=0) for c in clips], axis=0) + margin_cm
    lo[1], hi[1] = min(lo[1], 0.0), max(hi[1], 0.0)
    return [[float(v) for v in lo], [float(v) for v in hi]]


def recentred(clip) -> np.ndarray:
    """``clip`` [shape=(T, J, 3)], cm, as float32, moved along the floor so that its first root position is above the
    origin (side-by-side views, and the gallery's cells, then frame it alike)."""
    clip = np.asarray(clip, dtype=np.float32)
    return clip - np.array([clip[0, 0, 0], 0.0, clip[0, 0, 2]], dtype=np.float32)


def component_code(name: str) -> str:
    """The browser code of a skeleton component: ``skeleton.js`` (the side colours, camera, projection and bone drawing
    that the player and the gallery share) followed by the component's own file ``name`` (its ``render``), both
    beside this module: one self-contained ES module, nothing imported or fetched."""
    here = Path(__file__).parent
    return "\n".join((here / f).read_text(encoding="utf-8") for f in ("skeleton.js", name))


class PlayerView(JSComponent):
    """The browser side of :class:`SkeletonPlayer` (``player.js``); its parameters are the wire format."""

    positions = param.Bytes(default=None, doc="float32 little-endian (sum T_i, J, 3) cm: the clips, concatenated")
    alignment = param.Bytes(default=None, doc="int32 little-endian (S, n_clips): the frame of each clip per step")
    meta = param.Dict(default={}, doc="lengths, n_joints, titles, fps, parents, sides, bounds")
    step = param.Integer(default=0, bounds=(0, None), doc="the shown step (synced back, throttled)")
    speed = param.Number(default=1.0, doc="playback speed, a multiple of the clips' frame rate")
    view_size = param.List(default=[520, 380], doc="(width, height) of the canvas in px")

    _esm = component_code("player.js")

    _stylesheets: ClassVar[list[str]] = ["""
.mvp { font: 13px sans-serif; }
.mvp canvas { display: block; border: 1px solid #ddd; cursor: grab; touch-action: none; }
.mvp-controls { display: flex; align-items: center; gap: 4px; margin-top: 4px; }
.mvp-controls button { font-size: 13px; min-width: 30px; height: 26px; white-space: nowrap; border: 1px solid #bbb;
  border-radius: 4px; background: #f7f7f7; cursor: pointer; }
.mvp-controls button.active { background: #1f5fa8; color: #fff; border-color: #1f5fa8; }
.mvp-speeds { display: inline-flex; gap: 2px; margin-left: 4px; }
.mv-player-caption p { margin: 4px 0 0 2px; color: #333; }
"""]


class SkeletonPlayer(pn.viewable.Viewer):
    """Play/pause, a frame slider, speed and an orbiting camera over clips of canonical poses, in the browser.

    Parameters
    ----------
    size : (width, height) in pixels of the view (split between the clips side by side).

    Attributes
    ----------
    step : int parameter, the shown step (a frame of the first clip when there is no alignment); watch it to follow
        the player. The browser reports it when paused, stepped or scrubbed, and every 250 ms during playback;
        setting it moves the browser's player.
    speed : float parameter, the playback speed (0.25, 0.5, 1 or 2 times the clips' frame rate).
    view : PlayerView, the browser component.
    """

    step = param.Integer(default=0, bounds=(0, None))
    speed = param.Selector(default=1.0, objects=list(SPEEDS))

    def __init__(self, size=(520, 380), **params):
        super().__init__(**params)
        self.size = tuple(int(v) for v in size)
        self.fps = 30.0
        self._clips: list[np.ndarray] = []
        self._titles: list[str] = []
        self._alignment = np.zeros((1, 0), dtype=np.int64)
        self.view = PlayerView(view_size=list(self.size), width=self.size[0] + 2,
                               height=self.size[1] + CONTROLS_HEIGHT, css_classes=["mv-player"])
        self.view.param.watch(self._from_view, ["step", "speed"])
        self.param.watch(self._to_view, ["step", "speed"])
        self.legend = pn.pane.HTML(legend(SIDES, SIDE_NAMES, "bones"), margin=(0, 4), css_classes=["mv-player-legend"],
                                   styles={"font-size": "0.85em", "color": "#333"})  # fmt: skip

    def __panel__(self):
        return pn.Column(self.view, self.legend, margin=0)

    @property
    def n_steps(self) -> int:
        return self._alignment.shape[0]

    def _from_view(self, event) -> None:
        value = float(event.new) if event.name == "speed" else int(event.new)
        if getattr(self, event.name) != value and (event.name != "speed" or value in SPEEDS):
            setattr(self, event.name, value)

    def _to_view(self, event) -> None:
        if getattr(self.view, event.name) != event.new:
            setattr(self.view, event.name, event.new)

    def load(self, clips, titles=None, fps: float = 30.0, alignment=None) -> None:
        """Show new clips from their first step (sent to the browser in one message).

        Parameters
        ----------
        clips : list of np.ndarray [shape=(T_i, 24, 3)], cm, y up.
        titles : list of str, one per clip.
        fps : float, the clips' frame rate (playback at 1× is real time).
        alignment : np.ndarray [shape=(L, len(clips))], int, optional: frame of each clip per step.

        Raises
        ------
        ValueError
            No clip, an empty clip or one not of the canonical joints, or an alignment of the wrong shape or outside a
            clip's frames.
        """
        n_joints = len(CANONICAL_PARENTS)
        clips = [np.asarray(c, dtype=np.float32) for c in clips]
        if not clips or any(c.ndim != 3 or c.shape[1:] != (n_joints, 3) or len(c) == 0 for c in clips):
            raise ParameterError(f"the player needs one or more non-empty (T, {n_joints}, 3) clips")
        if not all(np.isfinite(c).all() for c in clips):
            raise ParameterError("the player's clips hold NaN or infinite positions")
        if not np.isfinite(fps) or fps <= 0:
            raise ParameterError(f"the player's fps must be a positive number; got {fps}")
        clips = [recentred(c) for c in clips]  # side-by-side viewports share one camera box
        if alignment is None:
            length = max(len(c) for c in clips)
            alignment = np.column_stack([np.minimum(np.arange(length), len(c) - 1) for c in clips])
        alignment = np.asarray(alignment, dtype=np.int64)
        if alignment.ndim != 2 or alignment.shape[1] != len(clips) or not len(alignment):
            raise ParameterError(f"alignment must be (L, {len(clips)}) frame numbers; got shape {alignment.shape}")
        for j, c in enumerate(clips):
            if alignment[:, j].min() < 0 or alignment[:, j].max() >= len(c):
                raise ParameterError(f"alignment column {j} leaves clip {j}'s frames 0..{len(c) - 1}")
        self._clips, self._alignment, self.fps = clips, alignment, float(fps)
        self._titles = list(titles) if titles is not None else [f"clip {j + 1}" for j in range(len(clips))]
        meta = {"lengths": [len(c) for c in clips], "n_joints": n_joints, "titles": [str(t) for t in self._titles],
                "fps": self.fps, "parents": [int(p) for p in CANONICAL_PARENTS], "sides": joint_sides(), "side_colours": SIDES,
                "bounds": scene_box(clips)}
        positions = np.concatenate([c.reshape(-1) for c in clips]).astype("<f4").tobytes()
        self.view.param.update(positions=positions, alignment=alignment.astype("<i4").tobytes(), meta=meta, step=0)
        self.step = 0

    def frames(self) -> list[int]:
        """The frame of each clip shown now."""
        if not self._clips:
            return []
        return [int(f) for f in self._alignment[min(self.step, self.n_steps - 1)]]

    def caption(self) -> str:
        """The caption the browser shows under the view: the step and the clip's playing time at the chosen speed
        (the speed button lit)."""
        seconds = self.n_steps / self.fps / self.speed
        return f"step {self.step + 1} of {self.n_steps} · {seconds:.2f} s at {self.speed:g}×"


def decode(view: PlayerView):
    """What ``view`` sends the browser, decoded as ``player.js`` does: (clips, alignment) as numpy arrays."""
    meta = view.meta
    flat = np.frombuffer(view.positions or b"", dtype="<f4")
    cuts = np.cumsum([0] + [n * meta["n_joints"] * 3 for n in meta["lengths"]])
    clips = [flat[a:b].reshape(-1, meta["n_joints"], 3) for a, b in pairwise(cuts)]
    alignment = np.frombuffer(view.alignment or b"", dtype="<i4").reshape(-1, len(meta["lengths"]))
    return clips, alignment
