"""The package's layers (docs/architecture.md): every import points to the same or a lower layer, and the imports
run when a module is loaded form no cycle. Read from the source with :mod:`ast` (function-level imports count for
the layering too), so a test fails the moment an import points the wrong way."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "mocapviz"
ARCHITECTURE = PACKAGE.parent / "docs" / "architecture.md"

# lowest first; a module belongs to the first entry that is it or one of its parents
LAYERS = [
    ("base", ["mocapviz._lazy", "mocapviz._moved", "mocapviz._version", "mocapviz.errors", "mocapviz.validation",
              "mocapviz.parallel", "mocapviz.store", "mocapviz.checked_map",
              "mocapviz.heap"]),
    ("motion", ["mocapviz.motion"]),
    ("io", ["mocapviz.io"]),
    ("db", ["mocapviz.db"]),
    ("export", ["mocapviz.export"]),
    ("features", ["mocapviz.features"]),
    ("match", ["mocapviz.match"]),
    ("relational", ["mocapviz.relational"]),
    ("similarity", ["mocapviz.similarity"]),
    ("sharded", ["mocapviz.sharded"]),
    ("experiments", ["mocapviz.experiments"]),
    ("viz", ["mocapviz.viz"]),
    ("runners", ["mocapviz.app", "mocapviz.cli", "mocapviz.reproduction", "mocapviz.integrity"]),
]


def _modules() -> dict[str, Path]:
    out = {}
    for f in sorted(PACKAGE.rglob("*.py")):
        parts = list(f.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = f
    return out


MODULES = _modules()


def layer(module: str) -> int:
    for rank, (_, prefixes) in enumerate(LAYERS):
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return rank
    raise AssertionError(f"{module} is in no layer of tests/test_architecture.py: add it, and to docs/architecture.md")


def _imports(module: str) -> list[tuple[str, bool, int]]:
    """(imported mocapviz module, at module level?, line) of every import statement of ``module``."""
    f = MODULES[module]
    package = module if f.name == "__init__.py" else module.rpartition(".")[0]
    tree = ast.parse(f.read_text())
    top = {id(node) for node in tree.body}
    top |= {id(n) for node in tree.body if isinstance(node, ast.If) for n in node.body}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names if a.name.split(".")[0] == "mocapviz"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            if source.split(".")[0] != "mocapviz":
                continue
            names = [f"{source}.{a.name}" if f"{source}.{a.name}" in MODULES else source for a in node.names]
        else:
            continue
        for name in dict.fromkeys(names):
            while name not in MODULES and "." in name:
                name = name.rpartition(".")[0]
            out.append((name, id(node) in top, node.lineno))
    return out


def test_every_module_is_in_a_layer_and_the_architecture_names_each_layer():
    text = ARCHITECTURE.read_text()
    for module in MODULES:
        if module != "mocapviz":
            layer(module)
    for name, prefixes in LAYERS:
        for prefix in prefixes:
            shown = prefix.removeprefix("mocapviz.").replace(".", "/")
            assert re.search(rf"\b{re.escape(shown)}\b", text), f"docs/architecture.md does not mention {shown}"


def test_imports_point_down_only():
    wrong = []
    for module in MODULES:
        if module == "mocapviz":
            continue
        for target, _, line in _imports(module):
            if target != "mocapviz" and layer(target) > layer(module):
                wrong.append(f"{MODULES[module].relative_to(PACKAGE.parent)}:{line} ({LAYERS[layer(module)][0]}) "
                             f"imports {target} ({LAYERS[layer(target)][0]})")
    assert not wrong, "imports against the layers:\n" + "\n".join(wrong)


def test_no_module_imports_the_package_root():
    """The root re-exports lazily; a module importing it would load every layer (and close a cycle)."""
    offenders = [f"{m}:{line}" for m in MODULES if m != "mocapviz" for t, _, line in _imports(m) if t == "mocapviz"]
    assert not offenders, offenders


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_no_import_cycle_at_load_time():
    graph = {m: {t for t, top, _ in _imports(m) if top and t != m} for m in MODULES}
    cycle = _cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_no_cycle_between_layers_even_through_function_level_imports():
    """Function-level imports are only ever a way to load a module late, never to reach upwards."""
    graph: dict[str, set[str]] = {}
    for m in MODULES:
        if m == "mocapviz":
            continue
        for t, _, _ in _imports(m):
            if t != "mocapviz" and layer(t) != layer(m):
                graph.setdefault(LAYERS[layer(m)][0], set()).add(LAYERS[layer(t)][0])
    assert _cycle(graph) is None


def test_cycle_finder_finds_a_cycle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": {"c"}}) is None


@pytest.mark.parametrize("module", ["mocapviz.search", "mocapviz.database", "mocapviz.batch"])
def test_old_module_paths_still_import_with_a_warning_naming_the_new_place(module):
    import importlib
    import sys

    sys.modules.pop(module, None)
    with pytest.warns(FutureWarning, match="moved to mocapviz\\."):
        old = importlib.import_module(module)
    name = {"mocapviz.search": "SimilaritySearch", "mocapviz.database": "MotionDB", "mocapviz.batch": "map_ordered"}
    assert getattr(old, name[module]).__module__.startswith(("mocapviz.similarity", "mocapviz.db", "mocapviz.parallel"))
