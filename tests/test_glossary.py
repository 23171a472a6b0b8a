"""One name per concept (docs/glossary.md): no public signature of mocapviz uses a retired parameter name, and every
old name kept for the README's and notebooks' sake (``mocapviz.validation.renamed``) still works, with a
FutureWarning that names the new one and the same result."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import warnings

import numpy as np
import pytest

import mocapviz
from mocapviz.cli import build_parser
from mocapviz.errors import ParameterError
from mocapviz.match import lng, subsequence_dtw
from mocapviz.similarity.knn import KnnIndex
from mocapviz.validation import renamed

# retired for: relational_set / numeric_set, n_matches, numeric_sets, threads, threads
RETIRED = ("feature_set", "k_matches", "sets", "n_jobs", "workers")
SKIPPED = ("mocapviz.app",)  # the dashboard imports panel and bokeh (seconds); its pages call the functions below
# the aliases the README and notebooks need for matches and numeric sets: function -> {old: new}
KNOWN_ALIASES = {
    "mocapviz.match.time_warping.subsequence_dtw": {"k": "n_matches"},
    "mocapviz.match.neighbourhood_graph.lng": {"k_matches": "n_matches"},
    "mocapviz.experiments.matching.lng_accuracy": {"feature_set": "numeric_set"},
    "mocapviz.experiments.matching.similarity_matrices": {"sets": "numeric_sets", "k_matches": "n_matches"},
    "mocapviz.experiments.matching.numerical_search": {"k_matches": "n_matches"},
}
_RENAMED_CODE = renamed(old="new")(lambda: None).__code__  # every @renamed wrapper runs this code object


def _modules(package=mocapviz):
    """The package and its modules, recursively, without importing the skipped ones (``pkgutil.walk_packages``
    would import every subpackage to look inside)."""
    if package is mocapviz:
        yield package
    for info in pkgutil.iter_modules(package.__path__, package.__name__ + "."):
        if info.name.startswith(SKIPPED):
            continue
        module = importlib.import_module(info.name)
        yield module
        if info.ispkg:
            yield from _modules(module)


def _public_callables():
    """(qualified name, callable) of every public function, class and method defined in the package."""
    seen = set()
    for module in _modules():
        for name, obj in vars(module).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
                continue
            if inspect.isclass(obj):
                members = [("__init__", obj.__dict__.get("__init__"))] + [
                    (n, m) for n, m in vars(obj).items() if not n.startswith("_")]  # fmt: skip
                for n, m in members:
                    m = m.__func__ if isinstance(m, (staticmethod, classmethod)) else m
                    if inspect.isfunction(m) or hasattr(m, "py_func"):
                        yield f"{module.__name__}.{name}.{n}", m
            elif (inspect.isfunction(obj) or hasattr(obj, "py_func")) and id(obj) not in seen:
                seen.add(id(obj))
                yield f"{module.__name__}.{name}", obj


def real_function(fn):
    """The function as written: below every decorator (``@renamed``'s wrapper takes ``*args, **kwargs``) and a
    numba dispatcher's Python function."""
    fn = inspect.unwrap(fn)
    return getattr(fn, "py_func", fn)


def real_parameters(fn) -> list[str]:
    return list(inspect.signature(real_function(fn), follow_wrapped=False).parameters)


def aliases(fn) -> dict[str, str]:
    """{old: new} of a ``@renamed`` wrapper (read from its closure), else {}."""
    if getattr(fn, "__code__", None) is not _RENAMED_CODE:
        return {}
    cells = dict(zip(fn.__code__.co_freevars, (c.cell_contents for c in fn.__closure__)))
    return dict(cells["old_to_new"])


PUBLIC = dict(_public_callables())
RENAMED = {name: aliases(fn) for name, fn in PUBLIC.items() if aliases(fn)}


def test_the_walk_sees_the_package():
    assert len(PUBLIC) > 200
    assert "mocapviz.similarity.search.SimilaritySearch.__init__" in PUBLIC and "mocapviz.relational.index.build" in PUBLIC
    assert "mocapviz.match.pruned.search_ranges" in PUBLIC  # numba kernels too


def test_real_signatures_look_below_the_alias_wrappers():
    """``inspect.signature`` follows ``__wrapped__``; the check must not be fooled either way: the wrapper itself
    shows only ``*args, **kwargs``, the real function the new names."""
    wrapper = PUBLIC["mocapviz.match.time_warping.subsequence_dtw"]
    assert list(inspect.signature(wrapper, follow_wrapped=False).parameters) == ["args", "kwargs"]
    assert "n_matches" in real_parameters(wrapper) and "k" not in real_parameters(wrapper)


@pytest.mark.parametrize("retired", RETIRED)
def test_no_public_parameter_uses_a_retired_name(retired):
    offenders = [name for name, fn in PUBLIC.items() if retired in real_parameters(fn)]
    assert not offenders, f"parameter {retired!r} (docs/glossary.md) still in: {', '.join(offenders)}"


def test_the_old_names_the_readme_and_notebooks_use_are_kept():
    for name, old_to_new in KNOWN_ALIASES.items():
        assert RENAMED.get(name, {}) == old_to_new, name


@pytest.mark.parametrize("name", sorted(RENAMED))
def test_every_alias_warns_names_the_new_parameter_and_refuses_both(name):
    fn = PUBLIC[name]
    params = inspect.signature(real_function(fn), follow_wrapped=False).parameters
    required = [p for p in params.values() if p.default is p.empty and p.kind is p.POSITIONAL_OR_KEYWORD]
    assert required, "the calls below rely on a missing argument to stop before any work"
    for old, new in RENAMED[name].items():
        assert new in params and old not in params
        # the warning comes first, then the call is made (and stops at the missing arguments)
        with pytest.warns(FutureWarning, match=f"{old}= is deprecated; pass {new}="), pytest.raises(TypeError,
                                                                                               match="missing"):
            fn(**{old: None})
        with pytest.raises(ParameterError, match=f"pass {new}= only"):
            fn(**{old: None, new: None})


@pytest.fixture(scope="module")
def walk():
    """A random walk of 3 documents (2-D features) and its document starts."""
    rng = np.random.default_rng(7)
    x = np.cumsum(rng.normal(size=(600, 2)), axis=0)
    return x, np.array([0, 200, 420])


def _same(a, b):
    assert a[["doc_id", "start", "end"]].equals(b[["doc_id", "start", "end"]])
    np.testing.assert_array_equal(a["cost"], b["cost"])
    for p, q in zip(a["path"], b["path"]):
        np.testing.assert_array_equal(p, q)


def test_subsequence_dtw_k_is_n_matches(walk):
    x, starts = walk
    q = x[250:280]
    new = subsequence_dtw(q, x, starts, n_matches=4)
    with pytest.warns(FutureWarning, match="n_matches="):
        old = subsequence_dtw(q, x, starts, k=4)
    assert len(new) == 4
    _same(old, new)


def test_lng_k_matches_is_n_matches(walk):
    x, starts = walk
    q, index = x[250:280], KnnIndex(x)
    new = lng(q, index, k=256, n_matches=3, starts=starts)
    with pytest.warns(FutureWarning, match="n_matches="):
        old = lng(q, index, k=256, k_matches=3, starts=starts)
    assert len(new) == 3
    _same(old, new)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new name: no warning
        lng(q, index, k=256, n_matches=3, starts=starts)


@pytest.mark.parametrize(("old", "new"), [
    (["query", "DB", "--example", "0", "--top", "5"], ["query", "DB", "--example", "0", "-K", "5"]),
    (["query", "DB", "--example", "0", "--feature-set", "2006"], ["query", "DB", "--example", "0", "--relational-set", "2006"]),
    (["index", "DB", "--feature-set", "2006"], ["index", "DB", "--relational-set", "2006"]),
    (["features", "DB", "--sets", "F15E"], ["features", "DB", "--numeric-sets", "F15E"]),
    (["knn", "DB", "--frame", "0:1", "--features", "F30E"], ["knn", "DB", "--frame", "0:1", "--numeric-set", "F30E"]),
    (["match", "DB", "--example", "0", "--features", "F30E", "-K", "3"],
     ["match", "DB", "--example", "0", "--numeric-set", "F30E", "--matches", "3"]),
    (["search", "DB", "--example", "0", "--features", "F30E", "-K", "3"],
     ["search", "DB", "--example", "0", "--numeric-set", "F30E", "--matches", "3"]),
])  # fmt: skip
def test_cli_options_follow_the_glossary_and_keep_their_old_spellings(old, new):
    parser = build_parser()
    a, b = vars(parser.parse_args(old)), vars(parser.parse_args(new))
    assert a == b


def test_cli_k_is_neighbours_and_K_matches():
    args = build_parser().parse_args(["match", "DB", "--example", "0", "-k", "64", "-K", "7"])
    assert (args.k, args.n_matches) == (64, 7)
