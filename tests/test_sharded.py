"""Sharded search (issue 26): every query path over a Dask cluster returns exactly the single-process hit table, on
a LocalCluster of 2 workers and on a real `dask scheduler` with 2 `dask worker` processes on loopback; a worker
killed gives the whole answer again (its shards started on the worker left) or, with none left, a ClusterError."""
from __future__ import annotations

import os
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
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import MotionDB
from mocapviz.cli import main
from mocapviz.db.shards import shard_view, split_documents
from mocapviz.errors import ClusterError, ParameterError
from mocapviz.features import feature_names, numeric_of, relational_features
from mocapviz.relational.index import build
from mocapviz.relational.query import query_by_example
from mocapviz.relational.scene import find
from mocapviz.relational.templates import learn_class
from mocapviz.sharded import ShardedDB
from mocapviz.similarity.knn import KnnIndex
from mocapviz.similarity.search import SimilaritySearch

KEY = ["doc_id", "start", "end"]


@pytest.fixture(scope="module")
def hdm05(hdm05_db30):
    """All 287 HDM05 clips at 30 Hz with their 2005 indexes (in memory) for the single-process answers."""
    values, _ = relational_features(hdm05_db30, "2005", progress=False)
    return hdm05_db30, build(hdm05_db30, "2005", progress=False, values=values, save=False)


@pytest.fixture(scope="module")
def sharded(hdm05):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with ShardedDB(hdm05[0], "local", n_shards=3, numeric_sets=["F15E"], relational_sets=["2005"]) as s:
            yield s


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
            same(search.clips(doc, n_matches=8, mode=mode), sharded.clips(doc, n_matches=8, mode=mode), "cost")
        same(search.clips(doc, n_matches=5, mode="exact", exclude_document=True),
             sharded.clips(doc, n_matches=5, mode="exact", exclude_document=True), "cost")  # fmt: skip
        same(search.stretches(doc, (0, 20), n_matches=6, mode="exact"),
             sharded.stretches(doc, (0, 20), n_matches=6, mode="exact"), "cost")  # fmt: skip


def test_motion_matching_is_exactly_the_single_process_answer(hdm05, sharded):
    """The lazy neighbourhood graph on the shards' merged neighbours, subsequence DTW on every shard."""
    from mocapviz.similarity.motion_matching import match_motion

    db = hdm05[0]
    for doc in (3, 77, 150):
        for method, options in (("lng", {"k": 64}), ("dtw", {})):
            for exclude in (False, True):
                one = match_motion(db, doc, (0, 20), method=method, n_matches=6, exclude_document=exclude, **options)
                many = sharded.match_motion(doc, (0, 20), method=method, n_matches=6, exclude_document=exclude,
                                            **options)  # fmt: skip
                same(one, many, "cost")


def test_knn_is_exactly_the_single_process_answer(hdm05, sharded):
    db = hdm05[0]
    features = numeric_of(db, "F15E")
    index = KnnIndex(features)
    rows = np.random.default_rng(5).integers(0, db.n_frames, 40)
    d1, f1 = index.query(features[rows], 16)
    d2, f2 = sharded.knn(features[rows], 16)
    assert np.array_equal(d1, d2)
    ties = np.isclose(d1[:, :, None], d1[:, None, :]).sum(axis=2) > 1
    assert np.array_equal(f1[~ties], f2[~ties])  # equal distances may come in either order
    own = db.frames(int(db.document_of([rows[0]])[0]))
    d1, f1 = index.query(features[rows[0]], 8, exclude=(own.start, own.stop))
    d2, f2 = sharded.knn(features[rows[0]], 8, exclude=(own.start, own.stop))
    assert np.array_equal(d1, d2[0]) and not ((f2 >= own.start) & (f2 < own.stop)).any()


def test_relational_queries_are_exactly_the_single_process_answer(hdm05, sharded):
    db, indexes = hdm05
    example = db.motion(int(db.select(label="kickLFront1Reps")["doc_id"].iloc[0]))
    for features, mode, m in ((["lfoot_raised", "lknee_bent"], "adaptive", 1), (["rknee_bent", "lknee_bent"],
                              "exact", 1), (["lfoot_raised", "lknee_bent", "lhand_fast"], "mismatch", 1)):  # fmt: skip
        one = query_by_example(db, example, features, mode=mode, mismatches=m, indexes=indexes)
        same(one, sharded.query_by_example(example, features, mode=mode, mismatches=m), "score")
    for text in ("kick_left", "squat", "walk_step", "squat then jump within 3 s", "kick_left | kick_right"):
        one, many = find(db, text, indexes=indexes), sharded.find(text)
        same(one, many, "score", "parts")
        assert one.attrs["counts"] == many.attrs["counts"] and one.attrs["empty_reason"] == many.attrs["empty_reason"]
    with pytest.raises(ParameterError, match="longer than every document"):
        sharded.query_by_example(replace(db.motion(0), fps=1.0), ["lknee_bent"])  # the clip played 30x slower


