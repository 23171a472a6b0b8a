"""Every parameter declared once (issue 38, 2): docs/parameters.md is the table; every command's option defaults to
the table's default for its use case and accepts exactly what the engine accepts (random values, hypothesis); the
engine refuses a value outside the table's bounds before any work, naming the parameter; the pages' defaults are the
table's."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapviz import Engine, MotionDB
from mocapviz.cli import build_parser
from mocapviz.engine.parameters import PARAMETERS, USE_DEFAULTS, default, markdown
from mocapviz.errors import ParameterError

DOCS = Path(__file__).resolve().parents[1] / "docs" / "parameters.md"

# (command words, use case, {option dest: parameter}) for every command made from the table
COMMANDS = [
    (["search"], "clips", ["n_matches", "numeric_set", "mode", "exclude_document", "paths"]),
    (["knn"], "knn", ["k", "numeric_set", "radius", "eps", "exclude_document", "per_document"]),
    (["match"], "match", ["numeric_set", "n_matches", "method", "min_length", "paths"]),
    (["query"], "query", ["query_mode", "relational_set"]),
    (["find"], "find", ["n_matches", "template_cost"]),
    (["template", "search"], "search_template", ["n_matches", "delta", "max_cost", "prefilter", "lower_bounds"]),
    (["template", "learn"], "learn_template", ["relational_set", "max_examples"]),
]


def _subparser(words):
    parser = build_parser()
    for word in words:
        action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = action.choices[word]
    return parser


def _action(parser, dest):
    return next(a for a in parser._actions if a.dest == dest)


@pytest.fixture(scope="module")
def engine():
    return Engine(MotionDB.sample())


def test_the_documentation_is_the_table():
    text = DOCS.read_text(encoding="utf-8")
    assert text.endswith(markdown()), "docs/parameters.md is out of date: its table is engine.parameters.markdown()"
    for name in PARAMETERS:
        assert f"| `{name}` |" in text


@pytest.mark.parametrize("words, use, names", COMMANDS, ids=[" ".join(c[0]) for c in COMMANDS])
def test_every_command_defaults_to_the_tables_default(words, use, names):
    parser = _subparser(words)
    for name in names:
        action = _action(parser, name)
        assert action.default == default(use, name), (words, name)
        assert PARAMETERS[name].doc in action.help, (words, name)  # --help says what the table says


def test_a_use_case_default_is_used_by_the_engine_method(engine):
    import inspect

    checked = 0
    for (use, name), value in USE_DEFAULTS.items():
        method = getattr(engine, use)
        for arg in (a for a, p in method.parameters.items() if p.name == name):  # find checks its K itself
            assert inspect.signature(method).parameters[arg].default == value, (use, name)
            checked += 1
    assert checked >= len(USE_DEFAULTS) - 1


def _cli_accepts(parameter, text: str) -> bool:
    try:
        parameter.reader("--x")(text)
    except argparse.ArgumentTypeError:
        return False
    return True


def _engine_accepts(parameter, value) -> bool:
    try:
        parameter.check(value)
    except ParameterError:
        return False
    return True


NUMBERS = [p for p in PARAMETERS.values() if p.kind in ("int", "float")]


@settings(max_examples=300, deadline=None)
@given(data=st.data())
def test_the_command_line_accepts_exactly_what_the_engine_accepts(data):
    """A random number, written as text, is read by the option iff the engine takes the number (no front accepts
    what the run refuses, and none refuses what it takes)."""
    parameter = data.draw(st.sampled_from(NUMBERS), label="parameter")
    if parameter.kind == "int":
        value = data.draw(st.integers(-5, 10**6), label="value")
    else:
        value = data.draw(st.floats(-2.0, 1e4) | st.sampled_from([0.0, 0.5, 1.0, math.inf, math.nan]),
                          label="value")  # fmt: skip
    assert _cli_accepts(parameter, repr(value) if parameter.kind == "float" else str(value)) == \
        _engine_accepts(parameter, value), (parameter.name, value)


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_the_engine_refuses_a_value_outside_the_table_naming_it(engine, data):
    use, arg = data.draw(st.sampled_from([(u, a) for u in ("clips", "stretches", "knn", "match", "query",
                                                           "search_template", "learn_template", "neighbours")
                                          for a, p in getattr(Engine, u).parameters.items()
                                          if p.kind in ("int", "float", "choice")]), label="argument")  # fmt: skip
    parameter = getattr(Engine, use).parameters[arg]
    if parameter.kind == "choice":
        bad = data.draw(st.sampled_from(["x", "", "F16E", "2007", "EXACT"]), label="value")
    elif parameter.low is not None:
        bad = parameter.low - data.draw(st.sampled_from([1, 0.5, 1e-9] if parameter.kind == "float" else [1, 5]))
        bad = bad if parameter.kind == "float" else int(bad)
        if parameter.low_open and parameter.kind == "float":
            bad = parameter.low
    else:
        bad = parameter.high + 1
    args = {"clips": (3,), "stretches": (3,), "knn": ([0.0] * 45,), "match": (3,), "query": (3,),
            "search_template": ("nope",), "learn_template": ("kickLFront1Reps",), "neighbours": (3, 0)}[use]
    with pytest.raises(ParameterError) as refused:
        getattr(engine, use)(*args, **{arg: bad})
    assert arg in str(refused.value) or parameter.name.replace("_", " ") in str(refused.value)


def test_a_new_parameter_reaches_every_front_from_the_table(sample_db, tmp_path, capsys):
    """`iterations` was added to learn_template by a row of the table, its name in USES, the engine method's
    keyword and this test: the command line offers it (with its bounds and default) and the template learned
    through it is the engine's."""
    from mocapviz.cli import main

    assert _action(_subparser(["template", "learn"]), "iterations").default == default("learn_template", "iterations")
    out = tmp_path / "t.npz"
    args = ["template", "learn", str(sample_db.path), "--label", "squat1Reps", "--iterations", "1", "--out", str(out)]
    assert main(args) == 0
    assert "1 iteration," in capsys.readouterr().out  # the count word agrees (was "1 iterations")
    from mocapviz.engine import MotionTemplate

    once = MotionTemplate.load(out)
    assert once.iterations == 1 and np.array_equal(
        once.values, Engine(sample_db).learn_template("squat1Reps", iterations=1).values)
    assert main([*args[:-4], "--iterations", "0"]) == 2
    assert "--iterations must be at least 1" in capsys.readouterr().err


