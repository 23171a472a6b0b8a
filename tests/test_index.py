"""Inverted-list index: the paper's worked examples (§4, §5) and every query mode against brute force."""
from __future__ import annotations

import numpy as np
import pytest

from mocapviz.features.segmentation import decode, encode, segment
from mocapviz.relational.index import InvertedIndex, merge_adjacent


def vecs(text: str) -> np.ndarray:
    """'11,01' -> [[1, 1], [0, 1]]: one feature vector per comma, feature 1 first."""
    return np.array([[c == "1" for c in word] for word in text.split(",")])


WALK = vecs("11,01,11,10,11,01,11,10,11,01")  # F2[D_walk] of §4, eq. (3)


@pytest.fixture(scope="module")
def walk():
    return InvertedIndex.from_feature_sequence(WALK)


def test_paper_inverted_lists(walk):
    """§5.1: L(11) = {1,3,5,7,9}, L(01) = {2,6,10}, L(10) = {4,8}, L(00) = ∅ (1-based)."""
    lists = {w: walk.inverted_list(encode(vecs(w))[0]) + 1 for w in ("11", "01", "10", "00")}
    assert lists["11"].tolist() == [1, 3, 5, 7, 9]
    assert lists["01"].tolist() == [2, 6, 10]
    assert lists["10"].tolist() == [4, 8]
    assert lists["00"].size == 0
    assert walk.list_codes.size == 3  # lists only for codes that occur


def test_paper_exact_query(walk):
    """Eq. (8): F[Q] = ((10), (11), (01)) hits segments 4 and 8."""
    assert (walk.exact(vecs("10,11,01")) + 1).tolist() == [4, 8]
    assert walk.exact(vecs("10,10")).size == 0


def test_paper_adaptive_fuzzy_query(walk):
    """§5.2: V1 = V3 = {00, 01}, V2 = {10, 11}: adaptive fuzzy hits 2 and 6 with segment indices (2, 3, 6) and
    (6, 7, 10); no plain fuzzy hit."""
    sets = [vecs("00,01"), vecs("10,11"), vecs("00,01")]
    hits = walk.adaptive_fuzzy(sets) + 1
    assert hits[:, :3].tolist() == [[2, 3, 6], [6, 7, 10]]
    assert hits[:, 3].tolist() == [7, 11]  # one past the coarsened last segment
    assert walk.fuzzy(sets).size == 0


def test_adjacent_sets_with_a_common_element_are_merged():
    merged = merge_adjacent([np.array([1, 2]), np.array([2, 3]), np.array([5]), np.array([3, 5])])
    assert [m.tolist() for m in merged] == [[1, 2, 3, 5]]
    assert [m.tolist() for m in merge_adjacent([np.array([1]), np.array([2]), np.array([1])])] == [[1], [2], [1]]


def test_segmentation_runs_and_document_boundaries():
    values = np.array([[1, 0], [1, 0], [0, 1], [0, 1], [0, 1], [1, 1]], bool)
    seq = segment(values, doc_starts=[0, 3])
    assert seq.codes.tolist() == [1, 2, 2, 3] and seq.starts.tolist() == [0, 2, 3, 5]
    assert seq.lengths.tolist() == [2, 1, 2, 1]
    np.testing.assert_array_equal(decode(seq.codes, 2), values[seq.starts])
    # the same query cannot hit across the boundary at frame 3
    idx = InvertedIndex.from_features(values, doc_starts=[0, 3])
    assert idx.exact(np.array([2, 2])).size == 0
    assert idx.exact(np.array([1, 2])).tolist() == [0]


# ---------------------------------------------------------------------- brute force on real data
def bf_exact(codes, doc, q):
    n = len(q)
    return [k for k in range(len(codes) - n + 1) if doc[k] == doc[k + n - 1] and all(codes[k + l] == q[l] for l in range(n))]


def bf_fuzzy(codes, doc, sets):
    n = len(sets)
    return [k for k in range(len(codes) - n + 1)
            if doc[k] == doc[k + n - 1] and all(codes[k + l] in sets[l] for l in range(n))]  # fmt: skip


