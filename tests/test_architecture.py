"""The package's layers (docs/architecture.md): every import points to the same or a lower layer, the runners import
the engine, viz, io and the base modules only, the imports run when a module is loaded form no cycle, and the
modules form no cycle even through imports inside functions.

The checker, :func:`check`, is a function of a source tree (a folder holding ``mocapviz/`` and
``docs/architecture.md``): the tests run it on this checkout, and on modified copies of it written to ``tmp_path``
to show that each kind of violation is reported. It reads the source with :mod:`ast`, never imports it, and finds
every import however it is written:

- ``import`` / ``from ... import`` statements anywhere: at the top level, inside ``try:``, ``if``, ``with``, loops
  and class bodies (all run when the module is loaded), inside functions (run later), under
  ``if TYPE_CHECKING:`` (never run: type references);
- ``importlib.import_module("...")`` and ``__import__("...")`` with a literal name (a computed name is refused
  outside the modules of :data:`DYNAMIC`, whose inputs are read instead);
- the tables of ``lazy_exports(package, {...})`` (``mocapviz._lazy``), read as imports of the package that run
  when a name is first used; ``from pkg import Name`` of a lazily exported ``Name`` imports its module then too;
- the table ``MOVED`` of ``mocapviz/_moved.py`` (old module paths and the modules that stand for them).

The layers are read from the table of docs/architecture.md ("The layers"), the one place that says which modules
each holds; its rows' order must also equal :data:`ORDER`, so that any reordering fails, not only one against the
imports. Cycles are looked for twice: among the imports run at load, and among all imports that may run (inside
functions and through lazy tables too) except TYPE_CHECKING ones and a module's imports of its own package.
"""

from __future__ import annotations

import ast
import functools
import importlib
import itertools
import re
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "mocapviz"
ARCHITECTURE = Path("docs") / "architecture.md"
MOVED_MODULE = f"{PACKAGE}._moved"

DYNAMIC = {
    f"{PACKAGE}._lazy": "imports the modules of the lazy_exports tables, which are read from each package",
    f"{PACKAGE}._moved": "imports the new modules of its MOVED table, which is read from _moved.py",
    f"{PACKAGE}.io.isolated": "imports, in its helper process, the module of a function its caller already holds",
}
"""Modules allowed to import a computed module name, and why the checker still sees what they import."""

ORDER = ["base", "motion", "io", "db", "export", "features", "match", "relational", "similarity", "experiments",
         "engine", "viz", "runners", "root"]
"""The layers, lowest first, as docs/architecture.md's table orders them. The checker reads the layers from the
table; this copy of their order makes any reordering of its rows fail, even one the imports allow (export and
features, features and match, engine and viz, runners and root import nothing of each other)."""

RUNNERS = "runners"
RUNNER_IMPORTS = ("base", "io", "engine", "viz", RUNNERS)
"""The layers a module of the runners layer may import: the fronts go through the engine, which offers what they use
of the layers below it (mocapviz/engine/library.py); nothing of motion, db, export, features, match, relational,
similarity or experiments directly."""

ALLOWED: dict[str, str] = {}
"""Violations tolerated for now: the checker's message -> the issue that removes it. Empty: none is tolerated."""


@dataclass(frozen=True)
class Import:
    """One import of a module of the package found in another module's source."""

    source: str  # the importing module
    target: str  # the imported module
    line: int
    how: str  # the kind of import, for the messages: "import", "function-level import", "lazy_exports string", ...
    load: bool  # runs when ``source`` is loaded
    typing: bool = False  # under ``if TYPE_CHECKING:``: never runs


