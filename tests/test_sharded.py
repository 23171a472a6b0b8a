"""Sharded search (issue 26): every query path over a Dask cluster returns exactly the single-process hit table, on
a LocalCluster of 2 workers and on a real `dask scheduler` with 2 `dask worker` processes on loopback; a worker
killed gives the whole answer again (its shards started on the worker left) or, with none left, a ClusterError.

Issue 38 (7): random inputs (hypothesis) for every use case on 1, 2, 3 and uneven shards give the single process's
table row for row, dtypes and attrs included, or the same error; and the CLI's --csv with and without --scheduler.
The discrepancies they found are kept as fixed tests below them."""
from __future__ import annotations

import contextlib
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.control import currently_in_test_context

from mocapviz import Engine, MotionDB
from mocapviz.cli import main
from mocapviz.db.shards import shard_view, split_documents
from mocapviz.errors import ClusterError, DescriptionError, MocapvizError, ParameterError
from mocapviz.features import feature_names, numeric_of, relational_features, store_numeric
from mocapviz.relational.description import named_descriptions
from mocapviz.relational.index import build
from mocapviz.relational.query import query_by_example
from mocapviz.relational.scene import find
from mocapviz.relational.templates import learn_class
from mocapviz.relational.vocabulary import vocabulary_of
from mocapviz.similarity.knn import KnnIndex
from mocapviz.similarity.search import SimilaritySearch

KEY = ["doc_id", "start", "end"]
NUMERIC = ("F15E", "F15x3E", "Fp8")  # the papers' set, a set on windows of frames, a PCA set (fitted per process)
RELATIONAL = ("2005", "2006")


@pytest.fixture(scope="module")
def hdm05(hdm05_db30):
    """All 287 HDM05 clips at 30 Hz with their 2005 indexes (in memory) for the single-process answers."""
    values, _ = relational_features(hdm05_db30, "2005", progress=False)
    return hdm05_db30, build(hdm05_db30, "2005", progress=False, values=values, save=False)


@pytest.fixture(scope="module")
def client():
    """One LocalCluster of 2 workers for the module: every ShardedDB below and the CLI's --scheduler ADDRESS."""
    from distributed import Client, LocalCluster

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                          silence_logs=logging.ERROR) as cluster, Client(cluster) as c:  # fmt: skip
            yield c


def uneven_shards(db) -> list[np.ndarray]:
    """Four shards of very different sizes: the first two documents (fewer than most K), the next ones, the
    shortest document alone (shorter than most examples: 14 frames in HDM05 at 30 Hz), and the rest."""
    docs = db.documents.sort_values("start")
    ids, frames = docs["doc_id"].to_numpy(np.int64), docs["n_frames"].to_numpy()
    alone = 3 + int(np.argmin(frames[3:-1]))
    return [ids[:2], ids[2:alone], ids[alone : alone + 1], ids[alone + 1 :]]


@pytest.fixture(scope="module")
def shardings(hdm05, client):
    """The database on 1, 2 and 3 shards of about equal frames and on four uneven ones (:func:`uneven_shards`),
    every shard's derived data made once (numeric sets, both relational sets)."""
    db = hdm05[0]
    layouts = {"1": {"n_shards": 1}, "2": {"n_shards": 2}, "3": {"n_shards": 3},
               "uneven": {"shards": uneven_shards(db)}, "here 2": {"n_shards": 2},
               "here uneven": {"shards": uneven_shards(db)}}  # fmt: skip
    with contextlib.ExitStack() as stack:
        yield {name: stack.enter_context(Engine(db, scheduler=client if name.isdigit() or name == 'uneven' else None,
                                                numeric_sets=NUMERIC, relational_sets=RELATIONAL, **layout)) for name, layout in layouts.items()}  # fmt: skip


@pytest.fixture(scope="module")
def sharded(shardings):
    return shardings["3"]


def same(a: pd.DataFrame, b: pd.DataFrame, *columns) -> None:
    assert list(a.columns) == list(b.columns)
    cols = [*KEY, *columns]
    assert a[cols].reset_index(drop=True).equals(b[cols].reset_index(drop=True)), (a[cols].head(), b[cols].head())
    assert b["rank"].tolist() == list(range(1, len(b) + 1))


def test_shards_are_views_of_consecutive_documents(hdm05_db30):
    db = hdm05_db30
    shards = split_documents(db, 3)
    assert sorted(np.concatenate(shards).tolist()) == sorted(db.documents["doc_id"].tolist())
    frames = [int(db.documents.set_index("doc_id").loc[s, "n_frames"].sum()) for s in shards]
    assert max(frames) - min(frames) <= db.documents["n_frames"].max()  # balanced to within one document
    view = shard_view(db, shards[1])
    doc = int(shards[1][3])
    assert np.array_equal(view.motion(doc).positions, db.motion(doc).positions)
    assert np.shares_memory(view.positions, db.positions)
    with pytest.raises(ParameterError, match="consecutive"):
        shard_view(db, [shards[0][0], shards[2][0]])