def bf_adaptive(codes, doc, sets):
    out = []
    m = len(codes)
    for k in range(m):
        if codes[k] not in sets[0] or (k > 0 and doc[k - 1] == doc[k] and codes[k - 1] in sets[0]):
            continue
        row, j = [], k
        for s in sets:
            if j >= m or doc[j] != doc[k] or codes[j] not in s:
                break
            row.append(j)
            while j < m and doc[j] == doc[k] and codes[j] in s:
                j += 1
        else:
            out.append(row + [j])
    return out


def bf_mismatch(codes, doc, q, m, allowed):
    n = len(q)
    hits = []
    for k in range(len(codes) - n + 1):
        if doc[k] != doc[k + n - 1]:
            continue
        bad = [l for l in range(n) if codes[k + l] != q[l]]
        if len(bad) <= m and all(l in allowed for l in bad):
            hits.append(k)
    return hits


@pytest.fixture(scope="module")
def real_index(hdm05_dir, hdm05_labels, tmp_path_factory):
    """The 2005 upper-body index over 40 HDM05 clips (documents kept apart)."""
    import mocapviz
    from mocapviz.features import feature_groups, relational_features

    files = [hdm05_dir / f for f in hdm05_labels["file"].iloc[::7][:40]]
    db = mocapviz.MotionDB.ingest(files, tmp_path_factory.mktemp("idx") / "db", progress=False)
    values, names = relational_features(db, "2005", progress=False)
    cols = [names.index(n) for n in feature_groups("2005")["upper"]]
    return InvertedIndex.from_features(values[:, cols], db.documents["start"].to_numpy())


def test_every_mode_equals_brute_force_on_real_data(real_index):
    idx = real_index
    codes, doc = idx.codes, idx.segment_doc
    rng = np.random.default_rng(7)
    occurring = idx.list_codes
    assert idx.n_segments > 300 and occurring.size > 20
    for trial in range(60):
        n = int(rng.integers(1, 8))
        k = int(rng.integers(0, idx.n_segments - n))
        q = codes[k : k + n].copy()
        if trial % 3 == 0:  # also queries that may have no hit
            q[rng.integers(n)] = rng.choice(occurring)
        assert idx.exact(q).tolist() == bf_exact(codes, doc, q)
        sets = [np.unique(np.append(rng.choice(occurring, int(rng.integers(1, 6))), c)) for c in q]
        merged = [set(s.tolist()) for s in merge_adjacent(sets)]
        assert idx.fuzzy(sets).tolist() == bf_fuzzy(codes, doc, merged)
        assert idx.adaptive_fuzzy(sets).tolist() == bf_adaptive(codes, doc, merged)
        if n > 1:
            m = int(rng.integers(0, n))
            allowed = sorted(rng.choice(n, int(rng.integers(1, n + 1)), replace=False).tolist())
            assert idx.mismatch(q, m).tolist() == bf_mismatch(codes, doc, q, m, range(n))
            assert idx.mismatch(q, m, allowed).tolist() == bf_mismatch(codes, doc, q, m, allowed)


def test_hits_never_span_documents(real_index):
    idx = real_index
    first = idx.doc_first_segment[1:-1]
    # a query made of the last segment of one document and the first of the next
    q = idx.codes[[first[0] - 1, first[0]]]
    for hit in idx.exact(q):
        assert idx.segment_doc[hit] == idx.segment_doc[hit + 1]


def test_exact_query_with_a_repeated_vector_has_no_hit(real_index):
    # adjacent segments always differ, so (v, v) never occurs, although the fuzzy query {v}, {v} is merged to {v}
    v = real_index.codes[0]
    assert real_index.exact([v, v]).size == 0
    assert real_index.fuzzy([[v], [v]]).size == real_index.inverted_list(v).size


