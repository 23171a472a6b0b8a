"""One engine behind every front (issue 38): Python (`Engine`), the command line's `--csv` and the dashboard's page
functions give the same table for random queries (hypothesis); the issue's sharded query keeps every hit; the
old sharded names still work with a FutureWarning."""
from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import Engine
from mocapviz.cli import main
from mocapviz.errors import MocapvizError

KEY = ["doc_id", "start", "end"]
SETTINGS = {"deadline": None, "suppress_health_check": [HealthCheck.function_scoped_fixture]}


@pytest.fixture(scope="module")
def backend(sample_db):
    from mocapviz.app.backend import Backend

    return Backend(sample_db)


def _csv(args, tmp_path, capsys) -> pd.DataFrame | str:
    """The hit table a command writes with --csv, or its one-line error."""
    out = tmp_path / "hits.csv"
    out.unlink(missing_ok=True)
    status = main([*args, "--csv", str(out)])
    captured = capsys.readouterr()
    return pd.read_csv(out) if status == 0 else captured.err.strip()


def _same_hits(cli, table: pd.DataFrame, cost: str) -> None:
    assert isinstance(cli, pd.DataFrame), cli
    assert cli[KEY].equals(table[KEY].reset_index(drop=True).astype(cli[KEY].dtypes.to_dict()))
    np.testing.assert_allclose(cli[cost], table[cost], rtol=1e-9)


@settings(max_examples=25, **SETTINGS)
@given(data=st.data())
def test_a_similarity_search_is_the_same_from_python_the_cli_and_the_page(sample_db, backend, tmp_path, capsys, data):
    from mocapviz.app.pages.similarity import search_span

    docs = sample_db.documents
    row = data.draw(st.integers(0, len(docs) - 1), label="document row")
    doc, n = int(docs["doc_id"].iloc[row]), int(docs["n_frames"].iloc[row])
    start = data.draw(st.integers(0, n - 2), label="start")
    stop = data.draw(st.integers(start + 2, min(n, start + 240)), label="stop")
    kind = data.draw(st.sampled_from(["clips", "stretches"]), label="kind")
    k = data.draw(st.integers(1, 12), label="K")
    mode = data.draw(st.sampled_from(["exact", "fast"]), label="mode")
    own = data.draw(st.booleans(), label="exclude own")
    args = ["search", str(sample_db.path), "--example", str(doc), "--frames", f"{start}:{stop}", "-K", str(k),
            "--mode", mode, *(["--stretches"] if kind == "stretches" else []),
            "--exclude-document" if own else "--no-exclude-document"]  # fmt: skip
    cli = _csv(args, tmp_path, capsys)
    try:
        python = getattr(backend.engine, kind)(doc, frames=(start, stop), n_matches=k, mode=mode,
                                               exclude_document=own)  # fmt: skip
    except MocapvizError as refused:
        assert isinstance(cli, str) and str(refused) in cli
        return
    _same_hits(cli, python, "cost")
    page = search_span(backend, "F15E", doc, (start, stop), kind, mode, k, own)
    assert page[KEY].equals(python[KEY]) and np.array_equal(page["cost"], python["cost"])


@settings(max_examples=20, **SETTINGS)
@given(data=st.data())
def test_a_description_finds_the_same_from_python_the_cli_and_the_page(sample_db, backend, tmp_path, capsys, data):
    from mocapviz.app.pages.describe import search
    from mocapviz.relational.description import named_descriptions

    names = sorted(named_descriptions())
    parts = data.draw(st.lists(st.sampled_from(names), min_size=1, max_size=2, unique=True), label="names")
    text = parts[0] if len(parts) == 1 else data.draw(st.sampled_from([
        f"{parts[0]} | {parts[1]}", f"{parts[0]} then {parts[1]} within 3 s"]), label="join")  # fmt: skip
    k = data.draw(st.integers(1, 30), label="K")
    relational_set = data.draw(st.sampled_from(["2005", "2006"]), label="set")
    cli = _csv(["find", str(sample_db.path), text, "-K", str(k), "--relational-set", relational_set], tmp_path,
               capsys)  # fmt: skip
    try:
        python = backend.engine.find(text, n_matches=k, relational_set=relational_set)
    except MocapvizError as refused:
        assert isinstance(cli, str) and str(refused).splitlines()[0] in cli
        return
    if python.empty:
        assert isinstance(cli, pd.DataFrame) and cli.empty
        return
    _same_hits(cli, python, "score")
    page = search(backend, text, relational_set, k)
    assert page[KEY].equals(python[KEY])


