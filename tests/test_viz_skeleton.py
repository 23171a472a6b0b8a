"""Offscreen skeleton drawings (mocapviz.viz.skeleton) of real sample poses, checked on their pixels: bones by side
in the palette's colours (right red, left blue), as the dashboard's player draws them."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from mocapviz.viz.skeleton import neighbour_poses, png_bytes, render_skeletons, scene_bounds


@pytest.fixture(scope="module")
def clip(sample_db):
    doc = int(sample_db.select(label="kickLFront1Reps")["doc_id"].iloc[0])
    return np.asarray(sample_db.positions[sample_db.frames(doc)])


def _red(image: np.ndarray) -> np.ndarray:
    """Pixels of the shaded red of the right side (SIDES["r"], #d1452f): red well above green and blue."""
    r, g, b = (image[..., i].astype(int) for i in range(3))
    return (r > 90) & (r > 2 * g) & (r > 2 * b)


def _blue(image: np.ndarray) -> np.ndarray:
    """Pixels of the shaded blue of the left side (SIDES["l"], #1f5fa8)."""
    r, _g, b = (image[..., i].astype(int) for i in range(3))
    return (b > 80) & (b > 2 * r)


def test_scene_bounds_hold_every_joint_and_the_floor(clip):
    lo, hi = scene_bounds(clip, margin_cm=5)
    pts = clip.reshape(-1, 3)
    assert (pts >= lo + 5 - 1e-4).all() and (pts <= hi - 5 + 1e-4).all()
    assert lo[1] <= 0 <= hi[1]


def test_side_by_side_draws_each_pose_in_its_own_half_by_side(clip):
    img = render_skeletons([clip[0], clip[-1]], bounds=scene_bounds(clip), size=(400, 200))
    assert img.shape == (200, 400, 3) and img.dtype == np.uint8
    blue, red = _blue(img), _red(img)
    for half in (slice(0, 200), slice(200, 400)):  # each pose: its right side red, its left side blue
        assert blue[:, half].sum() > 50 and red[:, half].sum() > 50
    single = render_skeletons([clip[0]], size=(200, 200), colours=["#2ca02c"])  # a colour of its own: no sides
    assert _red(single).sum() == 0 and _blue(single).sum() == 0


def test_overlay_puts_the_query_by_side_over_grey_neighbours(clip):
    img = neighbour_poses(clip[30], clip[::10], size=(300, 260))
    assert img.shape == (260, 300, 3)
    assert _red(img).sum() > 50 and _blue(img).sum() > 50  # the query: right red, left blue
    alone = neighbour_poses(clip[30], clip[::10][:0], size=(300, 260))  # without neighbours: the query alone
    r, g, b = (img[..., i].astype(int) for i in range(3))
    grey = (abs(r - g) < 12) & (abs(g - b) < 12) & (r < 200) & (r > 60)
    ra, ga, ba = (alone[..., i].astype(int) for i in range(3))
    assert grey.sum() > ((abs(ra - ga) < 12) & (abs(ga - ba) < 12) & (ra < 200) & (ra > 60)).sum() + 200


def test_bad_poses_are_refused(clip):
    with pytest.raises(ValueError, match=r"expected \(24, 3\)"):
        render_skeletons([clip[0, :10]])
    bad = clip[0].copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        render_skeletons([bad])
    with pytest.raises(ValueError, match="no poses"):
        render_skeletons([])


def test_png_bytes_round_trip(clip):
    img = render_skeletons([clip[0]], size=(120, 90))
    back = np.asarray(Image.open(io.BytesIO(png_bytes(img))))
    np.testing.assert_array_equal(back, img)


@pytest.mark.parametrize("far_cm", [600.0, 1000.0])
def test_every_drawing_of_a_plotter_draws_its_poses_wherever_they_stand(clip, far_cm):
    """Poses drawn one after another on the same plotter (a player's frames, a sheet's moments) are each drawn,
    wherever they stand: after a drawing at the origin, the same pose moved a few metres came out blank, and so
    did the origin after it (the plotter's later screenshots did not render the scene again)."""
    pose = clip[0] - clip[0, 0] * np.array([1.0, 0.0, 1.0])
    moved = pose + np.array([far_cm, 0.0, far_cm])
    drawn = [render_skeletons([p, p + 1.0], bounds=scene_bounds(p[None], (p + 1.0)[None]), size=(300, 260),
                              overlay=True) for p in (pose, moved, pose)]  # fmt: skip
    counts = [int(_red(img).sum()) for img in drawn]
    assert min(counts) > 50, counts
    assert abs(counts[2] - counts[0]) <= 0.1 * counts[0], counts  # the origin again as the first time
