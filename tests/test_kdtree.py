"""mocapviz.similarity.kdtree (the "kdtree" engine of KnnIndex) against brute force: random point sets drawn by
hypothesis (duplicates and exact ties included, float32 and float64 values, any leaf size), and the real F15E
frames of the sample database. The reference is the full distance matrix, ranked by (distance, frame).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz.similarity.kdtree import build_kdtree, query_kdtree
from mocapviz.similarity.knn import KnnIndex


def ranked_reference(data: np.ndarray, x: np.ndarray, k: int, radius: float | None):
    """The k least (distance, frame) of each query from the full distance matrix, squared differences summed in
    coordinate order in float64 (as both engines do, so that exact ties are the same ties); -1 / inf beyond the
    radius."""
    x, data = np.asarray(x, np.float64), np.asarray(data, np.float64)
    d2 = np.zeros((len(x), len(data)))
    for j in range(x.shape[1]):
        d2 += (x[:, j, None] - data[None, :, j]) ** 2
    d = np.sqrt(d2)
    order = np.lexsort((np.broadcast_to(np.arange(len(data)), d.shape), d), axis=1)[:, :k]
    dist = np.take_along_axis(d, order, axis=1)
    if radius is not None:
        far = ~(dist < radius)
        dist, order = np.where(far, np.inf, dist), np.where(far, -1, order)
    return dist, order


@st.composite
def point_sets(draw):
    """(data (n, d), queries (q, d), k, radius or None, leafsize): coordinates on a coarse grid, so that many
    points coincide and many distances tie; queries are data rows or new points; float32 or float64 values."""
    n = draw(st.integers(1, 300))
    d = draw(st.integers(1, 6))
    seed = draw(st.integers(0, 2**32 - 1))
    grid = draw(st.sampled_from([1.0, 0.5, 0.1]))
    rng = np.random.default_rng(seed)
    data = np.round(rng.normal(size=(n, d)) * 3 / grid) * grid
    if draw(st.booleans()):
        data = data + rng.normal(size=(n, d)) * 1e-3  # float64 values no float32 holds
    else:
        data = data.astype(np.float32)
    q = draw(st.integers(0, 80))
    own = data[rng.integers(0, n, q)].astype(np.float64)
    new = np.round(rng.normal(size=(q, d)) * 3 / grid) * grid
    x = np.where(rng.random((q, 1)) < 0.5, own, new)
    k = draw(st.integers(1, n))
    radius = draw(st.one_of(st.none(), st.floats(0.05, 10.0)))
    return data, x, k, radius, draw(st.sampled_from([1, 2, 5, 64]))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(point_sets(), st.sampled_from([1, 2]))
def test_kdtree_engine_equals_brute_force(case, threads):
    """KnnIndex(engine="kdtree") returns exactly brute force's k least (distance, frame), ties by lowest frame;
    the tree's own search returns the same distances (its ties in any order)."""
    data, x, k, radius, leafsize = case
    d_ref, i_ref = ranked_reference(data, x, k, radius)
    d, i = KnnIndex(data, engine="kdtree", leafsize=leafsize).query(x, k, radius=radius, threads=threads)
    np.testing.assert_array_equal(i, i_ref)
    np.testing.assert_allclose(d, d_ref, rtol=1e-12, atol=1e-12)
    tree = build_kdtree(np.asarray(data, np.float64), leafsize)
    d_t, i_t = query_kdtree(tree, x, k, radius, 0.0, threads)
    np.testing.assert_allclose(d_t, d_ref, rtol=1e-12, atol=1e-12)
    found = i_t >= 0
    assert (found == (i_ref >= 0)).all()
    recomputed = np.linalg.norm(np.asarray(data, np.float64)[i_t[found]] - np.repeat(x, k, axis=0)[found.ravel()],
                                axis=1)  # fmt: skip
    np.testing.assert_allclose(recomputed, d_t[found], rtol=1e-12, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(point_sets(), st.sampled_from([0.5, 2.0]))
def test_approximate_search_stays_within_its_bound(case, eps):
    """eps > 0: every returned distance is real, and the i-th is between the true i-th and (1 + eps) times it."""
    data, x, k, _, leafsize = case
    d_ref, _ = ranked_reference(data, x, k, None)
    d, i = query_kdtree(build_kdtree(np.asarray(data, np.float64), leafsize), x, k, None, eps, 1)
    assert (d >= d_ref - 1e-12).all() and (d <= (1 + eps) * d_ref + 1e-12).all()
    np.testing.assert_allclose(np.linalg.norm(np.asarray(data, np.float64)[i] - x[:, None], axis=-1), d, atol=1e-12)


def test_tree_leaves_cover_the_points_once_within_their_boxes():
    """Every point is in exactly one leaf of at most leafsize points (equal points aside), inside its box."""
    rng = np.random.default_rng(1)
    data = np.concatenate([rng.normal(size=(5000, 15)), np.zeros((300, 15))])  # 300 equal points
    tree = build_kdtree(data, 16)
    leaves = np.flatnonzero(tree.left < 0)
    sizes = tree.stop[leaves] - tree.start[leaves]
    assert sizes.sum() == len(data) and np.array_equal(np.sort(tree.perm), np.arange(len(data)))
    assert (sizes[sizes > 16] == 300).all()  # only the leaf of the equal points is larger
    np.testing.assert_array_equal(tree.points, data[tree.perm])
    for leaf in leaves:
        rows = tree.points[tree.start[leaf] : tree.stop[leaf]]
        assert (rows >= tree.lo[leaf]).all() and (rows <= tree.hi[leaf]).all()


def test_real_f15e_frames_of_the_sample_equal_brute_force(sample_db):
    """The sample's F15E (5,543 frames at 120 Hz, float32 cm): the kdtree engine's 1, 16 and 256 nearest of
    every 7th frame and of frames moved by a few cm, and within a radius, are brute force's, ties by frame."""
    from mocapviz.features import numeric_features

    x = numeric_features(sample_db, "F15E")
    rng = np.random.default_rng(3)
    queries = np.concatenate([x[::7], x[::50] + rng.normal(scale=3.0, size=x[::50].shape)]).astype(np.float64)
    ours, brute = KnnIndex(x), KnnIndex(x, engine="brute")
    assert ours.engine == "kdtree" and ours._structure.points.dtype == np.float32
    for k, radius in ((1, None), (16, None), (256, None), (64, 15.0)):
        d, i = ours.query(queries, k, radius=radius)
        d_ref, i_ref = ranked_reference(x, queries, k, radius)
        np.testing.assert_array_equal(i, i_ref)
        np.testing.assert_allclose(d, d_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(brute.query(queries, k, radius=radius)[0], d_ref, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("k", [16, 256])
def test_excluding_a_document_equals_brute_force(sample_db, k):
    """LNG's search (own document left out): the same distances and frames as brute force's, sample F15E."""
    from mocapviz.features import numeric_features

    x = numeric_features(sample_db, "F15E")
    own = sample_db.frames(7)
    q = x[own.start : own.stop : 5]
    ranges = np.tile([own.start, own.stop], (len(q), 1))
    d, i = KnnIndex(x).query(q, k, exclude=ranges)
    d_b, i_b = KnnIndex(x, engine="brute").query(q, k, exclude=ranges)
    np.testing.assert_allclose(d, d_b, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(i, i_b)  # no pose of this sample is tied exactly with another at the k-th
    assert not ((i >= own.start) & (i < own.stop)).any()