def test_similarity_search_is_exactly_the_single_process_answer(hdm05, sharded):
    db = hdm05[0]
    search = SimilaritySearch(db, "F15E")
    for doc in db.documents["doc_id"].iloc[[0, 40, 130, 286]].astype(int):
        for mode in ("exact", "brute"):
            same(search.clips(doc, n_matches=8, mode=mode), sharded.clips(doc, n_matches=8, mode=mode, exclude_document=False), "cost")
        same(search.clips(doc, n_matches=5, mode="exact", exclude_document=True),
             sharded.clips(doc, n_matches=5, mode="exact", exclude_document=True), "cost")  # fmt: skip
        same(search.stretches(doc, (0, 20), n_matches=6, mode="exact"),
             sharded.stretches(doc, frames=(0, 20), n_matches=6, mode="exact", exclude_document=False), "cost")  # fmt: skip


def test_motion_matching_is_exactly_the_single_process_answer(hdm05, sharded):
    """The lazy neighbourhood graph on the shards' merged neighbours, subsequence DTW on every shard."""
    from mocapviz.similarity.motion_matching import match_motion

    db = hdm05[0]
    for doc in (3, 77, 150):
        for method, options in (("lng", {"k": 64}), ("dtw", {})):
            for exclude in (False, True):
                one = match_motion(db, doc, (0, 20), method=method, n_matches=6, exclude_document=exclude, **options)
                many = sharded.match(doc, frames=(0, 20), method=method, n_matches=6, exclude_document=exclude,
                                            **options)  # fmt: skip
                same(one, many, "cost")


def test_knn_is_exactly_the_single_process_answer(hdm05, sharded):
    db = hdm05[0]
    features = numeric_of(db, "F15E")
    index = KnnIndex(features)
    rows = np.random.default_rng(5).integers(0, db.n_frames, 40)
    d1, f1 = index.query(features[rows], 16)
    d2, f2 = sharded.knn(features[rows], k=16)
    assert np.array_equal(d1, d2)
    ties = np.isclose(d1[:, :, None], d1[:, None, :]).sum(axis=2) > 1
    assert np.array_equal(f1[~ties], f2[~ties])  # equal distances may come in either order
    own = db.frames(int(db.document_of([rows[0]])[0]))
    d1, f1 = index.query(features[rows[0]], 8, exclude=(own.start, own.stop))
    d2, f2 = sharded.knn(features[rows[0]], k=8, exclude=(own.start, own.stop))
    assert np.array_equal(d1, d2[0]) and not ((f2 >= own.start) & (f2 < own.stop)).any()


def test_relational_queries_are_exactly_the_single_process_answer(hdm05, sharded):
    db, indexes = hdm05
    example = db.motion(int(db.select(label="kickLFront1Reps")["doc_id"].iloc[0]))
    for features, mode, m in ((["lfoot_raised", "lknee_bent"], "adaptive", 1), (["rknee_bent", "lknee_bent"],
                              "exact", 1), (["lfoot_raised", "lknee_bent", "lhand_fast"], "mismatch", 1)):  # fmt: skip
        one = query_by_example(db, example, features, mode=mode, mismatches=m, indexes=indexes)
        same(one, sharded.query(example, features=features, mode=mode, mismatches=m), "score")
    for text in ("kick_left", "squat", "walk_step", "squat then jump within 3 s", "kick_left | kick_right"):
        one, many = find(db, text, indexes=indexes), sharded.find(text, n_matches=None)
        same(one, many, "score", "parts")
        assert one.attrs["counts"] == many.attrs["counts"] and one.attrs["empty_reason"] == many.attrs["empty_reason"]
    with pytest.raises(ParameterError, match="longer than every document"):
        sharded.query(replace(db.motion(0), fps=1.0), features=["lknee_bent"])  # the clip played 30x slower


def test_an_example_longer_than_a_shards_documents_still_finds_their_hits(hdm05, sharded):
    """Issue 38's reproducer: document 100 (6.7 s) is longer than every document of the last shard, whose documents
    still hold adaptive hits (shorter than the query); the shard used to answer nothing, exit 0."""
    db, indexes = hdm05
    features = ["rknee_bent", "lknee_bent"]
    one = query_by_example(db, db.motion(100), features, indexes=indexes)
    last = set(split_documents(db, 3)[-1].tolist())
    assert last & set(one["doc_id"]), "the reproducer's hits must reach the last shard"
    same(one, sharded.query(db.motion(100), features=features), "score", "first_segment", "last_segment",
         "n_segments")  # fmt: skip


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_relational_queries_are_exactly_the_single_process_table(hdm05, sharded, data):
    """Any example (document, span), features and mode: the sharded table equals the single-process one, column for
    column (segments numbered in the whole database), or both refuse the query alike."""
    db, indexes = hdm05
    docs = db.documents
    row = data.draw(st.integers(0, len(docs) - 1), label="document row")
    n = int(docs["n_frames"].iloc[row])
    start = data.draw(st.integers(0, n - 2), label="start")
    stop = data.draw(st.integers(start + 2, n), label="stop")
    example = db.motion(int(docs["doc_id"].iloc[row]))[start:stop]
    features = data.draw(st.lists(st.sampled_from(feature_names("2005")), min_size=1, max_size=3, unique=True),
                         label="features")  # fmt: skip
    mode = data.draw(st.sampled_from(["adaptive", "exact", "fuzzy", "mismatch"]), label="mode")
    try:
        one = query_by_example(db, example, features, mode=mode, indexes=indexes)
    except ParameterError as refused:
        with pytest.raises(ParameterError) as also:
            sharded.query(example, features=features, mode=mode)
        assert str(also.value) == str(refused)
        return
    many = sharded.query(example, features=features, mode=mode)
    assert list(one.columns) == list(many.columns)
    assert one.reset_index(drop=True).equals(many.reset_index(drop=True)), (one.head(), many.head())