@settings(max_examples=15, **SETTINGS)
@given(data=st.data())
def test_a_template_search_is_the_same_from_python_the_cli_and_the_page(sample_db, backend, tmp_path, capsys, data):
    from mocapviz.app.pages import templates

    labels = templates.class_options(sample_db.documents)
    label = data.draw(st.sampled_from(labels), label="class")
    k = data.draw(st.integers(1, 25), label="K")
    delta = data.draw(st.sampled_from([0.1, 0.2, 0.3]), label="delta")
    template = templates.learn(backend, label, (), "2006")  # the page's template, stored for the CLI below
    python = backend.engine.search_template(template, n_matches=k, delta=delta)
    path = tmp_path / "t.npz"
    template.save(path)
    cli = _csv(["template", "search", str(sample_db.path), str(path), "-K", str(k), "--delta", str(delta)], tmp_path,
               capsys)  # fmt: skip
    _same_hits(cli, python, "cost")
    page = templates.search_template(backend, template, delta, k, None)
    assert page[KEY].equals(python[KEY])


def test_the_issues_sharded_query_keeps_every_hit(hdm05_db30, tmp_path, capsys):
    """`mocapviz query DB --example 100 --features rknee_bent,lknee_bent -K 20` on the HDM05 cut at 30 Hz found 30
    hits in one process and 14 with `--scheduler local` (every hit of the second shard lost, exit 0)."""
    from mocapviz.relational.index import load_or_build
    from mocapviz.relational.query import query_by_example

    args = ["query", str(hdm05_db30.path), "--example", "100", "--features", "rknee_bent,lknee_bent", "-K", "20",
            "--no-exclude-document"]  # as the library's kernel, its own document kept
    expected = query_by_example(hdm05_db30, hdm05_db30.motion(100), ["rknee_bent", "lknee_bent"], mode="adaptive",
                                indexes=load_or_build(hdm05_db30, "2005"))  # fmt: skip
    for scheduler in ([], ["--scheduler", "local"]):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert main([*args, *scheduler]) == 0
        out = capsys.readouterr().out
        assert out.startswith(f"{len(expected)} hits"), out[:200]
    assert len(expected) > 20  # the issue measured 30: more than one shard's worth


def test_the_old_sharded_names_still_work_with_a_future_warning(sample_db):
    with pytest.warns(FutureWarning, match="mocapviz.sharded moved to mocapviz.engine"):
        import mocapviz.sharded  # noqa: F401
    from mocapviz.sharded import ShardedDB

    with pytest.warns(FutureWarning, match="Engine"):
        old = ShardedDB(sample_db, None, shards=None)
    example = sample_db.motion(3)
    features = ["rknee_bent", "lknee_bent"]
    assert old.query_by_example(example, features, mode="adaptive").equals(
        Engine(sample_db).query(example, features=features, mode="adaptive"))


def test_indexes_built_on_demand_show_progress_when_asked(tmp_path, capsys):
    """`mocapviz reproduce` builds its indexes through the engine and shows the bar of their features (it lost it when
    the reproduction moved onto the engine); a built index loads without one. (The demo: a database of more than
    PROGRESS_MIN_DOCUMENTS documents shows a bar.)"""
    import shutil

    from mocapviz import MotionDB

    shutil.copytree(MotionDB.demo().path, tmp_path / "db.mdb")
    shutil.rmtree(tmp_path / "db.mdb" / "index", ignore_errors=True)
    engine = Engine(MotionDB.open(tmp_path / "db.mdb"))
    built = engine.indexes("2005", progress=True)
    assert "relational features" in capsys.readouterr().err
    again = Engine(MotionDB.open(tmp_path / "db.mdb")).indexes("2005", progress=True)
    assert capsys.readouterr().err == "" and sorted(again) == sorted(built)


def test_the_neighbours_of_a_file_frame_are_those_of_its_document(sample_db):
    """kNN of a frame of a take that is no document (an uploaded take, the Similarity page's kNN): the source file of a
    document, read as every use case reads an example, has the neighbours of that document's frame with its own
    document kept (the same rows, the same distances); a frame outside the take is refused naming its range."""
    engine = Engine(sample_db)
    path = sample_db.document(7)["path"]
    for frame in (0, 40, int(sample_db.document(7)["n_frames"]) - 1):
        from_file = engine.neighbours(path, frame, k=8)
        own = engine.neighbours(7, frame, k=8, exclude_document=False)
        assert from_file[["doc_id", "start", "end"]].equals(own[["doc_id", "start", "end"]])
        assert np.allclose(from_file["distance"], own["distance"], atol=1e-4)
    with pytest.raises(MocapvizError, match="the example has frames 0.."):
        engine.neighbours(path, 10_000, k=2)
