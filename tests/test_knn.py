"""mocapviz.similarity.knn on real motion: kd-tree searches against brute force, fat-graph base poses against the O(n^2)
reference (Krüger et al. 2010 §3.3, §4.1, §5.3).

Features: body-frame positions of the end effectors (lwrist, rwrist, lankle, rankle, head: F15E, cm) of every
HDM05 and CMU clip of the shared data at 30 Hz (about 29.7k frames). Queries that are not database frames come
from left/right mirrored copies of real clips.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from mocapviz import MotionDB, ParameterError
from mocapviz.motion.skeleton import CANONICAL_JOINTS, body_frame, mirror
from mocapviz.similarity.knn import KnnIndex, base_poses, base_poses_quadratic, frames_mask

END_EFFECTORS = [CANONICAL_JOINTS.index(j) for j in ("lwrist", "rwrist", "lankle", "rankle", "head")]


def f15e(positions: np.ndarray) -> np.ndarray:
    """(T, 24, 3) canonical joints, cm -> (T, 15) float32 body-frame end-effector positions, cm."""
    return body_frame(positions)[:, END_EFFECTORS].reshape(len(positions), 15)


@pytest.fixture(scope="module")
def db(hdm05_dir, cmu_dir, tmp_path_factory):
    return MotionDB.ingest([hdm05_dir, cmu_dir], tmp_path_factory.mktemp("knn") / "db", fps=30, progress=False,
                           threads=2)  # fmt: skip


@pytest.fixture(scope="module")
def features(db) -> np.ndarray:
    return f15e(np.asarray(db.positions))


@pytest.fixture(scope="module")
def queries(db, features) -> np.ndarray:
    """300 real poses: 200 database frames and 100 frames of mirrored clips (not in the database)."""
    rng = np.random.default_rng(5)
    own = features[rng.choice(len(features), 200, replace=False)]
    docs = db.documents["doc_id"].to_numpy()[:: len(db.documents) // 6]
    mirrored = np.concatenate([f15e(mirror(db.motion(int(d))).positions) for d in docs])
    return np.concatenate([own, mirrored[rng.choice(len(mirrored), 100, replace=False)]])


@pytest.fixture(scope="module", params=["kdtree", "ckdtree"])
def tree(features, request) -> KnnIndex:
    """Each kd-tree engine: mocapviz's own (the default) and scipy's."""
    return KnnIndex(features, engine=request.param)


@pytest.fixture(scope="module")
def brute(features) -> KnnIndex:
    return KnnIndex(features, engine="brute")


@pytest.fixture(scope="module")
def ranked(features, queries):
    """All database frames ranked for each query by (distance, frame number), from the full distance matrix:
    distances (q, N) float64 and frame numbers (q, N). Written independently of mocapviz.similarity.knn."""
    d = cdist(np.asarray(queries, np.float64), np.asarray(features, np.float64))
    order = np.argsort(d, axis=1, kind="stable")
    return np.take_along_axis(d, order, axis=1), order


def reference(ranked, k: int, radius: float | None = None, valid: np.ndarray | None = None):
    """The k nearest (valid) frames of each query, at distance < radius if given; -1 / inf padded."""
    dist, order = ranked
    if valid is not None:
        first = np.argsort(~valid[order], axis=1, kind="stable")[:, :k]  # the valid ones, in rank order
        dist, order = np.take_along_axis(dist, first, axis=1), np.take_along_axis(order, first, axis=1)
    dist, order = dist[:, :k].copy(), order[:, :k].copy()
    if radius is not None:
        far = ~(dist < radius)
        dist[far], order[far] = np.inf, -1
    return dist, order


def assert_same_neighbours(data, x, d, i, d_ref, i_ref):
    """Distances equal to 1e-5; indices identical except among frames tied exactly at the same distance, where
    any of the tied frames is right (checked by recomputing distances)."""
    np.testing.assert_allclose(d, d_ref, rtol=0, atol=1e-5)
    assert i.dtype == np.int64
    rows, cols = np.nonzero(i != i_ref)
    for r, c in zip(rows, cols):
        assert i[r, c] >= 0 and i_ref[r, c] >= 0, (r, c)
        to_all = np.linalg.norm(np.asarray(data, np.float64) - x[r], axis=1)
        assert to_all[i[r, c]] == pytest.approx(d_ref[r, c], abs=1e-9), (r, c)
        assert (np.abs(to_all - d_ref[r, c]) < 1e-9).sum() >= 2, (r, c)  # an exact tie in the database
    for row in i:
        found = row[row >= 0]
        assert len(np.unique(found)) == len(found)


# ============================================================================ k nearest neighbours
@pytest.mark.parametrize("k", [1, 16, 256])
def test_exact_kdtree_equals_brute_force(tree, brute, features, queries, ranked, k):
    d_ref, i_ref = reference(ranked, k)
    for index in (tree, brute):
        d, i = index.query(queries, k)
        assert d.shape == i.shape == (len(queries), k)
        assert_same_neighbours(features, queries, d, i, d_ref, i_ref)
    assert (tree.query(queries[:200], 1)[0][:, 0] == 0).all()  # database frames find themselves


def test_single_query_and_small_batches_match_the_batch(tree, brute, queries):
    d, i = tree.query(queries, 16)
    d1, i1 = tree.query(queries[7], 16)
    assert d1.shape == i1.shape == (16,)
    np.testing.assert_array_equal(i1, i[7])
    d_small, i_small = tree.query(queries[:10], 16, threads=1)  # fewer queries than the leaf-order threshold
    np.testing.assert_array_equal(i_small, i[:10])
    np.testing.assert_array_equal(d_small, d[:10])
    for index in (tree, brute):
        assert index.query(queries[:0], 4)[1].shape == (0, 4)


@pytest.mark.parametrize("eps", [0.5, 2.0])
def test_approximate_search_meets_the_bound(tree, features, queries, ranked, eps):
    k = 16
    d_exact, _ = reference(ranked, k)
    d, i = tree.query(queries, k, eps=eps)
    assert (d[:, -1] <= (1 + eps) * d_exact[:, -1] + 1e-9).all()
    assert (d >= d_exact - 1e-9).all()  # nothing closer than the true i-th neighbour
    recomputed = np.linalg.norm(features[i].astype(np.float64) - queries[:, None, :], axis=-1)
    np.testing.assert_allclose(d, recomputed, atol=1e-5)
    assert (np.diff(d, axis=1) >= 0).all()


@pytest.mark.parametrize("k", [8, 64])
def test_radius_with_cap_returns_the_brute_force_neighbours_within_r(tree, brute, features, queries, ranked, k):
    radius = float(np.median(ranked[0][:, 8]))  # about half the rows are capped at k=8
    d_ref, i_ref = reference(ranked, k, radius)
    assert 0 < (i_ref < 0).mean() < 1
    for index in (tree, brute):
        d, i = index.query(queries, k, radius=radius)
        assert_same_neighbours(features, queries, d, i, d_ref, i_ref)
        missing = i < 0
        assert np.isinf(d[missing]).all() and (d[~missing] < radius).all()
        assert (np.diff(missing.astype(int), axis=1) >= 0).all()  # padding only at the end


def test_valid_mask_never_returns_excluded_frames(db, features, queries, ranked):
    docs = db.documents
    drop_docs = docs[(docs["actor"] == "bd") | (docs.index % 3 == 0)]
    bounds = np.stack([drop_docs["start"], drop_docs["start"] + drop_docs["n_frames"]], axis=1)
    excluded = frames_mask(bounds, len(features))
    valid = ~excluded
    kept = np.flatnonzero(valid)
    index = KnnIndex(features, valid=valid)
    assert index.n_indexed == len(kept)
    for k, radius in ((16, None), (256, None), (32, 10.0)):
        d, i = index.query(queries, k, radius=radius)
        assert not excluded[i[i >= 0]].any()
        d_ref, i_ref = reference(ranked, k, radius, valid=valid)
        assert_same_neighbours(features, queries, d, i, d_ref, i_ref)
        d_b, i_b = KnnIndex(features, "brute", valid=valid).query(queries, k, radius=radius)
        assert_same_neighbours(features, queries, d_b, i_b, d_ref, i_ref)
    # exclude(): the same index from the full one, by document ranges or by mask
    for drop in (bounds, excluded):
        view = KnnIndex(features).exclude(drop)
        np.testing.assert_array_equal(view.frames, kept)
        np.testing.assert_array_equal(view.query(queries, 16)[1], index.query(queries, 16)[1])


def test_a_large_copy_is_a_memory_mapped_file_with_the_same_answers(tree, features, queries, ranked, monkeypatch,
                                                                    tmp_path):
    """Above SPILL_BYTES the kd-tree's float64 copy lives in an unlinked temporary file of the cache folder, mapped
    (file-backed pages, not anonymous memory): the same neighbours, all frames or a valid subset; nothing left."""
    from mocapviz.similarity import knn

    monkeypatch.setattr(knn, "SPILL_BYTES", 0)
    monkeypatch.setattr(knn, "_COPY_ROWS", 1000)  # several blocks
    monkeypatch.setenv("MOCAPVIZ_HOME", str(tmp_path))
    spilled = KnnIndex(features, engine="ckdtree")
    assert isinstance(spilled._structure[0].data.base, np.memmap)  # the tree searches the mapped file, no copy
    for k in (1, 16):
        np.testing.assert_array_equal(spilled.query(queries, k)[1], tree.query(queries, k)[1])
    valid = np.arange(len(features)) % 3 != 0
    d, i = KnnIndex(features, valid=valid).query(queries, 16)
    assert not (i % 3 == 0).any()
    assert_same_neighbours(features, queries, d, i, *reference(ranked, 16, None, valid=valid))
    assert list(tmp_path.iterdir()) == []  # unlinked at once


def test_nbytes_and_build_time(tree, brute, features):
    n = len(features)
    assert tree.n_frames == tree.n_indexed == n and tree.dim == 15
    point_bytes = 4 if tree.engine == "kdtree" else 8  # "kdtree" keeps float32 features as float32
    assert tree.nbytes > n * 15 * point_bytes + n * 8 and brute.nbytes >= n * 15 * 8
    assert tree.build_seconds > 0
    assert tree.engine in repr(tree)


# ============================================================================ fat-graph base poses
@pytest.fixture(scope="module")
def subset(features) -> np.ndarray:
    """Every 10th frame: about 3,000 poses of all clips."""
    return features[::10]


@pytest.mark.parametrize(("radius", "k"), [(6.0, 16), (12.0, 16), (12.0, 200), (25.0, 64)])
def test_base_poses_equal_the_quadratic_reference(subset, radius, k):
    base, cluster = base_poses(subset, radius, k=k)
    base_q, cluster_q = base_poses_quadratic(subset, radius, k=k)
    np.testing.assert_array_equal(base, base_q)
    np.testing.assert_array_equal(cluster, cluster_q)
    assert base.dtype == cluster.dtype == np.int64
    assert 1 < len(base) < len(subset)
    # every frame in exactly one cluster, its base's; bases are their own base; each frame within r of it
    assert (cluster >= 0).all()
    assert np.array_equal(np.unique(cluster), np.sort(base))
    assert (cluster[base] == base).all()
    assert (np.linalg.norm(subset - subset[cluster], axis=1) < radius).all()
    # the first base pose has the most neighbours of all frames (before any was taken)
    counts = np.minimum((cdist(subset, subset) < radius).sum(axis=1) - 1, k)
    assert counts[base[0]] == counts.max() and base[0] == np.argmax(counts)


def test_base_poses_of_valid_frames_only(subset):
    valid = np.zeros(len(subset), dtype=bool)
    valid[: len(subset) // 2] = True
    base, cluster = base_poses(subset, 12.0, k=32, valid=valid)
    base_q, cluster_q = base_poses_quadratic(subset, 12.0, k=32, valid=valid)
    np.testing.assert_array_equal(base, base_q)
    np.testing.assert_array_equal(cluster, cluster_q)
    assert (cluster[~valid] == -1).all() and (cluster[valid] >= 0).all() and valid[base].all()


def test_base_poses_of_far_apart_frames_are_singletons(features):
    base, cluster = base_poses(features[:2000:200], 1e-3, k=4)
    np.testing.assert_array_equal(np.sort(base), np.arange(10))
    np.testing.assert_array_equal(cluster, np.arange(10))
    for fn in (base_poses, base_poses_quadratic):  # one frame: its own base pose
        np.testing.assert_array_equal(np.concatenate(fn(features[:1], 5.0)), [0, 0])


def test_workers_is_threads_with_a_warning(tree, queries):
    d, i = tree.query(queries, 8, threads=2)
    with pytest.warns(FutureWarning, match="workers= is deprecated; pass threads="):
        d_old, i_old = tree.query(queries, 8, workers=1)
    np.testing.assert_array_equal(i_old, i)
    np.testing.assert_array_equal(d_old, d)
    with pytest.raises(ParameterError, match="pass threads= only"):
        tree.query(queries, 8, workers=1, threads=1)


def test_knn_timings_workers_is_threads_with_a_warning(sample_db):
    from mocapviz.experiments import knn_timings

    with pytest.warns(FutureWarning, match="workers= is deprecated; pass threads="):
        table = knn_timings(sample_db, numeric_sets=["F15E"], ks=(4,), n_queries=20, workers=1, repeats=1)
    assert table[["set", "k", "queries"]].values.tolist() == [["F15E", 4, 20]]


# ============================================================================ errors
def test_bad_input_raises_clear_errors(features, tree):
    q = features[:5].copy()
    q[3, 2] = np.nan
    cases = [
        (lambda: KnnIndex(features, engine="annoy"), "unknown engine 'annoy'"),
        (lambda: KnnIndex(features[0]), "2-D array"),
        (lambda: KnnIndex(np.where(np.arange(len(features))[:, None] == 42, np.nan, features)), "frame 42"),
        (lambda: KnnIndex(features, valid=np.ones(3, bool)), "valid must be a bool mask"),
        (lambda: KnnIndex(features, valid=np.zeros(len(features), bool)), "selects no frame"),
        (lambda: KnnIndex(features, leafsize=0), "leafsize"),
        (lambda: tree.query(q, 4), "query row 3"),
        (lambda: tree.query(features[:5, :14], 4), r"shape \(15,\) or \(q, 15\)"),
        (lambda: tree.query(features[:5], 0), "k must be between 1"),
        (lambda: tree.query(features[:5], len(features) + 1), "k must be between 1"),
        (lambda: tree.query(features[:5], 4, radius=0), "radius must be a positive"),
        (lambda: tree.query(features[:5], 4, eps=-1), "eps must be"),
        (lambda: tree.query(features[:5], 4, threads=0), "threads"),
        (lambda: tree.exclude(np.array([[5, 2]])), "start <= stop"),
        (lambda: tree.exclude(np.ones(4, bool)), "frame mask must have shape"),
        (lambda: base_poses(features[:100], -1.0), "radius must be a positive"),
        (lambda: base_poses(features[:100], 5.0, k=0), "k must be a positive integer"),
        (lambda: base_poses_quadratic(features[:100], None), "radius must be a positive"),
        (lambda: base_poses_quadratic(features[:100], 5.0, k=-2), "k must be a positive integer"),
    ]
    for call, message in cases:
        with pytest.raises(ValueError, match=message):
            call()
    with pytest.raises(ParameterError, match="k must be an integer"):
        tree.query(features[:5], 2.5)
    k_small = KnnIndex(features, valid=np.arange(len(features)) < 10)
    with pytest.raises(ValueError, match=r"number of indexed frames \(10\)"):
        k_small.query(features[:2], 11)


def test_describe_frames_names_documents_and_frames(db):
    from mocapviz.similarity.knn import describe_frames

    docs = db.documents
    picks = np.array([0, int(docs["start"].iloc[5]) + 3, -1, db.n_frames - 1])
    table = describe_frames(db, picks, distances=np.array([0.0, 1.5, np.inf, 2.0]))
    assert table["rank"].tolist() == [1, 2, 3]  # the missing neighbour (-1) left out
    assert table["doc_id"].tolist() == [docs["doc_id"].iloc[0], docs["doc_id"].iloc[5], docs["doc_id"].iloc[-1]]
    assert table["start"].tolist() == [0, 3, int(docs["n_frames"].iloc[-1]) - 1]  # one-frame hits
    assert (table["end"] == table["start"] + 1).all() and (table["frames"] == 1).all()
    np.testing.assert_allclose(table["start_s"], table["start"] / docs["fps"].iloc[[0, 5, -1]].to_numpy())
    assert table["label"].tolist() == docs["label"].iloc[[0, 5, -1]].tolist()
    assert table["distance"].tolist() == [0.0, 1.5, 2.0]
    with pytest.raises(ValueError, match="beyond the database"):
        describe_frames(db, [db.n_frames])


def test_per_query_exclusion_equals_an_index_without_those_frames(db, tree, features, queries, ranked):
    """Each query leaves out its own [start, stop) range (here: a real document, different per query): the
    answer equals the brute-force ranking restricted to the frames outside that range."""
    docs = db.documents
    rng = np.random.default_rng(11)
    picks = rng.integers(0, len(docs), len(queries))
    ranges = np.stack([docs["start"].to_numpy()[picks], (docs["start"] + docs["n_frames"]).to_numpy()[picks]], 1)
    for k, radius in ((16, None), (40, 30.0)):
        d, i = tree.query(queries, k, radius=radius, exclude=ranges)
        for r in range(len(queries)):
            valid = np.ones(len(features), bool)
            valid[ranges[r, 0] : ranges[r, 1]] = False
            d_ref, i_ref = reference((ranked[0][r : r + 1], ranked[1][r : r + 1]), k, radius, valid)
            assert_same_neighbours(features, queries[r : r + 1], d[r : r + 1], i[r : r + 1], d_ref, i_ref)
    _, single_i = tree.query(queries[0], 16, exclude=ranges[0])
    np.testing.assert_array_equal(single_i, tree.query(queries[:1], 16, exclude=ranges[:1])[1][0])
    with pytest.raises(ValueError, match="one \\[start, stop\\) frame range per query"):
        tree.query(queries[:3], 4, exclude=ranges[:2])


@pytest.mark.parametrize("engine", ["kdtree", "ckdtree"])
def test_single_queries_are_the_rows_of_the_batch_on_every_path(features, queries, engine):
    """A single query (its own short path: no leaf ordering, one thread, no frame mapping when every frame is
    indexed) returns exactly the batch's row, distances to the bit, with or without a valid mask."""
    valid = np.ones(len(features), dtype=bool)
    valid[::3] = False
    for index in (KnnIndex(features, engine), KnnIndex(features, engine, valid=valid)):
        for k in (1, 16):
            d, i = index.query(queries, k)  # >= 64 queries: searched in the tree's leaf order
            for r in (0, 7, 250):
                for threads in (None, 1, 2):
                    d1, i1 = index.query(queries[r], k, threads=threads)
                    np.testing.assert_array_equal(i1, i[r])
                    np.testing.assert_array_equal(d1, d[r])
                    d2, i2 = index.query(queries[r : r + 1], k, threads=threads)
                    assert d2.shape == i2.shape == (1, k)
                    np.testing.assert_array_equal(i2[0], i[r])
            own = [0, 50]
            np.testing.assert_array_equal(index.query(queries[3], k, exclude=own)[1],
                                          index.query(queries[3:4], k, exclude=[own])[1][0])  # fmt: skip
            assert index.valid[index.query(queries[3], k)[1]].all()