def test_template_search_is_exactly_the_single_process_answer(hdm05, sharded):
    from mocapviz.relational.templates import search_template

    db = hdm05[0]
    template = learn_class(db, "squat1Reps", actors=["bd"])
    same(search_template(db, template, n_matches=12, delta=0.2), sharded.search_template(template, n_matches=12),
         "cost")  # the engine's δ is 0.2 (docs/parameters.md)
    one = search_template(db, template, n_matches=12, prefilter=True)  # the keyframe pre-filter, per shard
    two = sharded.search_template(template, n_matches=12, prefilter=True, delta=0.1)
    same(one, two, "cost")
    assert two.attrs["aligned"] == pytest.approx(one.attrs["aligned"], abs=1e-6) and one.attrs["aligned"] < 1


def test_cli_scheduler_local_writes_the_same_csv(sample_db, client, tmp_path, capsys):
    """The first command with --scheduler local (a cluster of its own), the others on the module's cluster by its
    address (a cluster started per command cost 5 s each)."""
    db = MotionDB.ingest(sample_db.documents["path"].tolist(), tmp_path / "db", progress=False)
    assert main(["index", str(db.path), "--quiet", "--scheduler", client.scheduler.address]) == 0
    assert main(["template", "learn", str(db.path), "--label", "kickLFront1Reps", "--relational-set", "2005"]) == 0
    for i, command in enumerate((["search", str(db.path), "--example", "7", "-K", "4", "--mode", "exact"],
                                 ["find", str(db.path), "kick_left"],
                                 ["template", "search", str(db.path), "kickLFront1Reps", "-K", "5", "--prefilter"],
                                 ["knn", str(db.path), "--frame", "7:30", "-k", "6", "--quiet"])):  # fmt: skip
        one, many = tmp_path / "one.csv", tmp_path / "many.csv"
        assert main([*command, "--csv", str(one)]) == 0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scheduler = "local" if i == 0 else client.scheduler.address
            assert main([*command, "--csv", str(many), "--scheduler", scheduler]) == 0
        assert one.read_bytes() == many.read_bytes(), command
    capsys.readouterr()


# ================================================================================================ random inputs
# Issue 38 (7): for every use case, random inputs over the 287 HDM05 clips at 30 Hz give the sharded table equal to
# the single process's, row for row with its dtypes and the attrs that say what was searched, on 1, 2, 3 and uneven
# shards; or both refuse the query with the same error.
class Single:
    """The single-process answers' derived data, made once: relational values and indexes of both sets, the numeric
    sets with their searches and kd-trees, templates learned on demand."""

    def __init__(self, db, indexes_2005: dict):
        self.db = db
        self.values = {s: relational_features(db, s, progress=False)[0] for s in RELATIONAL}
        self.indexes = {s: indexes_2005 if s == "2005" else build(db, s, progress=False, values=self.values[s],
                                                                     save=False) for s in RELATIONAL}  # fmt: skip
        self.features = {n: numeric_of(db, n) for n in NUMERIC}
        self.searches = {n: SimilaritySearch(db, n, features=self.features[n]) for n in NUMERIC}
        self.knn = {n: KnnIndex(self.features[n]) for n in NUMERIC}
        self._templates: dict = {}

    def template(self, label: str, relational_set: str):
        if (label, relational_set) not in self._templates:
            self._templates[label, relational_set] = learn_class(self.db, label, relational_set=relational_set,
                                                                 values=self.values[relational_set])  # fmt: skip
        return self._templates[label, relational_set]


@pytest.fixture(scope="module")
def single(hdm05):
    return Single(*hdm05)


def answer(call):
    """The table ``call()`` returns, or the error it raises (a refusal both paths must share)."""
    try:
        return call()
    except MocapvizError as refused:
        return refused


def identical(one, many, attrs=()) -> None:
    """``many`` is ``one``: the same error, or the same table (columns, dtypes, every value exactly, the rows in
    order) with the same ``attrs``."""
    if isinstance(one, Exception) or isinstance(many, Exception):
        assert (type(one), str(one)) == (type(many), str(many))
        if currently_in_test_context():
            event(f"both refused: {type(one).__name__}")
        return
    pd.testing.assert_frame_equal(one.reset_index(drop=True), many.reset_index(drop=True), check_exact=True)
    assert {a: one.attrs.get(a) for a in attrs} == {a: many.attrs.get(a) for a in attrs}
    if currently_in_test_context():
        event("hits" if len(one) else "no hit")


shards_of = st.sampled_from(["1", "2", "3", "uneven", "here 2", "here uneven"])


def draw_example(data, db, motion: bool = True):
    """A random example: any document (of any shard), any span of at least 2 frames, given as (doc id, (start,
    stop)) or, with ``motion``, half the time as the Motion of that span (no own document)."""
    docs = db.documents
    row = data.draw(st.integers(0, len(docs) - 1), label="document row")
    doc, n = int(docs["doc_id"].iloc[row]), int(docs["n_frames"].iloc[row])
    start = data.draw(st.integers(0, n - 2), label="start")
    stop = data.draw(st.integers(start + 2, n), label="stop")
    if motion and data.draw(st.booleans(), label="as a Motion"):
        return db.motion(doc)[start:stop], None
    return doc, (start, stop)