def test_save_load_round_trip(real_index, tmp_path):
    real_index.save(tmp_path / "i.npz")
    back = InvertedIndex.load(tmp_path / "i.npz")
    for name in ("codes", "starts", "lengths", "doc_first_segment", "list_codes", "list_offsets", "positions"):
        np.testing.assert_array_equal(getattr(back, name), getattr(real_index, name))
    assert back.feature_names == real_index.feature_names
    assert not list(tmp_path.glob("*.tmp"))


def test_bad_queries_have_clear_errors(walk):
    with pytest.raises(ValueError, match="empty query"):
        walk.exact(np.empty(0, dtype=np.int64))
    with pytest.raises(ValueError, match="3 features, the index 2"):
        walk.exact(np.ones((1, 3), bool))
    with pytest.raises(ValueError, match="0 <= m < 3"):
        walk.mismatch(vecs("10,11,01"), 3)
    with pytest.raises(ValueError, match="fuzzy set is empty"):
        walk.fuzzy([np.empty(0, np.int64)])


@pytest.mark.parametrize("f", [1, 12, 31, 62])
def test_encode_is_the_weighted_bit_sum_and_decode_inverts_it(f):
    values = np.random.default_rng(f).random((500, f)) < 0.5
    codes = encode(values)
    assert codes.tolist() == [sum(1 << k for k in range(f) if row[k]) for row in values]
    assert (decode(codes, f) == values).all()


def test_frame_spans_recover_the_frames_of_adaptive_hits():
    """The walk of §4 at frame level (segment l lasting l + 1 frames): the adaptive hits (2, 3, 6) and (6, 7, 10)
    cover frames [sum of the lengths before segment 2, the end of segment 6) and likewise for the second."""
    lengths = np.arange(1, len(WALK) + 1)
    index = InvertedIndex.from_features(np.repeat(WALK, lengths, axis=0))
    assert index.starts.tolist() == np.concatenate([[0], np.cumsum(lengths)[:-1]]).tolist()
    hits = index.adaptive_fuzzy([vecs("00,01"), vecs("10,11"), vecs("00,01")])
    start, stop = index.frame_spans(hits[:, 0], hits[:, -1])
    ends = np.cumsum(lengths)
    assert start.tolist() == [ends[0], ends[4]]  # segments 2 and 6 (1-based) start after segments 1 and 5
    assert stop.tolist() == [ends[5], ends[9]]  # ... and the hits end with segments 6 and 10


def test_load_or_build_saves_only_when_asked(sample_db, tmp_path):
    import shutil

    from mocapviz import MotionDB
    from mocapviz.relational.index import build, load, load_or_build

    shutil.copytree(sample_db.path, tmp_path / "db")
    db = MotionDB.open(tmp_path / "db")
    shutil.rmtree(db.path / "index", ignore_errors=True)
    in_memory = load_or_build(db, save=False)
    assert not (db.path / "index").exists()  # nothing written: a read-only database can be queried
    saved = load_or_build(db)
    assert (db.path / "index").is_dir()
    for got in (load(db), load_or_build(db, save=False)):
        for group, idx in build(db, save=False, progress=False).items():
            np.testing.assert_array_equal(got[group].codes, idx.codes)
            np.testing.assert_array_equal(in_memory[group].codes, idx.codes)
            np.testing.assert_array_equal(saved[group].starts, idx.starts)


def test_the_union_of_inverted_lists_is_the_sorted_union_both_ways(real_index):
    """_gather merges few lists by a run-finding sort and many through a mask of the segments: either way the sorted
    union of the lists' positions (checked against np.union1d on the real index, small and large unions)."""
    idx = real_index
    sizes = np.diff(idx.list_offsets)
    for lists in (np.argsort(sizes)[:3], np.argsort(sizes)[-40:], np.arange(0, len(sizes), 2)):
        expected = np.sort(np.concatenate([idx.positions[idx.list_offsets[k]:idx.list_offsets[k + 1]] for k in lists]))
        got = idx._gather(lists)
        np.testing.assert_array_equal(got, expected)
        assert got.dtype == np.int64
    assert {np.sort(sizes)[:3].sum() * 16 < idx.n_segments, sizes[::2].sum() * 16 < idx.n_segments} == {True, False}