def test_one_row_per_document_is_each_documents_nearest_neighbour(sample_db):
    """``per_document=True``: the k nearest frames of a real pose (a kick of the sample, its own document left
    in) fill their top rows with consecutive frames of a few takes; one row per document keeps each document's
    nearest, in distance order: the brute-force best row per document of the full answer."""
    from mocapviz.features import numeric_features
    from mocapviz.similarity.knn import describe_frames

    x = numeric_features(sample_db, "F15E")
    query = x[sample_db.frames(7).start + 40]
    dist, near = KnnIndex(x).query(query, 300)
    full = describe_frames(sample_db, near, dist)
    assert full["doc_id"].head(10).nunique() < 10  # consecutive frames of few documents on top
    each = describe_frames(sample_db, near, dist, per_document=True)
    assert each["doc_id"].is_unique and each["rank"].tolist() == list(range(1, len(each) + 1))
    d_all = np.linalg.norm(x.astype(np.float64) - query, axis=1)  # brute force: every frame's distance
    best = (full.assign(d=d_all[near]).sort_values(["d", "doc_id", "start"]).groupby("doc_id", sort=False).head(1))
    assert each["doc_id"].tolist() == best["doc_id"].tolist()
    assert each["start"].tolist() == best["start"].tolist()
    np.testing.assert_allclose(each["distance"], best["d"], rtol=1e-5)
    assert set(each["doc_id"]) == set(full["doc_id"])