@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_random_similarity_searches_are_the_single_process_table(single, shardings, data):
    """clips and stretches, exact and brute mode (fast mode is per shard: docs/reproduce.md, Sharded search)."""
    key, numeric_set = data.draw(shards_of, label="shards"), data.draw(st.sampled_from(NUMERIC), label="numeric set")
    example, frames = draw_example(data, single.db)
    task = data.draw(st.sampled_from(["clips", "stretches"]), label="task")
    options = {"n_matches": data.draw(st.integers(1, 12) | st.sampled_from([287, 400]), label="K"),
               "mode": data.draw(st.sampled_from(["exact", "brute"]), label="mode"),
               "exclude_document": data.draw(st.booleans(), label="exclude_document")}  # fmt: skip
    if task == "stretches":
        options["min_length"] = data.draw(st.sampled_from([None, 0.5, 1.0]) | st.floats(0.05, 1.0), label="min_length")
    one = answer(lambda: getattr(single.searches[numeric_set], task)(example, frames, **options))
    many = answer(lambda: getattr(shardings[key], task)(example, frames=frames, numeric_set=numeric_set, **options))
    identical(one, many, ("mode", "query_frames", "documents", "brute_cells", "ranges"))


@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_random_knn_is_the_single_process_answer(single, shardings, data):
    """Distances and frames exactly, ties in frame order, k past a shard's frames or the whole database's."""
    key, numeric_set = data.draw(shards_of, label="shards"), data.draw(st.sampled_from(NUMERIC), label="numeric set")
    db, features = single.db, single.features[numeric_set]
    firsts = db.documents["start"].tolist()  # a document's first frame: often a pose the one before ends with
    rows = np.array(data.draw(st.lists(st.integers(0, db.n_frames - 1) | st.sampled_from(firsts), min_size=1,
                                       max_size=4), label="frames"))  # fmt: skip
    k = data.draw(st.integers(1, 64) | st.sampled_from([db.n_frames, db.n_frames + 1]), label="k")
    radius = data.draw(st.none() | st.floats(1.0, 200.0), label="radius")
    exclude = None
    if data.draw(st.booleans(), label="exclude own document"):
        starts = db.documents.set_index("doc_id")["start"]
        own = db.document_of(rows)
        exclude = np.stack([starts.loc[own].to_numpy(), starts.loc[own].to_numpy() + db.documents.set_index(
            "doc_id")["n_frames"].loc[own].to_numpy()], axis=1)  # fmt: skip
    one = answer(lambda: single.knn[numeric_set].query(features[rows], k, radius=radius, exclude=exclude))
    many = answer(lambda: shardings[key].knn(features[rows], k=k, numeric_set=numeric_set, radius=radius, eps=0.0,
                                                  exclude=exclude))
    if isinstance(one, Exception) or isinstance(many, Exception):
        identical(one, many)
        return
    assert np.array_equal(one[0], many[0]) and np.array_equal(one[1], many[1])
    event("some padded" if (one[1] < 0).any() else "k found")


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_random_motion_matching_is_the_single_process_table(single, shardings, data):
    """match_motion by the lazy neighbourhood graph (the shards' merged neighbours) and by subsequence DTW."""
    from mocapviz.similarity.motion_matching import DEFAULT_K, match_motion

    key, numeric_set = data.draw(shards_of, label="shards"), data.draw(st.sampled_from(NUMERIC), label="numeric set")
    example, frames = draw_example(data, single.db)
    method = data.draw(st.sampled_from(["lng", "dtw"]), label="method")
    k = data.draw(st.sampled_from([8, 64, DEFAULT_K]), label="k") if method == "lng" else None
    radius = data.draw(st.none() | st.floats(5.0, 100.0), label="radius") if method == "lng" else None
    options = {"n_matches": data.draw(st.integers(1, 12), label="K"), "radius": radius,
               "exclude_document": data.draw(st.booleans(), label="exclude_document"),
               "min_length": data.draw(st.sampled_from([None, 0.5, 1.0]) | st.floats(0.05, 1.0), label="min_length")}
    one = answer(lambda: match_motion(single.db, example, frames, numeric_set, method, k=k or DEFAULT_K,
                                      features=single.features[numeric_set], index=single.knn[numeric_set],
                                      **options))  # fmt: skip
    many = answer(lambda: shardings[key].match(example, frames=frames, numeric_set=numeric_set, method=method,
                                               **({"k": k} if k else {}), **options))
    identical(one, many, ("method", "query_frames", "min_length"))