def test_the_tables_bounds_are_the_kernels():
    """The kernels check their own arguments for their direct callers with an Interval; the table (loaded by
    `mocapviz --help`, which cannot import them) states the same bounds."""
    from mocapviz.relational.templates import DELTA_RANGE, MAX_COST_RANGE
    from mocapviz.validation import MIN_LENGTH_RANGE

    for name, interval in (("delta", DELTA_RANGE), ("max_cost", MAX_COST_RANGE), ("min_length", MIN_LENGTH_RANGE)):
        p = PARAMETERS[name]
        assert (p.low, p.high, p.low_open, p.high_open) == (interval.low, interval.high, interval.low_open,
                                                            interval.high_open), name  # fmt: skip


def test_the_pages_defaults_are_the_tables():
    from mocapviz.app.pages import describe, templates

    assert templates.DEFAULT_DELTA == default("search_template", "delta")
    assert templates.DEFAULT_MATCHES == default("search_template", "n_matches")
    assert templates.MAX_EXAMPLES == default("learn_template", "max_examples")
    assert describe.DEFAULT_MATCHES == default("find", "n_matches")


def test_the_similarity_pages_boxes_start_at_the_tables_defaults(sample_db):
    from mocapviz.app.backend import Backend
    from mocapviz.app.pages.similarity import SimilarityPage
    from mocapviz.app.state import Selection

    page = SimilarityPage(Backend(sample_db), Selection(doc=0, span=(0, 10)))
    assert page.search_mode.value == default("clips", "mode")
    assert page.search_k.value == default("clips", "n_matches")
    assert page.numeric_set.value == default("clips", "numeric_set")
    assert page.knn_k.value == default("knn", "k")
    assert page.match_count_k.value == default("match", "n_matches")
    assert page.exclude_own.value == default("clips", "exclude_document")
    for box in (page.search_k, page.knn_k, page.match_count_k, page.match_k):  # the table's lower bound
        assert box.start == 1 == PARAMETERS["n_matches"].low == PARAMETERS["k"].low


def test_the_templates_pages_boxes_take_the_tables_bounds(sample_db):
    from mocapviz.app.backend import Backend
    from mocapviz.app.pages.templates import TemplatesPage
    from mocapviz.app.state import Selection

    page = TemplatesPage(Backend(sample_db), Selection(doc=0, span=(0, 10)))
    delta = PARAMETERS["delta"]
    assert (page.delta.value, page.delta.start, page.delta.end) == (default("search_template", "delta"), 0.01, 0.49)
    assert delta.low < page.delta.start and page.delta.end < delta.high  # open ends: one step inside
    assert (page.max_cost.start, page.max_cost.end, page.max_cost.value) == (0.0, 1.0, None)
