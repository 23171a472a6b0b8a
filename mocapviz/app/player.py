"""The dashboard's 3D skeleton player: one or more clips rendered offscreen by PyVista, played side by side.

The server draws each shown frame (:func:`mocapviz.viz.skeleton.render_skeletons`, a few milliseconds through EGL)
and sends it as a PNG, so the browser needs no WebGL. Several clips play in step through an alignment: row s of
``alignment`` names the frame of every clip shown at step s (a DTW or LNG warping path plays two motions aligned;
without one, clips play from their first frames at the same rate, each holding its last frame).
"""

from __future__ import annotations

import numpy as np
import panel as pn
import param

from ..errors import ParameterError
from ..viz.skeleton import png_bytes, render_skeletons, scene_bounds

SPEEDS = {"0.25×": 0.25, "0.5×": 0.5, "1×": 1.0, "2×": 2.0}
MAX_DISPLAY_FPS = 15.0


class SkeletonPlayer(pn.viewable.Viewer):
    """Play/pause, a frame slider, speed and camera angle over clips of canonical poses.

    Parameters
    ----------
    size : (width, height) in pixels of the whole image (split between the clips side by side).

    Attributes
    ----------
    step : int parameter, the shown step (a frame of the first clip when there is no alignment); watch it to follow
        the player.
    """

    step = param.Integer(default=0, bounds=(0, None))

    def __init__(self, size=(520, 380), **params):
        super().__init__(**params)
        self.size = tuple(size)
        self._clips: list[np.ndarray] = []
        self._titles: list[str] = []
        self._alignment = np.zeros((1, 0), dtype=np.int64)
        self._bounds = None
        self.image = pn.pane.PNG(None, width=self.size[0], height=self.size[1], css_classes=["mv-player-image"])
        self.player = pn.widgets.Player(start=0, end=1, value=0, interval=100, loop_policy="loop",
                                        show_loop_controls=False, width=self.size[0], css_classes=["mv-player"],
                                        visible_buttons=["slower", "previous", "pause", "play", "next", "faster"])
        self.speed = pn.widgets.RadioButtonGroup(options=list(SPEEDS), value="1×", width=200)
        self.azimuth = pn.widgets.IntSlider(label="camera (°)", start=-180, end=180, step=15, value=0, width=180)
        self.caption = pn.pane.Markdown("", margin=(0, 5), css_classes=["mv-player-caption"])
        self.player.param.watch(lambda e: setattr(self, "step", int(e.new)), "value")
        self.param.watch(self._on_step, "step")
        self.speed.param.watch(lambda e: self._set_interval(), "value")
        self.azimuth.param.watch(lambda e: self._draw(), "value")
        self.fps = 30.0

    def __panel__(self):
        return pn.Column(self.image, self.player, pn.Row(self.speed, self.azimuth), self.caption)

    @property
    def n_steps(self) -> int:
        return self._alignment.shape[0]

    def load(self, clips, titles=None, fps: float = 30.0, alignment=None) -> None:
        """Show new clips from their first step.

        Parameters
        ----------
        clips : list of np.ndarray [shape=(T_i, 24, 3)], cm, y up.
        titles : list of str, one per clip.
        fps : float, the clips' frame rate (playback at 1× is real time).
        alignment : np.ndarray [shape=(L, len(clips))], int, optional: frame of each clip per step.

        Raises
        ------
        ValueError
            No clip, an empty clip, or an alignment of the wrong shape or outside a clip's frames.
        """
        clips = [np.asarray(c, dtype=np.float32) for c in clips]
        if not clips or any(c.ndim != 3 or len(c) == 0 for c in clips):
            raise ParameterError("the player needs one or more non-empty (T, 24, 3) clips")
        # each clip starts above the origin, so side-by-side viewports share one camera box
        clips = [c - np.array([c[0, 0, 0], 0.0, c[0, 0, 2]], dtype=np.float32) for c in clips]
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
        self._bounds = scene_bounds(*clips)
        self._set_interval()
        self.player.param.update(value=0, end=max(self.n_steps - 1, 1))
        self.step = 0
        self._draw()

    def _set_interval(self) -> None:
        stride = max(1, round(self.fps / MAX_DISPLAY_FPS))
        self.player.step = stride
        self.player.interval = round(1000 * stride / self.fps / SPEEDS[self.speed.value])

    def _on_step(self, event) -> None:
        if self.player.value != event.new:
            self.player.value = event.new
        self._draw()

    def frames(self) -> list[int]:
        """The frame of each clip shown now."""
        if not self._clips:
            return []
        return [int(f) for f in self._alignment[min(self.step, self.n_steps - 1)]]

    def _draw(self) -> None:
        if not self._clips:
            return
        frames = self.frames()
        poses = [c[f] for c, f in zip(self._clips, frames)]
        titles = [f"{t}  frame {f}" for t, f in zip(self._titles, frames)]
        image = render_skeletons(poses, bounds=self._bounds, size=self.size, titles=titles,
                                 azimuth=float(self.azimuth.value))
        self.image.object = png_bytes(image)
        self.caption.object = f"step {self.step + 1} of {self.n_steps} · {self.n_steps / self.fps:.2f} s at 1×"