@settings(max_examples=50, deadline=None)
@given(data=st.data())
def test_random_queries_by_example_are_the_single_process_table(single, shardings, data):
    """Every mode, either set, mismatches with and without allowed segments (segments numbered in the whole
    database)."""
    key, relational_set = data.draw(shards_of, label="shards"), data.draw(st.sampled_from(RELATIONAL), label="set")
    example, _ = draw_example(data, single.db, motion=False)
    example = single.db.motion(example)[slice(*_)]
    features = data.draw(st.lists(st.sampled_from(feature_names(relational_set)), min_size=1, max_size=4,
                                  unique=True), label="features")  # fmt: skip
    mode = data.draw(st.sampled_from(["adaptive", "exact", "fuzzy", "mismatch"]), label="mode")
    mismatches = data.draw(st.integers(0, 3), label="mismatches")
    allowed = data.draw(st.none() | st.lists(st.integers(0, 4), max_size=3, unique=True), label="allowed")
    options = {"mode": mode, "mismatches": mismatches, "relational_set": relational_set, "allowed": allowed}
    one = answer(lambda: query_by_example(single.db, example, features, indexes=single.indexes[relational_set],
                                          **options))  # fmt: skip
    many = answer(lambda: shardings[key].query(example, features=features, **options))
    identical(one, many, ("group_segments",))


def progression(data, relational_set: str) -> str:
    """A random progression of 2-4 states of one feature (a state never twice in a row), maybe with a duration
    and a somewhere / never condition."""
    words = vocabulary_of(relational_set)
    feature = data.draw(st.sampled_from(words.features), label="feature")
    steps = [data.draw(st.sampled_from([0, 1, None]), label="state")]
    for _ in range(data.draw(st.integers(1, 3), label="more states")):
        steps.append(data.draw(st.sampled_from([0, 1, None] if steps[-1] is None else [None, 1 - steps[-1]])))
    if all(v is None for v in steps):
        steps[0] = 0
    states = words.states(feature)
    text = f"{words.part(feature)}: " + " ".join("*" if v is None else states[v] for v in steps)
    if data.draw(st.booleans(), label="duration"):
        value = data.draw(st.sampled_from([v for v in steps if v is not None]))
        low, high = data.draw(st.sampled_from([("", "0.4"), ("0.1", ""), ("0.2", "1.5")]), label="for")
        text += f" and {words.part(feature)} {states[value]} for {low}..{high} s"
    if data.draw(st.booleans(), label="condition"):
        other = data.draw(st.sampled_from(words.features))
        kind = data.draw(st.sampled_from(["somewhere", "never"]))
        text += f" and {kind} {words.part(other)} {words.states(other)[data.draw(st.sampled_from([0, 1]))]}"
    return text


def description(data, relational_set: str, templates=()) -> str:
    """Shipped names, random progressions and ``templates`` (stored names: ``template:NAME``) joined by ``then``
    (maybe ``within``) and ``|``."""
    names = [n for n, body in named_descriptions(relational_set).items() if not isinstance(body, DescriptionError)]
    names += [f"template:{name}" for name in templates]

    def primary() -> str:
        if data.draw(st.integers(0, 2), label="progression?") == 0:
            return progression(data, relational_set)
        return data.draw(st.sampled_from(names), label="name")

    def sequence() -> str:
        text = primary()
        for _ in range(data.draw(st.sampled_from([0, 0, 1, 2]), label="thens")):
            within = data.draw(st.sampled_from(["", " within 0.5 s", " within 2 s", " within 10 s"]), label="within")
            text += f" then {primary()}{within}"
        return text

    text = " | ".join(sequence() for _ in range(data.draw(st.integers(1, 2), label="alternatives")))
    return ("set 2006; " if relational_set == "2006" else "") + text


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_random_descriptions_find_the_single_process_table(single, shardings, data):
    key, relational_set = data.draw(shards_of, label="shards"), data.draw(st.sampled_from(RELATIONAL), label="set")
    text = description(data, relational_set)
    options = {"n_matches": data.draw(st.none() | st.integers(1, 30), label="K"),
               "overlapping": data.draw(st.booleans(), label="overlapping")}
    one = answer(lambda: find(single.db, text, indexes=single.indexes[relational_set],
                              values=single.values[relational_set], **options))  # fmt: skip
    many = answer(lambda: shardings[key].find(text, **options))
    identical(one, many, ("description", "relational_set", "counts", "candidates", "empty_reason"))


@pytest.mark.slow  # the heaviest random test: 3.6 s on an idle machine, 18.6 s with the 2 cores loaded 2x
@settings(max_examples=30, deadline=None)
@given(data=st.data())
def test_random_template_searches_are_the_single_process_table(single, shardings, data):
    """The template of a random label (either set), with and without the keyframe pre-filter; the share of the
    frames aligned is the single process's with the pre-filter (the same ranges) and may differ by lower bounds
    (each shard aligns until its own K best are certain), the hits never."""
    from mocapviz.relational.templates import search_template

    key, relational_set = data.draw(shards_of, label="shards"), data.draw(st.sampled_from(RELATIONAL), label="set")
    labels = sorted(single.db.documents["label"].dropna().unique())
    template = single.template(data.draw(st.sampled_from(labels), label="label"), relational_set)
    options = {"n_matches": data.draw(st.integers(1, 15), label="K"),
               "delta": data.draw(st.sampled_from([0.1, 0.2, 0.3]), label="delta"),
               "max_cost": data.draw(st.none() | st.floats(0.0, 0.5), label="max_cost"),
               "prefilter": data.draw(st.booleans(), label="prefilter")}  # fmt: skip
    one = answer(lambda: search_template(single.db, template, values=single.values[relational_set],
                                         indexes=single.indexes[relational_set], **options))  # fmt: skip
    many = answer(lambda: shardings[key].search_template(template, **options))
    identical(one, many, ("relational_set", "aligned") if options["prefilter"] else ("relational_set",))


