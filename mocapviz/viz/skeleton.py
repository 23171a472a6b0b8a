"""Skeletons drawn offscreen with PyVista (VTK through EGL; no display needed): figures for notebooks and
``reproduce``, and the neighbour-pose figure of Krüger, Tautges, Weber & Zinke 2010, Fig. 1 (the dashboard's 3D
player animates in the browser instead: :mod:`mocapviz.app.player`).

render_skeletons   one image of one or more canonical poses: side by side (each in its own viewport, one shared
                   camera) or drawn together in one scene (``overlay``), over a floor grid.
scene_bounds       the box a whole clip (or several) moves in, so a player's camera stays put while it plays.
neighbour_poses    Fig. 1: the k nearest poses of a query pose, each turned into the body frame (root at the origin,
                   facing +z) and drawn together, the query in front.

Bones are coloured by side as in the dashboard's player (right red, left blue: :data:`mocapviz.viz.palette.SIDES`);
a pose given a colour of its own is drawn in it (Fig. 1's neighbours: grey).
png_bytes          an RGB image as PNG bytes (for ``panel.pane.PNG``).

Poses are float (J, 3) arrays in cm, y up, joints in :data:`mocapviz.motion.skeleton.CANONICAL_JOINTS` order. VTK is not
thread safe (a plotter rendered from another thread than its own crashes the process): every drawing is done in
one render thread, on a plotter kept per (viewports, size), whichever thread asks for it; concurrent dashboard
sessions queue for a few milliseconds.
"""

from __future__ import annotations

import io
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..errors import ParameterError
from ..motion.skeleton import CANONICAL_PARENTS, body_frame
from .palette import OTHERS, SIDES, joint_sides

BY_SIDE = "sides"  # a pose's colour: each bone in its side's colour (SIDES), the default
_RENDER_THREAD = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mocapviz-vtk")
_PLOTTERS: dict = {}  # (viewports, size) -> pyvista.Plotter, created and used in _RENDER_THREAD only


def _check_poses(poses, what: str = "poses") -> list[np.ndarray]:
    out = [np.asarray(p, dtype=np.float64) for p in poses]
    if not out:
        raise ParameterError(f"no {what} to draw")
    for i, p in enumerate(out):
        if p.shape != (len(CANONICAL_PARENTS), 3):
            raise ParameterError(f"{what}[{i}] has shape {p.shape}; expected ({len(CANONICAL_PARENTS)}, 3) canonical "
                             "joint positions in cm")
        if not np.isfinite(p).all():
            raise ParameterError(f"{what}[{i}] holds NaN or infinite coordinates")
    return out


def scene_bounds(*clips, margin_cm: float = 20.0) -> np.ndarray:
    """The box every frame of the given clips lies in, widened by ``margin_cm``.

    Parameters
    ----------
    *clips : np.ndarray [shape=(T, J, 3) or (J, 3)]
        Joint positions, cm, y up.
    margin_cm : float
        Added on every side, cm.

    Returns
    -------
    np.ndarray [shape=(2, 3)], float64
        (min, max) corners in cm; the floor (y = 0) is always inside.

    Examples
    --------
    >>> scene_bounds(np.array([[0.0, 10.0, 0.0], [50.0, 170.0, 20.0]]), margin_cm=10.0).tolist()
    [[-10.0, 0.0, -10.0], [60.0, 180.0, 30.0]]
    """
    pts = np.concatenate([np.asarray(c, dtype=np.float64).reshape(-1, 3) for c in clips])
    lo, hi = np.nanmin(pts, axis=0) - margin_cm, np.nanmax(pts, axis=0) + margin_cm
    lo[1], hi[1] = min(lo[1], 0.0), max(hi[1], 0.0)
    return np.stack([lo, hi])


def _plotter(viewports: int, size: tuple[int, int]):
    key = (viewports, size)
    if key not in _PLOTTERS:
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        import pyvista as pv

        _PLOTTERS[key] = pv.Plotter(off_screen=True, shape=(1, viewports), window_size=size, border=False)
    return _PLOTTERS[key]