def test_an_example_longer_than_a_shards_documents_still_finds_their_hits(hdm05, sharded):
    """Issue 38's reproducer: document 100 (6.7 s) is longer than every document of the last shard, whose documents
    still hold adaptive hits (shorter than the query); the shard used to answer nothing, exit 0."""
    db, indexes = hdm05
    features = ["rknee_bent", "lknee_bent"]
    one = query_by_example(db, db.motion(100), features, indexes=indexes)
    last = set(split_documents(db, 3)[-1].tolist())
    assert last & set(one["doc_id"]), "the reproducer's hits must reach the last shard"
    same(one, sharded.query_by_example(db.motion(100), features), "score", "first_segment", "last_segment",
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
            sharded.query_by_example(example, features, mode=mode)
        assert str(also.value) == str(refused)
        return
    many = sharded.query_by_example(example, features, mode=mode)
    assert list(one.columns) == list(many.columns)
    assert one.reset_index(drop=True).equals(many.reset_index(drop=True)), (one.head(), many.head())


def test_template_search_is_exactly_the_single_process_answer(hdm05, sharded):
    from mocapviz.relational.templates import search_template

    db = hdm05[0]
    template = learn_class(db, "squat1Reps", actors=["bd"])
    same(search_template(db, template, n_matches=12), sharded.search_template(template, n_matches=12), "cost")
    one = search_template(db, template, n_matches=12, prefilter=True)  # the keyframe pre-filter, per shard
    two = sharded.search_template(template, n_matches=12, prefilter=True)
    same(one, two, "cost")
    assert two.attrs["aligned"] == pytest.approx(one.attrs["aligned"], abs=1e-6) and one.attrs["aligned"] < 1


def test_cli_scheduler_local_writes_the_same_csv(sample_db, tmp_path, capsys):
    db = MotionDB.ingest(sample_db.documents["path"].tolist(), tmp_path / "db", progress=False)
    assert main(["index", str(db.path), "--quiet"]) == 0
    assert main(["template", "learn", str(db.path), "--label", "kickLFront1Reps", "--relational-set", "2005"]) == 0
    for command in (["search", str(db.path), "--example", "7", "-K", "4", "--mode", "exact"],
                    ["find", str(db.path), "kick_left"],
                    ["template", "search", str(db.path), "kickLFront1Reps", "-K", "5", "--prefilter"],
                    ["knn", str(db.path), "--frame", "7:30", "-k", "6", "--quiet"]):  # fmt: skip
        one, many = tmp_path / "one.csv", tmp_path / "many.csv"
        assert main([*command, "--csv", str(one)]) == 0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert main([*command, "--csv", str(many), "--scheduler", "local"]) == 0
        assert one.read_bytes() == many.read_bytes(), command
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
    with ShardedDB(db, address, n_shards=4) as sharded:
        same(expected, sharded.clips(40, n_matches=6, mode="exact"), "cost")
        same(kicks, sharded.find("kick_left"), "score")
        procs[1].send_signal(signal.SIGKILL)  # one worker dies: its shards go to the other
        procs[1].wait()
        for _ in range(100):
            if len(client.scheduler_info()["workers"]) == 1:
                break
            time.sleep(0.1)
        same(expected, sharded.clips(40, n_matches=6, mode="exact"), "cost")  # the whole answer, recomputed
        same(kicks, sharded.find("kick_left"), "score")
        procs[2].send_signal(signal.SIGKILL)  # no worker left: an error, never a partial answer
        procs[2].wait()
        with pytest.raises(ClusterError, match="no worker is left|failed twice"):
            sharded.clips(40, n_matches=6, mode="exact")


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
        same(local.query_by_example(example, ["lfoot_raised", "lknee_bent"], "adaptive", 0, "2005"),
             remote.query_by_example(example, ["lfoot_raised", "lknee_bent"], "adaptive", 0, "2005"), "score")
        template = learn_class(db, "squat1Reps")
        same(templates.search_template(local, template, 0.1, 5, None),
             templates.search_template(remote, template, 0.1, 5, None), "cost")
    finally:
        remote.sharded.close()


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