def test_uneven_shards_are_checked(hdm05, client):
    db = hdm05[0]
    shards = uneven_shards(db)
    for bad in ([shards[1], shards[0], *shards[2:]], shards[:-1], [*shards[:-1], shards[-1][1:]], [[], *shards]):
        with pytest.raises(ParameterError, match="storage order, every document once"):
            Engine(db, scheduler=client, shards=bad)
    with pytest.raises(ParameterError, match="not both"):
        Engine(db, scheduler=client, n_shards=2, shards=shards)


# The discrepancies the random tests found, kept as fixed cases.
def test_a_query_longer_than_a_shards_documents_still_searches_them(single, shardings):
    """Stretches and subsequence DTW: a shard whose documents are all shorter than the query refused it ("the
    query has 15 frames, more than the longest searchable document (14 frames)"; random test, 'uneven', document 0
    frames 0:15, K=1) where one process answers: a match may be as short as min_length x the query. Also on two
    even shards (200 frames of document 102, the second shard's longest 186) and with the query's own document,
    alone on its shard, left out (that shard searches nothing). The length is checked once, on the whole database."""
    from mocapviz.similarity.motion_matching import match_motion

    db, search = single.db, single.searches["F15E"]
    alone = int(uneven_shards(db)[2][0])  # 14 frames
    short = db.documents.set_index("doc_id")["n_frames"]
    for key, doc, frames, exclude in (("uneven", 0, (0, 15), False), ("uneven", alone, None, True),
                                      ("uneven", alone, None, False), ("2", 102, (0, 200), False)):  # fmt: skip
        for mode in ("exact", "brute"):
            options = {"n_matches": 6, "mode": mode, "exclude_document": exclude}
            identical(search.stretches(doc, frames, **options), shardings[key].stretches(doc, frames=frames, **options),
                      ("documents", "brute_cells", "ranges"))  # fmt: skip
        options = {"method": "dtw", "n_matches": 6, "exclude_document": exclude}
        identical(match_motion(db, doc, frames, features=single.features["F15E"], **options),
                  shardings[key].match(doc, frames=frames, **options), ("method", "query_frames"))  # fmt: skip
    every = search.stretches(0, (0, 15), n_matches=400, mode="brute")
    assert (short.loc[every["doc_id"]].to_numpy() < 15).any()  # documents shorter than the query hold matches
    identical(every, shardings["uneven"].stretches(0, frames=(0, 15), n_matches=400, mode="brute",
                                                      exclude_document=False), ("documents",))


def test_knn_checks_k_and_exclude_on_the_whole_database(single, shardings):
    """k past the database's frames: one kd-tree refuses it, the shards answered (padded with -1); a frame of a
    document alone on its shard with that document excluded: the shard refused ("every indexed frame") where one
    process answers, and so did the lazy neighbourhood graph through it."""
    from mocapviz.similarity.motion_matching import match_motion

    db, features, index = single.db, single.features["F15E"], single.knn["F15E"]
    for sharded in shardings.values():
        identical(answer(lambda: index.query(features[:2], db.n_frames + 1)),
                  answer(lambda: sharded.knn(features[:2], k=db.n_frames + 1)))  # fmt: skip
    alone = int(uneven_shards(db)[2][0])
    own = db.frames(alone)
    rows, exclude = np.array([own.start, own.start + 5, 0]), [[own.start, own.stop]] * 2 + [[0, 1]]
    one, many = index.query(features[rows], 16, exclude=exclude), shardings["uneven"].knn(features[rows], k=16,
                                                                                            exclude=exclude)
    assert np.array_equal(one[0], many[0]) and np.array_equal(one[1], many[1])
    identical(match_motion(db, alone, k=64, exclude_document=True, features=features, index=index),
              shardings["uneven"].match(alone, k=64, exclude_document=True), ("method", "query_frames"))


def test_knn_ties_across_the_kth_neighbour_go_to_the_first_frame(single, shardings):
    """HDM05's cut clips often share a pose at a cut (the last frame of one document is the first of the next,
    distance 0): asked for k=1 at such a frame, the kd-tree over the whole database returned one of the two and a
    shard's kd-tree the other (random CLI test: knn --frame 53:0 -k 1, doc 52 frame 43 against doc 53 frame 0). The
    k returned are now the k least by (distance, frame) from any index: the first frame of the pose."""
    db, features = single.db, single.features["F15E"]
    starts = db.documents.sort_values("start")["start"].to_numpy()[1:]
    shared = starts[(features[starts] == features[starts - 1]).all(axis=1)]
    assert len(shared) > 10
    first = [int(np.flatnonzero((features == features[f]).all(axis=1))[0]) for f in shared]
    for engine in ("kdtree", "ckdtree", "brute"):
        assert KnnIndex(features, engine=engine).query(features[shared], 1)[1][:, 0].tolist() == first
    for sharded in shardings.values():
        assert sharded.knn(features[shared], k=1)[1][:, 0].tolist() == first