# --------------------------------------------------------------------------------------------------- the source tree
def modules(root: Path) -> dict[str, Path]:
    """Module name -> file of every module of the package under ``root`` (a package is its ``__init__.py``)."""
    out = {}
    for f in sorted((root / PACKAGE).rglob("*.py")):
        parts = list(f.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = f
    return out


def _member(token: str) -> str:
    """The module a name of the layer table stands for: ``io/`` and ``io`` -> mocapviz.io, ``cli.py`` ->
    mocapviz.cli, ``__init__.py`` -> the package root."""
    name = token.rstrip("/").removesuffix(".py").replace("/", ".")
    return PACKAGE if name == "__init__" else f"{PACKAGE}.{name}"


def layers(root: Path) -> list[tuple[str, list[str]]]:
    """The layers of docs/architecture.md's table "The layers", lowest first: (name, the modules and packages its
    "folder / modules" cell names outside parentheses)."""
    text = (root / ARCHITECTURE).read_text()
    section = text.partition("## The layers")[2].partition("\n## ")[0]
    out = []
    for row in re.findall(r"^\|(.*)\|\s*$", section, re.MULTILINE)[2:]:  # past the header and its rule
        name, cell = (c.strip() for c in row.split("|")[:2])
        while re.search(r"\([^()]*\)", cell):
            cell = re.sub(r"\([^()]*\)", "", cell)
        out.append((name, [_member(t) for t in re.findall(r"`([^`]+)`", cell)]))
    return out


def _layer_of(table: list[tuple[str, list[str]]]):
    """module -> index of its layer in ``table`` (the most specific entry that is it or a package holding it; the
    package root ``mocapviz`` stands for its own module only), or None."""

    def layer(module: str) -> int | None:
        best = None
        for rank, (_, members) in enumerate(table):
            for m in members:
                inside = module.startswith(m + ".") and m != PACKAGE  # the root layer holds the root module only
                if (module == m or inside) and (best is None or len(m) > len(best[1])):
                    best = (rank, m)
        return None if best is None else best[0]

    return layer


# ------------------------------------------------------------------------------------------------ reading the imports
def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")  # fmt: skip


def _call_name(call: ast.Call) -> str:
    func = call.func
    return func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""


class _Reader(ast.NodeVisitor):
    """Every import of one module: statements, ``import_module`` / ``__import__`` calls, ``lazy_exports`` tables,
    each with whether it runs at load and whether it is a TYPE_CHECKING one."""

    def __init__(self, module: str, package: str):
        self.module, self.package = module, package
        self.found: list[tuple[str, str, tuple[str, ...], int, str, bool]] = []  # (kind, base, names, line, how, load)
        self.problems: list[tuple[int, str]] = []
        self.depth = 0  # functions around the node
        self.typing = 0  # TYPE_CHECKING blocks around the node
        self.lazy: dict[str, str] = {}  # this package's lazy_exports table: public name -> module

    def _add(self, kind, base, names, line, how, later=False):
        """One import; ``later``: it runs after the module is loaded even when written at its top level."""
        how = "TYPE_CHECKING import" if self.typing else how
        self.found.append((kind, base, tuple(names), line, how, not (self.depth or self.typing or later)))

    def _statement_how(self) -> str:
        return "function-level import" if self.depth else "import"

    def visit_FunctionDef(self, node):
        for n in [*node.decorator_list, node.args, *([node.returns] if node.returns else [])]:
            self.visit(n)  # run when the function is defined
        self.depth += 1
        for n in node.body:
            self.visit(n)
        self.depth -= 1

    visit_AsyncFunctionDef = visit_FunctionDef

    def visit_Lambda(self, node):
        self.visit(node.args)
        self.depth += 1
        self.visit(node.body)
        self.depth -= 1

    def visit_If(self, node):
        self.visit(node.test)
        typing = _is_type_checking(node.test)
        self.typing += typing
        for n in node.body:
            self.visit(n)
        self.typing -= typing
        for n in node.orelse:
            self.visit(n)

    def visit_Import(self, node):
        for alias in node.names:
            self._add("module", alias.name, (), node.lineno, self._statement_how())

    def visit_ImportFrom(self, node):
        if node.level:
            parts = self.package.split(".")
            base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
        else:
            base = node.module or ""
        self._add("from", base, [a.name for a in node.names], node.lineno, self._statement_how())

    def visit_Call(self, node):
        self.generic_visit(node)
        name = _call_name(node)
        if name in ("import_module", "__import__"):
            self._dynamic(node, name)
        elif name == "lazy_exports":
            self._lazy_table(node)

    def _dynamic(self, node: ast.Call, name: str) -> None:
        arg = node.args[0] if node.args else None
        if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
            if self.module not in DYNAMIC:
                self.problems.append((node.lineno, (f"{name}() of a computed name: the checker cannot see what it "
                                                    f"imports (write the name, or list the module in DYNAMIC)")))
            return
        target = arg.value
        if target.startswith("."):
            anchor = self._package_argument(node.args[1] if len(node.args) > 1 else None)
            if anchor is None:
                self.problems.append((node.lineno, f"{name}({target!r}) without a readable package"))
                return
            target = _relative(target, anchor)
        self._add("module", target, (), node.lineno, f"{name} string")

    def _package_argument(self, arg) -> str | None:
        if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
            return arg.value
        if isinstance(arg, ast.Name) and arg.id in ("__name__", "__package__"):
            return self.module if arg.id == "__name__" else self.package
        return None

    def _lazy_table(self, node: ast.Call) -> None:
        anchor = self._package_argument(node.args[0] if node.args else None)
        table = _literal_table(node.args[1]) if len(node.args) > 1 else None
        if anchor is None or table is None:
            self.problems.append((node.lineno, ("lazy_exports with a table that is not a literal: the checker "
                                                "cannot read it (write the package and the dict out)")))
            return
        for public, (where, line) in table.items():
            target = _relative(where, anchor) if where.startswith(".") else where
            self.lazy[public] = target  # imported when the name is first used, not when the package is loaded
            self._add("module", target, (), line, "lazy_exports string", later=True)


def _relative(name: str, anchor: str) -> str:
    """``name`` (``.x``, ``..x``) as importlib resolves it against the package ``anchor``."""
    level = len(name) - len(name.lstrip("."))
    parts = anchor.split(".")
    return ".".join(parts[: len(parts) - level + 1] + ([name[level:]] if name[level:] else []))


def _literal_table(node: ast.expr) -> dict[str, tuple[str, int]] | None:
    """A dict of str -> str written as a literal (``**dict.fromkeys([...], "...")`` entries included), each value with
    the line it is written on; None for anything else."""
    if not isinstance(node, ast.Dict):
        return None
    out = {}
    for key, value in zip(node.keys, node.values):
        try:
            if key is None:  # ** of dict.fromkeys(names, where)
                if not (isinstance(value, ast.Call) and _call_name(value) == "fromkeys" and len(value.args) == 2):
                    return None
                where = (ast.literal_eval(value.args[1]), value.args[1].lineno)
                out.update(dict.fromkeys(ast.literal_eval(value.args[0]), where))
            else:
                out[ast.literal_eval(key)] = (ast.literal_eval(value), value.lineno)
        except ValueError:
            return None
    return out if all(isinstance(k, str) and isinstance(v, str) for k, (v, _) in out.items()) else None


def _moved_table(path: Path) -> dict[str, tuple[tuple[str, ...], int]] | None:
    """The ``MOVED`` table of ``_moved.py``: old module path -> (the modules that stand for it, line); None if it is
    not a literal."""
    for node in ast.parse(path.read_text()).body:
        targets = [node.target] if isinstance(node, ast.AnnAssign) else getattr(node, "targets", [])
        if any(isinstance(t, ast.Name) and t.id == "MOVED" for t in targets):
            if not isinstance(node.value, ast.Dict) or None in node.value.keys:
                return None
            try:
                return {ast.literal_eval(k): (tuple(ast.literal_eval(v)), k.lineno)
                        for k, v in zip(node.value.keys, node.value.values)}  # fmt: skip
            except ValueError:
                return None
    return None


def _bound(tree: ast.Module) -> set[str]:
    """The names a module binds when it is loaded (assignments, definitions, imports outside functions and classes):
    a package's lazy ``__getattr__`` is never asked for them."""
    out, todo = set(), list(tree.body)
    while todo:
        node = todo.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(node.name)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            out |= {(a.asname or a.name).split(".")[0] for a in node.names}
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            out.add(node.id)
        todo += ast.iter_child_nodes(node)
    return out


@dataclass
class Tree:
    """Everything the checker reads from a source tree."""

    files: dict[str, Path]
    imports: list[Import]
    problems: list[str]  # imports it could not read, of unknown or old modules


@functools.lru_cache(maxsize=1024)
def _read_module(module: str, package: str, text: str) -> _Reader:
    """The imports of one module's source ``text`` (cached by text: a modified copy of the tree parses only what
    changed). ``reader.lazy`` keeps only the lazy names the module does not bind itself."""
    reader = _Reader(module, package)
    source = ast.parse(text)
    reader.visit(source)
    bound = _bound(source)
    reader.lazy = {name: where for name, where in reader.lazy.items() if name not in bound}
    return reader


def read_tree(root: Path) -> Tree:
    """Read every import of every module of the package under ``root``."""
    files = modules(root)
    readers, problems = {}, []
    for module, f in files.items():
        package = module if f.name == "__init__.py" else module.rpartition(".")[0]
        readers[module] = reader = _read_module(module, package, f.read_text())
        problems += [f"{_where(root, f, line)}: {text}" for line, text in reader.problems]
    lazy = {module: reader.lazy for module, reader in readers.items()}
    table = _moved_table(files[MOVED_MODULE]) if MOVED_MODULE in files else {}
    if table is None:
        problems.append(f"{_where(root, files[MOVED_MODULE], 1)}: no literal MOVED table the checker can read")
    table = table or {}
    imports = [Import(MOVED_MODULE, target, line, "MOVED table", False) for targets, line in table.values()
               for target in targets]  # fmt: skip
    moved = {old: targets for old, (targets, _) in table.items()}
    for module, reader in readers.items():
        for kind, base, names, line, how, load in reader.found:
            for target, note in _resolve(kind, base, names, files, lazy, moved):
                if note:
                    problems.append(f"{_where(root, files[module], line)}: {note}")
                else:
                    imports.append(Import(module, target, line, how, load, how == "TYPE_CHECKING import"))
    return Tree(files, imports, problems)


def _resolve(kind, base, names, files, lazy, moved):
    """(module, None) for each module of the package an import reaches, (name, message) for one it cannot."""
    if base.split(".")[0] != PACKAGE:
        return
    if base in moved:
        yield base, f"imports the old path {base}: import {' or '.join(moved[base])} instead"
        return
    if kind == "module":
        module = base
        while module not in files and "." in module:
            module = module.rpartition(".")[0]
        if module != base and kind == "module":
            yield base, f"imports {base}, which is no module of the package"
        else:
            yield module, None
        return
    for name in names:
        full = f"{base}.{name}"
        if full in moved:
            yield full, f"imports the old path {full}: import {' or '.join(moved[full])} instead"
        elif full in files:
            yield full, None
        elif base in files:
            yield base, None
            if name in lazy[base]:  # from pkg import Name: pkg's __getattr__ imports Name's module now
                yield lazy[base][name], None
        else:
            yield base, f"imports from {base}, which is no module of the package"


def _where(root: Path, f: Path, line: int) -> str:
    return f"{f.relative_to(root).as_posix()}:{line}"


# ------------------------------------------------------------------------------------------------------ the checks
def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle (first node repeated at the end) per strongly connected component of ``graph`` that has one (a
    tangle: every node of it reaches every other)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components = []

    def connect(v):  # Tarjan's algorithm; the package has ~110 modules, far below the recursion limit
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(set(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return [_cycle_in(graph, c) for c in sorted(components, key=min)]


def _cycle_in(graph: dict[str, set[str]], component: set[str]) -> list[str]:
    """A shortest cycle through the first node (sorted) of a strongly connected ``component``."""
    start = min(component)
    paths = {start: [start]}
    queue = [start]
    while queue:
        v = queue.pop(0)
        for w in sorted(graph.get(v, ())):
            if w == start:
                return paths[v] + [start]
            if w in component and w not in paths:
                paths[w] = paths[v] + [w]
                queue.append(w)
    raise AssertionError("not a strongly connected component")


def _cycle_text(cycle: list[str], edges: dict[tuple[str, str], Import], root: Path, files: dict[str, Path]) -> str:
    steps = []
    for a, b in itertools.pairwise(cycle):
        e = edges[a, b]
        steps.append(f"{a} -> {b} ({_where(root, files[a], e.line)}, {e.how})")
    return "; ".join(steps)


def check(root: Path) -> list[str]:
    """Every violation of docs/architecture.md's rules in the source tree ``root``, as one message each.

    Parameters
    ----------
    root : pathlib.Path
        A folder holding the package (``mocapviz/``) and ``docs/architecture.md``.

    Returns
    -------
    list of str
        Messages naming the file and line: the layers in another order than :data:`ORDER`, a module in no
        layer, a layer naming no module, an import that points up (of any kind), a runner's import of a layer not
        in :data:`RUNNER_IMPORTS`, an import of the package root, of an old module path or of no module, an import
        the checker cannot read, a cycle of imports run at load,
        a cycle of modules through any import that may run (function-level and lazy ones included; TYPE_CHECKING
        imports never run and count for the layers only, and so do imports of a module's own package).
    """
    tree = read_tree(root)
    table = layers(root)
    problems = list(tree.problems)
    if not table:
        return problems + [f"{ARCHITECTURE}: no layer table under '## The layers'"]
    names = [name for name, _ in table]
    if names != ORDER:
        problems.append(f"{ARCHITECTURE}: the layers are, lowest first, {', '.join(names)}; ORDER in "
                        f"tests/test_architecture.py has {', '.join(ORDER)}: change both, and only on purpose")
    layer = _layer_of(table)
    for name, members in table:
        problems += [f"{ARCHITECTURE}: layer {name} names {m}, which is no module of the package"
                     for m in members if m not in tree.files]  # fmt: skip
    for module, f in tree.files.items():
        if layer(module) is None:
            problems.append(f"{_where(root, f, 1)}: {module} is in no layer of {ARCHITECTURE}'s table")
    problems += _layering(root, tree, table, layer)
    for name, keep in (("import cycle at load time", lambda e: e.load), ("module cycle", _runs_in_any_order)):
        edges: dict[tuple[str, str], Import] = {}
        for e in tree.imports:
            if keep(e) and e.source != e.target:
                edges.setdefault((e.source, e.target), e)  # the first line that imports it, for the message
        graph: dict[str, set[str]] = {}
        for a, b in edges:
            graph.setdefault(a, set()).add(b)
        problems += [f"{name}: {_cycle_text(c, edges, root, tree.files)}{_tangle(graph, c)}" for c in _cycles(graph)]
    return problems


def _tangle(graph: dict[str, set[str]], cycle: list[str]) -> str:
    """The other modules of the tangle ``cycle`` is one cycle of, for the message ("" when there are none)."""
    start = cycle[0]
    others = sorted(v for v in _reachable(graph, start) - set(cycle) if start in _reachable(graph, v))
    return f" (the same tangle holds {', '.join(others)})" if others else ""


def _reachable(graph: dict[str, set[str]], start: str) -> set[str]:
    seen, todo = {start}, [start]
    while todo:
        for w in graph.get(todo.pop(), ()):
            if w not in seen:
                seen.add(w)
                todo.append(w)
    return seen


def _runs_in_any_order(e: Import) -> bool:
    """Whether ``e`` counts for the module cycles: every import that may run, except one of a module's own package
    (``from . import NAME`` of a name defined in its ``__init__.py``): Python loads a module's packages before the
    module whatever it imports, and the package's lazy table points back at its modules by design."""
    return not e.typing and not e.source.startswith(e.target + ".")


def _layering(root: Path, tree: Tree, table, layer) -> list[str]:
    """An import of the package root, every import that points to a higher layer, and every import of a runner
    that points to a layer other than :data:`RUNNER_IMPORTS`."""
    out = []
    for e in tree.imports:
        where = _where(root, tree.files[e.source], e.line)
        if e.target == PACKAGE and e.source != MOVED_MODULE:
            out.append(f"{where}: {e.source} imports the package root ({e.how}): it re-exports every layer")
            continue
        low, high = layer(e.source), layer(e.target)
        if low is not None and high is not None and high > low:
            out.append(f"{where} ({table[low][0]}) imports {e.target} ({table[high][0]}): {e.how} against the layers")
        elif low is not None and high is not None and table[low][0] == RUNNERS and table[high][0] not in RUNNER_IMPORTS:
            out.append(f"{where} ({RUNNERS}) imports {e.target} ({table[high][0]}): {e.how}; the runners import "
                       f"{', '.join(RUNNER_IMPORTS[:-1])} and each other only (mocapviz.engine offers the rest)")
    return out


# -------------------------------------------------------------------------------------------------- this checkout
def test_the_package_keeps_the_layers_of_docs_architecture():
    problems = check(REPO)
    stale = sorted(set(ALLOWED) - set(problems))
    assert not stale, f"ALLOWED lists violations that are gone: remove them: {stale}"
    left = [p for p in problems if p not in ALLOWED]
    assert not left, "against docs/architecture.md:\n" + "\n".join(left)


def test_the_layer_table_is_read_from_the_architecture():
    table = layers(REPO)
    names = [name for name, _ in table]
    assert names[:3] == ["base", "motion", "io"] and names[-2:] == ["runners", "root"], names
    assert dict(table)["motion"] == ["mocapviz.motion"]
    assert dict(table)["runners"] == ["mocapviz.app", "mocapviz.cli", "mocapviz.reproduction", "mocapviz.integrity"]
    assert dict(table)["root"] == ["mocapviz", "mocapviz._moved"]
    assert "mocapviz._lazy" in dict(table)["base"] and "mocapviz._moved" not in dict(table)["base"]


def test_every_kind_of_import_is_read():
    """The checker sees the imports of this checkout that the old test missed: lazy tables, MOVED, importlib."""
    tree = read_tree(REPO)
    kinds = {(e.source, e.target, e.how) for e in tree.imports}
    assert ("mocapviz.db", "mocapviz.db.database", "lazy_exports string") in kinds
    assert ("mocapviz.match", "mocapviz.match.time_warping", "lazy_exports string") in kinds  # **dict.fromkeys
    assert ("mocapviz._moved", "mocapviz.similarity.search", "MOVED table") in kinds
    assert ("mocapviz.motion.motion", "mocapviz.motion.skeleton", "function-level import") in kinds
    assert any(e.how == "TYPE_CHECKING import" and not e.load for e in tree.imports)


@pytest.mark.parametrize("module", ["mocapviz.search", "mocapviz.database", "mocapviz.batch"])
def test_old_module_paths_still_import_with_a_warning_naming_the_new_place(module):
    sys.modules.pop(module, None)
    with pytest.warns(FutureWarning, match="moved to mocapviz\\."):
        old = importlib.import_module(module)
    name = {"mocapviz.search": "SimilaritySearch", "mocapviz.database": "MotionDB", "mocapviz.batch": "map_ordered"}
    assert getattr(old, name[module]).__module__.startswith(("mocapviz.similarity", "mocapviz.db", "mocapviz.parallel"))


# --------------------------------------------------------------------- the checker fails: modified copies of the tree
@pytest.fixture
def copy(tmp_path) -> Path:
    """The package's Python files and docs/architecture.md, copied to ``tmp_path`` (the checker's whole input)."""
    shutil.copytree(REPO / PACKAGE, tmp_path / PACKAGE, ignore=lambda d, names: [
        n for n in names if n == "__pycache__" or not (n.endswith(".py") or (Path(d) / n).is_dir())])  # fmt: skip
    (tmp_path / "docs").mkdir()
    shutil.copy(REPO / ARCHITECTURE, tmp_path / ARCHITECTURE)
    return tmp_path


def test_the_copy_is_clean_as_the_checkout(copy):
    assert check(copy) == check(REPO) == []


def _edit(root: Path, path: str, old: str, new: str) -> None:
    f = root / path
    text = f.read_text()
    assert text.count(old) == 1, f"{path}: {old!r}"
    f.write_text(text.replace(old, new))


def _append(root: Path, path: str, text: str) -> None:
    f = root / path
    f.write_text(f.read_text() + "\n" + text)


def test_a_load_time_cycle_inside_a_top_level_try_is_found(copy):
    _append(copy, "mocapviz/errors.py", "try:\n    from .validation import number\nexcept ImportError:\n    pass\n")
    found = check(copy)
    assert [p for p in found if p.startswith("import cycle at load time: mocapviz.errors -> mocapviz.validation "
                                             "(mocapviz/errors.py:")], found  # fmt: skip
    assert "mocapviz.validation -> mocapviz.errors" in found[0]


def test_a_load_time_cycle_in_a_class_body_and_through_a_lazy_name_is_found(copy):
    """A class body runs at load; ``from pkg import Name`` runs pkg's lazy ``__getattr__``, loading Name's module."""
    _append(copy, "mocapviz/errors.py", "class _X:\n    from .validation import number\n")
    assert any(p.startswith("import cycle at load time: mocapviz.errors -> mocapviz.validation") for p in check(copy))
    (copy / "mocapviz/errors.py").write_text((REPO / "mocapviz/errors.py").read_text())
    _append(copy, "mocapviz/db/ingest.py", "from ..db import MotionDB\n")  # lazy: .database, which imports .ingest
    found = check(copy)
    assert any("import cycle at load time" in p and "mocapviz.db.ingest" in p and "mocapviz.db.database" in p
               for p in found), found  # fmt: skip


def test_a_lazy_exports_string_pointing_up_is_found(copy):
    entry = '"hit_table": ".hits"'
    _edit(copy, "mocapviz/db/__init__.py", entry, entry + ', "KnnIndex": "..similarity.knn"')
    found = check(copy)
    assert any(p.startswith("mocapviz/db/__init__.py:16 (db) imports mocapviz.similarity.knn (similarity): "
                            "lazy_exports string") for p in found), found  # fmt: skip


def test_an_upward_import_inside_a_function_or_by_importlib_is_found(copy):
    _append(copy, "mocapviz/motion/rotations.py", "def _late():\n    from ..db import database\n")
    _append(copy, "mocapviz/store.py", "def _viz():\n    from importlib import import_module\n"
                                       "    return import_module('mocapviz.viz')")
    found = check(copy)
    assert any("(motion) imports mocapviz.db.database (db): function-level import" in p for p in found), found
    assert any("(base) imports mocapviz.viz (viz): import_module string" in p for p in found), found


def test_imports_the_checker_cannot_read_are_refused(copy):
    _append(copy, "mocapviz/store.py", "def _any(name):\n    return __import__(name)")
    _edit(copy, "mocapviz/engine/__init__.py", '{"Engine": ".engine",', "dict(Engine='.engine') or {")
    _append(copy, "mocapviz/heap.py", "def _old():\n    import mocapviz.search\n")
    found = check(copy)
    assert any(p.startswith("mocapviz/store.py:") and "__import__() of a computed name" in p for p in found), found
    line = next(i for i, text in enumerate((copy / "mocapviz/engine/__init__.py").read_text().splitlines(), 1)
                if "lazy_exports(__name__" in text)
    assert any(p.startswith(f"mocapviz/engine/__init__.py:{line}: lazy_exports with a table that is not a literal")
               for p in found), found  # fmt: skip
    assert any("imports the old path mocapviz.search: import mocapviz.similarity.search instead" in p for p in found)


def test_the_package_root_and_moved_paths_are_refused_below_the_root(copy):
    _append(copy, "mocapviz/viz/palette.py", "def _root():\n    import mocapviz\n")
    _edit(copy, "mocapviz/_moved.py", '"mocapviz.skeleton": ("mocapviz.motion.skeleton",),', "")
    _append(copy, "mocapviz/cli/__init__.py", "def _gone():\n    from mocapviz.skeleton import CANONICAL_JOINTS\n")
    found = check(copy)
    assert any("mocapviz.viz.palette imports the package root (function-level import)" in p for p in found), found
    assert any("imports from mocapviz.skeleton, which is no module of the package" in p for p in found), found


def _swap(root: Path, lower: str, upper: str) -> None:
    text = (root / ARCHITECTURE).read_text()
    rows = [re.search(rf"^\| {name} \|.*\n", text, re.MULTILINE)[0] for name in (lower, upper)]
    (root / ARCHITECTURE).write_text(text.replace(rows[0] + rows[1], rows[1] + rows[0]))


def test_a_changed_layer_order_is_found(copy):
    _swap(copy, "motion", "io")
    assert [name for name, _ in layers(copy)][1:3] == ["io", "motion"]
    found = check(copy)
    assert found[0].startswith("docs/architecture.md: the layers are, lowest first, base, io, motion, db,"), found
    assert any(" (io) imports mocapviz.motion" in p and "against the layers" in p for p in found), found
    assert not any(" (motion) imports mocapviz.io" in p for p in found)


def test_a_layer_order_the_imports_allow_is_found_too(copy):
    _swap(copy, "export", "features")
    found = check(copy)
    assert len(found) == 1 and "features, export, match" in found[0], found


def test_a_module_or_folder_left_out_of_the_table_is_found(copy):
    _edit(copy, ARCHITECTURE.as_posix(), "| export | `export/` (", "| export | (`export/`, ")
    (copy / "mocapviz/newlayer").mkdir()
    (copy / "mocapviz/newlayer/__init__.py").write_text("")
    found = check(copy)
    assert any("mocapviz.export is in no layer" in p for p in found), found
    assert any("mocapviz.newlayer is in no layer" in p for p in found), found


def test_the_motion_cycle_is_found(copy):
    """The cycle the old test missed, put back as it was: motion.py imports skeleton.py inside Motion.canonical,
    skeleton.py and markers.py import Motion at their top. No cycle at load time, a cycle of modules."""
    for module in ("markers", "skeleton"):
        _edit(copy, f"mocapviz/motion/{module}.py", "from .joints", "from .motion import Motion\nfrom .joints")
    found = check(copy)
    assert len(found) == 1 and found[0].startswith(
        "module cycle: mocapviz.motion.markers -> mocapviz.motion.motion (mocapviz/motion/markers.py:"), found
    assert "mocapviz.motion.motion -> mocapviz.motion.skeleton (mocapviz/motion/motion.py:" in found[0]
    assert "function-level import); mocapviz.motion.skeleton -> mocapviz.motion.markers" in found[0]


def test_type_checking_imports_count_for_the_layers_not_for_cycles(copy):
    _append(copy, "mocapviz/errors.py", "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n"
                                        "    from . import validation")
    assert check(copy) == []
    _append(copy, "mocapviz/errors.py", "if TYPE_CHECKING:\n    from .db.database import MotionDB\n")
    found = check(copy)
    assert len(found) == 1 and "(base) imports mocapviz.db.database (db): TYPE_CHECKING import" in found[0], found


def test_a_runner_importing_below_the_engine_is_found(copy):
    """The runners import the engine, viz, io and the base modules only, however written: a page importing
    mocapviz.relational.query, or reproduction.py importing a similarity module inside a function, is reported; the
    same name through mocapviz.engine is not."""
    _append(copy, "mocapviz/app/pages/relational.py", "from ...relational.query import query_by_example\n")
    _append(copy, "mocapviz/reproduction.py", "def _late():\n    from .similarity.knn import KnnIndex\n")
    found = check(copy)
    assert len(found) == 2, found
    assert any(p.startswith("mocapviz/app/pages/relational.py:") and "(runners) imports mocapviz.relational.query "
               "(relational): import; the runners import base, io, engine, viz and each other only" in p
               for p in found), found  # fmt: skip
    assert any(p.startswith("mocapviz/reproduction.py:") and "(runners) imports mocapviz.similarity.knn "
               "(similarity): function-level import" in p for p in found), found  # fmt: skip
    for module in ("mocapviz/app/pages/relational.py", "mocapviz/reproduction.py"):
        (copy / module).write_text((REPO / module).read_text())
    _append(copy, "mocapviz/app/pages/relational.py", "from ...engine import query_segmentation\n")
    assert check(copy) == []


def test_the_engine_offers_every_name_of_its_library_module():
    """A front's ``from mocapviz.engine import NAME`` of a library name reads as an import of the engine: the
    engine's lazy table names library.py for exactly the names of library.py's own table, which are its __all__."""
    from mocapviz.engine import library

    def lazy(module: str, file: str) -> dict[str, str]:
        return _read_module(f"{PACKAGE}.{module}", f"{PACKAGE}.engine", (REPO / PACKAGE / file).read_text()).lazy

    offered = {name for name, where in lazy("engine", "engine/__init__.py").items()
               if where == f"{PACKAGE}.engine.library"}  # fmt: skip
    assert offered == set(lazy("engine.library", "engine/library.py")) == set(library.__all__)


def test_cycles_are_found_one_per_tangle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "e": {"f"}, "f": {"e"}}
    assert sorted(_cycles(graph)) == [["a", "b", "c", "a"], ["e", "f", "e"]]
    assert _cycles({"a": {"b"}, "b": {"c"}}) == []