def render_skeletons(poses, bounds=None, size: tuple[int, int] = (480, 360), overlay: bool = False,
                     colours=None, opacities=None, titles=None, azimuth: float = 0.0) -> np.ndarray:
    """Draw canonical poses offscreen.

    Parameters
    ----------
    poses : sequence of np.ndarray [shape=(24, 3)]
        Canonical joints, cm, y up.
    bounds : np.ndarray [shape=(2, 3)], optional
        The box the camera frames (:func:`scene_bounds`, so a playing clip does not make the camera jump), cm;
        default the poses' own box.
    size : (int, int)
        (width, height) of the whole image in pixels.
    overlay : bool
        All poses in one scene (Fig. 1) instead of one viewport each, side by side.
    colours, opacities : sequence, optional
        One per pose: a colour, or :data:`BY_SIDE` (default: every bone in its side's colour,
        :data:`mocapviz.viz.palette.SIDES`); opacities default opaque.
    titles : sequence of str, optional
        One caption per viewport (side by side) or one for the scene (overlay).
    azimuth : float
        Degrees the camera is turned about the vertical axis from its front-right view.

    Returns
    -------
    np.ndarray [shape=(height, width, 3)], uint8
        RGB pixels.
    """
    poses = _check_poses(poses)
    colours = list(colours or [BY_SIDE] * len(poses))
    opacities = list(opacities or [1.0] * len(poses))
    bounds = scene_bounds(*poses) if bounds is None else np.asarray(bounds, dtype=np.float64)
    viewports = [list(range(len(poses)))] if overlay else [[i] for i in range(len(poses))]
    return _RENDER_THREAD.submit(_render, poses, viewports, bounds, tuple(size), colours, opacities, titles,
                                 azimuth).result()


def _render(poses, viewports, bounds, size, colours, opacities, titles, azimuth) -> np.ndarray:
    """Draw in the render thread: per viewport, the poses of each (colour, opacity) merged into one mesh (by side:
    one mesh per side)."""
    import pyvista as pv

    p = _plotter(len(viewports), size)
    p.clear_actors()  # of every viewport
    for v, members in enumerate(viewports):
        p.subplot(0, v)
        styles = dict.fromkeys((colours[i], opacities[i]) for i in members)
        for colour, opacity in styles:
            group = [poses[i] for i in members if (colours[i], opacities[i]) == (colour, opacity)]
            sides = SIDES.items() if colour == BY_SIDE else [(None, colour)]
            thin = opacity < 1  # faint poses (Fig. 1's neighbours) thinner, so the opaque one shows through them
            for side, ink in sides:
                mesh = pv.PolyData(np.concatenate(group), lines=_bones_of(len(group), side))
                p.add_mesh(mesh, color=ink, opacity=opacity, line_width=2 if thin else 5, render_lines_as_tubes=True)
                p.add_points(mesh.points[_joints_of(len(group), side)], color=ink, opacity=opacity,
                             point_size=4 if thin else 9, render_points_as_spheres=True)
        _floor(p, bounds)
        if titles is not None and v < len(titles):
            p.add_text(str(titles[v]), font_size=9, position="upper_left", color="black", name=f"title{v}")
        _camera(p, bounds, azimuth)
    p.set_background("white")
    p.render()  # a plotter's later screenshots do not render the scene again by themselves: without this, a
    # drawing after the first came out blank once its poses stood a few metres from the last ones
    return np.asarray(p.screenshot(return_img=True))[..., :3].copy()


def _bones_of(n_poses: int, side: str | None = None) -> np.ndarray:
    """VTK line cells of ``n_poses`` canonical skeletons stacked one after the other in one point array; ``side``:
    only the bones whose child joint is on that side ("l", "r", "c"; :func:`mocapviz.viz.palette.joint_sides`)."""
    child = np.flatnonzero((CANONICAL_PARENTS >= 0) & _on(side))
    one = np.column_stack([np.full(len(child), 2), CANONICAL_PARENTS[child], child])  # cells (2, parent, child)
    shift = (np.arange(n_poses) * len(CANONICAL_PARENTS))[:, None, None] * np.array([0, 1, 1])
    return (one[None] + shift).ravel()