def test_a_name_used_twice_is_counted_twice(single, shardings):
    """find's attrs ``counts`` hold a label once per part, in evaluation order, twice when a name is used twice;
    the shards' counts were merged by label ('kick_right | kick_right': one ('kick_right', 0) fewer, random test)."""
    for text in ("kick_right | kick_right", "squat then squat within 3 s", "kick_left then kick_left | squat"):
        one = find(single.db, text, indexes=single.indexes["2005"])
        assert len({label for label, _ in one.attrs["counts"]}) < len(one.attrs["counts"])
        for sharded in shardings.values():
            identical(one, sharded.find(text, n_matches=None), ("counts", "candidates", "empty_reason"))


def test_a_similarity_searchs_work_is_counted_on_every_shard(single, shardings):
    """attrs ``documents`` and ``brute_cells`` were the first shard's (103 documents of 287 on three shards)."""
    one = single.searches["F15E"].clips(40, n_matches=3, mode="exact")
    for sharded in shardings.values():
        many = sharded.clips(40, n_matches=3, mode="exact", exclude_document=False)
        assert (many.attrs["documents"], many.attrs["brute_cells"]) == (287, one.attrs["brute_cells"])


# ------------------------------------------------------------------------------------------------ the CLI's --csv
@pytest.fixture(scope="module")
def cli_db(single, tmp_path_factory):
    """A copy of the HDM05 database with both relational indexes, F15E (F15x3E computed per call) and the templates
    of :data:`CLI_TEMPLATES` stored."""
    from mocapviz.relational.templates import store_template

    path = tmp_path_factory.mktemp("cli") / "db"
    shutil.copytree(single.db.path, path)
    db = MotionDB.open(path)
    for relational_set in RELATIONAL:
        build(db, relational_set, progress=False, values=single.values[relational_set])
        for label in CLI_TEMPLATES:
            store_template(db, single.template(label, relational_set), f"{label}-{relational_set}")
    store_numeric(db, ["F15E"], progress=False)
    return db


CLI_TEMPLATES = ("squat1Reps", "kickLFront1Reps")  # stored as LABEL-SET, named by template: atoms of find


def cli_command(data, db) -> list[str]:
    """A random query, find, search or knn command line (without --csv and --scheduler)."""
    command = data.draw(st.sampled_from(["query", "find", "search", "knn"]), label="command")
    docs = db.documents
    row = data.draw(st.integers(0, len(docs) - 1), label="document row")
    doc, n = int(docs["doc_id"].iloc[row]), int(docs["n_frames"].iloc[row])
    start = data.draw(st.integers(0, n - 2), label="start")
    span = f"{start}:{data.draw(st.integers(start + 2, n), label='stop')}"
    K = str(data.draw(st.integers(1, 30), label="K"))
    if command == "query":
        relational_set = data.draw(st.sampled_from(RELATIONAL), label="set")
        features = data.draw(st.lists(st.sampled_from(feature_names(relational_set)), min_size=1, max_size=3,
                                      unique=True), label="features")  # fmt: skip
        mode = data.draw(st.sampled_from([["--mode", "adaptive"], ["--mode", "exact"], ["--mode", "fuzzy"],
                                          ["--mismatch", "1"]]), label="mode")  # fmt: skip
        return ["query", str(db.path), "--example", str(doc), "--frames", span, "--features", ",".join(features),
                *mode, "--relational-set", relational_set, "-K", K]  # fmt: skip
    if command == "find":
        relational_set = data.draw(st.sampled_from(RELATIONAL), label="set")
        stored = [f"{label}-{relational_set}" for label in CLI_TEMPLATES]
        return ["find", str(db.path), description(data, relational_set, stored), "-K", K]
    numeric_set = data.draw(st.sampled_from(["F15E", "F15x3E"]), label="numeric set")
    if command == "knn":
        frame = data.draw(st.integers(0, n - 1), label="frame")
        flags = data.draw(st.lists(st.sampled_from(["--exclude-document", "--per-document"]), unique=True))
        return ["knn", str(db.path), "--frame", f"{doc}:{frame}", "-k", K, "--numeric-set", numeric_set, "--quiet",
                *flags]  # fmt: skip
    mode = data.draw(st.sampled_from(["exact", "brute"]), label="mode")
    flags = data.draw(st.lists(st.sampled_from(["--stretches", "--exclude-document"]), unique=True), label="flags")
    return ["search", str(db.path), "--example", str(doc), "--frames", span, "--numeric-set", numeric_set, "-K", K,
            "--mode", mode, *flags]  # fmt: skip


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_cli_csv_is_the_same_with_a_scheduler(cli_db, client, tmp_path, capsys, data):
    """query, find, search and knn write the same --csv bytes (or the same error) with --scheduler ADDRESS (the
    module's cluster: the CLI shards the database over its 2 workers) as without."""
    command = cli_command(data, cli_db)
    outputs = []
    for extra in ([], ["--scheduler", client.scheduler.address]):
        csv = tmp_path / f"{len(outputs)}.csv"
        csv.unlink(missing_ok=True)
        capsys.readouterr()
        code = main([*command, "--csv", str(csv), *extra])
        err = capsys.readouterr().err
        outputs.append((code, csv.read_bytes() if code == 0 else err))
    assert outputs[0] == outputs[1], command
    event(f"{command[0]}{' with a template' if 'template:' in ' '.join(command) else ''}: exit {outputs[0][0]}")


