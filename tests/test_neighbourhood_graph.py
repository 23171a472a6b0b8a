"""The lazy neighbourhood graph's search step on whole clips with their own document excluded (issue 43): the
neighbourhoods searched a block of query frames at a time, stopping where no path goes on
(:func:`mocapviz.match.neighbourhood_graph.reached_neighbourhoods`, ``lng``'s default), and ``KnnIndex.query``'s
exclusion asking for a few neighbours beyond k, give the answers of the paper's order on an index that never held
the own document (:meth:`KnnIndex.exclude`: another kd-tree, built without those frames).

Data: the embedded demo at 30 Hz (:meth:`MotionDB.demo`: 44 HDM05 clips, 8 CMU trials, 2 C3D takes; 7,187 frames).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import MotionDB
from mocapviz.errors import ParameterError
from mocapviz.features.numeric import numeric_features
from mocapviz.match import lng
from mocapviz.match.neighbourhood_graph import reached_neighbourhoods
from mocapviz.similarity.knn import KnnIndex
from mocapviz.similarity.motion_matching import graph_k


@pytest.fixture(scope="module")
def demo():
    db = MotionDB.demo()
    X = numeric_features(db, "F15E")
    return db, X, db.documents["start"].to_numpy(), KnnIndex(X)


def _without_own(index: KnnIndex, own: tuple[int, int]) -> KnnIndex:
    return index.exclude(np.array([own]))


def assert_same_matches(found, reference):
    """Same documents, frames, costs (to the bit: the same distances of the same kd-tree code) and paths."""
    assert found[["doc_id", "start", "end"]].to_numpy().tolist() == reference[["doc_id", "start", "end"]].to_numpy().tolist()
    np.testing.assert_array_equal(found["cost"].to_numpy(), reference["cost"].to_numpy())
    for a, b in zip(found["path"], reference["path"]):
        np.testing.assert_array_equal(a, b)


def test_whole_clips_give_the_matches_of_the_full_search(demo):
    """Every clip of the demo of at least 10 s (300 frames at 30 Hz), whole, own document excluded, with the
    default k of the database: the matches of every query frame's neighbourhood searched first on an index without
    the own document (none of these 8 clips has a match: each search ends early)."""
    db, X, starts, index = demo
    k = graph_k(db.n_frames, db.fps)
    docs = db.documents[db.documents["n_frames"] >= 300]
    assert len(docs) >= 5
    early = 0
    for s, n in zip(docs["start"], docs["n_frames"]):
        own = (int(s), int(s + n))
        found = lng(X[own[0] : own[1]], index, k=k, starts=starts, n_matches=10, exclude=own)
        reference = lng(X[own[0] : own[1]], _without_own(index, own), k=k, starts=starts, n_matches=10, early_stop=False)
        assert_same_matches(found, reference)
        early += found.attrs["searched"] < n
    assert early >= 3, "no clip ended the search early: nothing tested"


def test_short_stretches_with_matches_are_the_same(demo):
    """2 s of each HDM05 clip (4 takes of every class: matches exist), own document excluded, k = 256: the graph's
    matches reached through every query frame, the same as the full search's."""
    db, X, starts, index = demo
    hdm05 = db.documents[db.documents["name"].str.startswith("HDM")]
    matched = 0
    for s, n in zip(hdm05["start"], hdm05["n_frames"]):
        own, stop = (int(s), int(s + n)), int(s + min(n, 60))
        found = lng(X[s:stop], index, k=256, starts=starts, n_matches=5, exclude=own)
        assert_same_matches(found, lng(X[s:stop], _without_own(index, own), k=256, starts=starts, n_matches=5,
                                       early_stop=False))  # fmt: skip
        matched += len(found) > 0
    assert matched >= 20


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(doc=st.integers(0, 53), first=st.floats(0, 1), length=st.integers(2, 400), k=st.integers(1, 600),
       n_matches=st.integers(1, 20), radius=st.one_of(st.none(), st.floats(20.0, 200.0)),
       min_length=st.sampled_from([None, 0.5, 1.0]))  # fmt: skip
def test_random_stretches_give_the_matches_of_the_full_search(demo, doc, first, length, k, n_matches, radius,
                                                              min_length):  # fmt: skip
    """Random stretches of random clips, k, K, radius and shortest match: the same matches either way."""
    db, X, starts, index = demo
    s, n = int(starts[doc]), int(db.documents["n_frames"].iloc[doc])
    length = min(length, n)
    a = s + int(first * (n - length))
    own = (s, s + n)
    found = lng(X[a : a + length], index, k=k, radius=radius, starts=starts, n_matches=n_matches, exclude=own,
                min_length=min_length)  # fmt: skip
    reference = lng(X[a : a + length], _without_own(index, own), k=k, radius=radius, starts=starts,
                    n_matches=n_matches, min_length=min_length, early_stop=False)  # fmt: skip
    assert_same_matches(found, reference)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(doc=st.integers(0, 53), k=st.integers(1, 300), rows=st.integers(1, 40))
def test_excluding_the_own_document_equals_an_index_without_it(demo, doc, k, rows):
    """Query frames of a clip, its own document excluded (most of their nearest frames are their own clip's: the
    search asks again for more): the neighbours of an index without the document, distances to the bit."""
    db, X, starts, index = demo
    s, n = int(starts[doc]), int(db.documents["n_frames"].iloc[doc])
    q = X[s : s + min(rows, n)]
    d, i = index.query(q, k, exclude=np.tile([s, s + n], (len(q), 1)))
    d_ref, i_ref = _without_own(index, (s, s + n)).query(q, k)
    np.testing.assert_array_equal(i, i_ref)
    np.testing.assert_array_equal(d, d_ref)


def test_the_search_stops_after_the_first_block_no_path_goes_through(demo):
    """A query of two clips of different documents joined: no path crosses from one to the other, so the search
    stops in the block holding the junction; its rows up to there are those of the full search."""
    _, X, starts, index = demo
    q = np.concatenate([X[starts[3] : starts[3] + 40], X[starts[30] : starts[30] + 200]])
    d, f, rows = reached_neighbourhoods(q, index, k=64, starts=starts)
    d_all, f_all = index.query(q, 64)
    np.testing.assert_array_equal(d[:rows], d_all[:rows])
    assert rows < len(q)
    np.testing.assert_array_equal(f[:rows], f_all[:rows])
    assert (f[rows:] == -1).all() and np.isinf(d[rows:]).all()
    assert lng(q, index, k=64, starts=starts).empty and lng(q, index, k=64, starts=starts, early_stop=False).empty


def test_a_k_above_the_indexed_frames_is_refused_before_anything_is_allocated():
    """k beyond the index's frames is a ParameterError naming k (as ``KnnIndex.query`` refuses it), raised before the
    (m, k) arrays are made: k = 10^8 on a 30-frame query would be 22 GiB (the CLI's bad-value test found it)."""
    x = np.arange(40.0)[:, None]
    with pytest.raises(ParameterError, match="k"):
        reached_neighbourhoods(x[:30], KnnIndex(x), k=100_000_000)