def _on(side: str | None) -> np.ndarray:
    """The canonical joints on ``side`` (None: all), (24,) bool."""
    sides = np.array(joint_sides())
    return np.ones(len(sides), dtype=bool) if side is None else sides == side


def _joints_of(n_poses: int, side: str | None) -> np.ndarray:
    """The points of the joints on ``side`` of ``n_poses`` stacked skeletons, (n_poses * 24,) bool."""
    return np.tile(_on(side), n_poses)


def _floor(p, bounds: np.ndarray) -> None:
    import pyvista as pv

    (x0, _, z0), (x1, _, z1) = bounds
    floor = pv.Plane(center=((x0 + x1) / 2, 0.0, (z0 + z1) / 2), direction=(0, 1, 0), i_size=x1 - x0,
                     j_size=z1 - z0, i_resolution=max(1, int((x1 - x0) // 50)),
                     j_resolution=max(1, int((z1 - z0) // 50)))
    p.add_mesh(floor, color="#d9d9d9", style="wireframe", line_width=1)


def _camera(p, bounds: np.ndarray, azimuth: float) -> None:
    centre = bounds.mean(axis=0)
    radius = float(np.linalg.norm(bounds[1] - bounds[0])) / 2
    a = np.deg2rad(30.0 + azimuth)
    direction = np.array([np.sin(a), 0.35, np.cos(a)])
    p.camera.focal_point = tuple(centre)
    p.camera.position = tuple(centre + direction / np.linalg.norm(direction) * radius / np.tan(np.deg2rad(14.0)))
    p.camera.up = (0.0, 1.0, 0.0)
    p.camera.view_angle = 30.0
    p.camera.clipping_range = (radius * 0.1, radius * 8)


def neighbour_poses(query_pose, neighbours, size: tuple[int, int] = (480, 420), azimuth: float = 0.0) -> np.ndarray:
    """Krüger et al. 2010, Fig. 1: a query pose and its nearest neighbours drawn together in the body frame.

    Parameters
    ----------
    query_pose : np.ndarray [shape=(24, 3)]
        The query frame's canonical joints, cm, y up (world coordinates).
    neighbours : np.ndarray [shape=(k, 24, 3)]
        The neighbour frames' poses, cm, y up (world coordinates).
    size : (int, int)
        (width, height) of the image in pixels.
    azimuth : float
        Degrees the camera is turned about the vertical axis from its front-right view.

    Returns
    -------
    np.ndarray [shape=(height, width, 3)], uint8
        RGB: the neighbours faint grey (:data:`mocapviz.viz.palette.OTHERS`), the query opaque with its bones by
        side (right red, left blue, as in the player), all with the root at the origin facing +z (so only the
        posture differs, as in the figure).
    """
    neighbours = np.asarray(neighbours, dtype=np.float64).reshape(-1, len(CANONICAL_PARENTS), 3)
    poses = body_frame(np.concatenate([neighbours, np.asarray(query_pose, dtype=np.float64)[None]]))
    poses[..., 1] -= poses[..., 1].min()  # the root sits at height 0: lift the lowest joint onto the floor
    k = len(neighbours)
    return render_skeletons(list(poses), size=size, overlay=True, colours=[OTHERS] * k + [BY_SIDE],
                            opacities=[max(0.1, min(0.35, 4.0 / max(k, 1)))] * k + [1.0],
                            titles=[f"query and its {k} nearest neighbours"], azimuth=azimuth)


def png_bytes(image: np.ndarray) -> bytes:
    """An RGB image as PNG file bytes (fast compression).

    Parameters
    ----------
    image : np.ndarray [shape=(H, W, 3)], uint8
        RGB pixels.

    Returns
    -------
    bytes
        A PNG file.
    """
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.asarray(image, dtype=np.uint8)).save(buf, format="PNG", compress_level=1)
    return buf.getvalue()