def test_cli_cases_the_random_tests_found(cli_db, client, tmp_path, capsys):
    """`search --stretches` of 200 frames of document 102 exited 1 with --scheduler on two shards (the second's
    longest document has 186 frames) and answered without; `knn --frame 53:0 -k 1` (a pose documents 52 and 53
    share) named another frame. Now the same CSV."""
    stretches = ["--frames", "0:200", "--stretches", "--mode", "exact", "-K", "5"]
    for command in (["search", str(cli_db.path), "--example", "102", *stretches],
                    ["knn", str(cli_db.path), "--frame", "53:0", "-k", "1", "--quiet"]):  # fmt: skip
        assert main([*command, "--csv", str(tmp_path / "one.csv")]) == 0
        assert main([*command, "--csv", str(tmp_path / "many.csv"), "--scheduler", client.scheduler.address]) == 0
        assert (tmp_path / "one.csv").read_bytes() == (tmp_path / "many.csv").read_bytes(), command
    capsys.readouterr()


# ================================================================================================ a real cluster
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def real_cluster(tmp_path):
    """`dask scheduler` and two `dask worker` processes (no nanny: a killed worker stays dead) on loopback."""
    dask = str(Path(sys.executable).with_name("dask"))
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    log = open(tmp_path / "cluster.log", "w")
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                              stdout=log, stderr=subprocess.STDOUT, env=env)]  # fmt: skip
    time.sleep(2)
    for i in range(2):
        procs.append(subprocess.Popen([dask, "worker", address, "--nthreads", "1", "--no-nanny", "--name", f"w{i}",
                                       "--no-dashboard"], stdout=log, stderr=subprocess.STDOUT, env=env))  # fmt: skip
    from distributed import Client

    with Client(address, timeout=30) as client:
        client.wait_for_workers(2, timeout=60)
        yield address, procs, client
    for p in procs:
        p.kill()
        p.wait()
    log.close()


def test_a_real_cluster_and_a_killed_worker(hdm05, real_cluster):
    db, indexes = hdm05
    address, procs, client = real_cluster
    search = SimilaritySearch(db, "F15E")
    expected = search.clips(40, n_matches=6, mode="exact")
    kicks = find(db, "kick_left", indexes=indexes)
    with Engine(db, scheduler=address, n_shards=4) as sharded:
        same(expected, sharded.clips(40, n_matches=6, mode="exact", exclude_document=False), "cost")
        same(kicks, sharded.find("kick_left", n_matches=None), "score")
        procs[1].send_signal(signal.SIGKILL)  # one worker dies: its shards go to the other
        procs[1].wait()
        for _ in range(100):
            if len(client.scheduler_info()["workers"]) == 1:
                break
            time.sleep(0.1)
        same(expected, sharded.clips(40, n_matches=6, mode="exact", exclude_document=False), "cost")  # the whole answer, recomputed
        same(kicks, sharded.find("kick_left", n_matches=None), "score")
        procs[2].send_signal(signal.SIGKILL)  # no worker left: an error, never a partial answer
        procs[2].wait()
        with pytest.raises(ClusterError, match="no worker is left|failed twice"):
            sharded.clips(40, n_matches=6, mode="exact", exclude_document=False)


# ================================================================================================ the dashboard
def test_the_dashboards_searches_through_the_cluster(sample_db, tmp_path):
    """A Backend with a scheduler answers every page's search as the one without (mocapviz serve --scheduler)."""
    from mocapviz.app.backend import Backend
    from mocapviz.app.pages import describe, similarity, templates

    db = MotionDB.ingest(sample_db.documents["path"].tolist(), tmp_path / "db", progress=False)
    build(db, progress=False)
    local = Backend(db)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        remote = Backend(db, scheduler="local")
    try:
        for fn, args in ((similarity.nearest_frames, ("F15E", 7, 30, 8, True)),
                         (similarity.match_span, ("F15E", 7, (10, 60), 64, 4, True)),
                         (similarity.search_span, ("F15E", 7, (10, 60), "clips", "exact", 4, False)),
                         (similarity.search_span, ("F15E", 7, (10, 60), "stretches", "exact", 4, True)),
                         (describe.search, ("kick_left", "2005", 5))):  # fmt: skip
            same(fn(local, *args), fn(remote, *args))
        example = db.motion(7)[0:60]
        options = {"features": ["lfoot_raised", "lknee_bent"], "mode": "adaptive", "relational_set": "2005"}
        same(local.engine.query(example, **options), remote.engine.query(example, **options), "score")
        template = learn_class(db, "squat1Reps")
        same(templates.search_template(local, template, 0.1, 5, None),
             templates.search_template(remote, template, 0.1, 5, None), "cost")
    finally:
        remote.engine.close()


def test_serve_with_a_scheduler_answers_http(sample_db, tmp_path):
    import urllib.request

    port = _free_port()
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    proc = subprocess.Popen([sys.executable, "-m", "mocapviz.cli", "serve", str(sample_db.path), "--port", str(port),
                             "--scheduler", "local"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env)  # fmt: skip
    try:
        for _ in range(300):
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=5) as answer:
                    assert answer.status == 200 and b"mocapviz" in answer.read()
                    break
            except OSError:
                assert proc.poll() is None, proc.stdout.read().decode()[-2000:]
                time.sleep(1)
        else:
            raise AssertionError("the dashboard did not answer within 300 s")
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
