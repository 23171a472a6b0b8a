"""The lower bounds of mocapviz.relational.templates and the exact top-K template search by lower bounds (issue 43, 1): the bounds
never exceed a document's best cost (brute force), and the bounded search gives the full pass's answer on every
class of the demo database, on random templates (hypothesis) and, in the slow tier, on every class of HDM05 and of
Bandai Namco 1."""

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import MotionDB
from mocapviz.engine import Engine
from mocapviz.features import feature_names, relational_features
from mocapviz.relational.templates import (
    document_codes,
    document_costs,
    find_instances,
    learn_class,
    learn_template,
    quantised_distance,
    row_bounds,
    run_bounds,
    search_template,
    steepest_rows,
)


@pytest.fixture(scope="module")
def demo():
    """The demo database (30 Hz), its 2006 relational values and document starts."""
    db = MotionDB.demo()
    values, _ = relational_features(db, "2006", progress=False)
    return db, values, db.documents["start"].to_numpy()


def _same_answer(full, bounded):
    """The same matches and costs, best first; matches of equal cost may come in another order."""
    assert np.array_equal(full["cost"].to_numpy(), bounded["cost"].to_numpy())
    key = ["cost", "doc_id", "start", "end"]
    a = full[key].sort_values(key, ignore_index=True)
    b = bounded[key].sort_values(key, ignore_index=True)
    assert a.equals(b), f"full pass:\n{full}\nbounded:\n{bounded}"


def _every_class_equal(db, values, group, options):
    starts = db.documents["start"].to_numpy()
    labels = sorted(db.documents["label"].dropna().unique())
    assert labels
    for label in labels:
        template = learn_class(db, label, values=values, group=group, max_examples=16)
        for n_matches, delta in options:
            full = find_instances(template, values, starts, n_matches=n_matches, delta=delta, bounds=False)
            bounded = find_instances(template, values, starts, n_matches=n_matches, delta=delta)
            _same_answer(full, bounded)
            assert bounded.attrs["aligned"] <= full.attrs["aligned"] == len(values)


def test_the_row_bound_is_the_brute_force_sum_of_row_minima(demo):
    """Computed another way: the (m, n) matching costs of every frame, each row's least in each document, summed."""
    db, values, starts = demo
    template = learn_class(db, "kickLFront1Reps", values=values)
    q = template.quantised(0.2)
    local = quantised_distance(q, values)
    edges = np.r_[starts, len(values)]
    brute = [local[:, a:b].min(axis=1).sum() for a, b in itertools.pairwise(edges)]
    np.testing.assert_allclose(row_bounds(q, document_codes(values, starts)), brute, rtol=0, atol=1e-12)


@pytest.mark.parametrize("label", ["kickLFront1Reps", "squat1Reps", "Oiduki", "throwBasketball"])
@pytest.mark.parametrize("delta", [0.1, 0.2, 0.35])
def test_no_bound_exceeds_a_documents_best_cost(demo, label, delta):
    """Brute force: every document's least match cost by the full pass (document_costs), with and without the
    rule on rows per frame; both bounds are at most that, and the run bound, which keeps the order, is above the
    row bound somewhere."""
    db, values, starts = demo
    template = learn_class(db, label, values=values)
    q = template.quantised(delta)
    codes = document_codes(values, starts)
    rows = row_bounds(q, codes)
    for max_rows in (None, 0):
        best = document_costs(template, values, starts, delta=delta, max_rows=max_rows) * len(q)
        runs = run_bounds(q, codes, np.arange(len(starts)), steepest_rows(template) if max_rows is None else 0)
        assert (rows <= best + 1e-9).all() and (runs <= best + 1e-9).all()
        assert (runs > rows + 1e-6).any()


def test_the_bounded_search_equals_the_full_pass_on_every_demo_class(demo):
    """Every class of the demo database (44 HDM05 clips of 4 actors, 8 CMU trials, 2 C3D takes; its labels),
    learned from its documents, searched for K = 3, 10, 20 at δ = 0.1, 0.2, 0.3."""
    db, values, _ = demo
    _every_class_equal(db, values, "actor", [(3, 0.3), (10, 0.1), (20, 0.2)])


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_templates_give_the_full_pass_answer(demo, data):
    """A template learned from 1 to 4 random documents of the demo (or stretches of them), random K, δ and max
    cost: the bounded search's answer is the full pass's."""
    _, values, starts = demo
    edges = np.r_[starts, len(values)]
    chosen = data.draw(st.lists(st.integers(0, len(starts) - 1), min_size=1, max_size=4, unique=True), label="docs")
    examples = []
    for d in chosen:
        a, b = int(edges[d]), int(edges[d + 1])
        lo = data.draw(st.integers(a, max(a, b - 20)), label="from")
        hi = data.draw(st.integers(min(b, lo + 10), min(b, lo + 150)), label="to")
        examples.append(values[lo:hi])
    template = learn_template(examples, feature_names("2006"), iterations=3)
    n_matches = data.draw(st.integers(1, 40), label="K")
    delta = data.draw(st.floats(0.05, 0.45), label="delta")
    max_cost = data.draw(st.one_of(st.none(), st.floats(0.0, 0.5)), label="max_cost")
    max_rows = data.draw(st.sampled_from([None, 0]), label="max_rows")
    options = {"n_matches": n_matches, "delta": delta, "max_cost": max_cost, "max_rows": max_rows}
    full = find_instances(template, values, starts, bounds=False, **options)
    _same_answer(full, find_instances(template, values, starts, **options))


def test_search_template_and_the_engine_search_by_bounds_by_default(demo):
    """search_template and Engine.search_template: the bounded search unless asked for the full pass, the same
    hits either way, and the share of frames aligned says which ran."""
    db, values, _ = demo
    template = learn_class(db, "hopBothLegs1hops", values=values)
    full = search_template(db, template, n_matches=5, delta=0.2, values=values, lower_bounds=False)
    bounded = search_template(db, template, n_matches=5, delta=0.2, values=values)
    _same_answer(full, bounded)
    assert full.attrs["aligned"] == 1.0 and bounded.attrs["aligned"] < 1.0
    engine = Engine(db)
    hits = engine.search_template(template, n_matches=5, delta=0.2)
    _same_answer(full, hits)
    assert hits.attrs["aligned"] < 1.0
    assert engine.search_template(template, n_matches=5, delta=0.2, lower_bounds=False).attrs["aligned"] == 1.0


@pytest.mark.slow
def test_the_bounded_search_equals_the_full_pass_on_every_hdm05_class(hdm05_db30):
    """All 287 HDM05 cut clips at 30 Hz: every class (at most 16 examples each), K = 20 at δ = 0.2 (the dashboard's)
    and K = 50 at δ = 0.1 (bench_templates')."""
    values, _ = relational_features(hdm05_db30, "2006", progress=False)
    _every_class_equal(hdm05_db30, values, "actor", [(20, 0.2), (50, 0.1)])


@pytest.mark.slow
def test_the_bounded_search_equals_the_full_pass_on_every_bandai_namco_class(bandai1_dir, tmp_path_factory):
    """Bandai Namco 1 (174 takes of 16 contents in 15 styles) at 30 Hz: every content learned from its takes,
    grouped by style, K = 20 at δ = 0.2 and K = 50 at δ = 0.1."""
    db = MotionDB.ingest([bandai1_dir], tmp_path_factory.mktemp("bandai1-30") / "db", fps=30, progress=False)
    values, _ = relational_features(db, "2006", progress=False)
    _every_class_equal(db, values, "style", [(20, 0.2), (50, 0.1)])
