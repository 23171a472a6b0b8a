"""Cross-references of the docstrings, checked against the code (``missing-reference``; ``nitpicky`` and ``-W``
make any reference left unresolved fail the build).

A reference the API reference documents resolves as usual. One it does not is looked up in Python, as written and
relative to the object whose docstring holds it (``:func:`learn_template``` in a function of
``mocapviz.relational.templates``), the way the code itself would find the name:

- a mocapviz object the site documents under another name (``mocapviz.engine.Engine``: the lazy re-exports are the
  same objects) links to its entry;
- an existing mocapviz object the site leaves out (a private helper, a module below the public API, an instance
  attribute assigned in ``__init__``) is shown as code, unlinked;
- a name of Python, NumPy, pandas, ... (no intersphinx: the machine is offline) is shown as code;
- a name that finds nothing (a renamed or removed function, an old name kept with a FutureWarning) stays
  unresolved: the build fails on it.
"""
from __future__ import annotations

import builtins
import importlib
import inspect
import re
import warnings

MISSING = object()
ATTRIBUTE = object()  # an instance attribute: real, not an object of its own
ALIASES = {"np": "numpy", "pd": "pandas", "hv": "holoviews", "pn": "panel"}
DOCSTRING_OF = re.compile(r"docstring of ([\w.]+)")


def _import(dotted: str):
    """The object of a dotted name; ``MISSING`` for none, and for an old name kept with a FutureWarning
    (``mocapviz._moved``): a docstring names the new one."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", FutureWarning)
                obj = importlib.import_module(".".join(parts[:cut]))
        except (ImportError, FutureWarning):
            continue
        for name in parts[cut:]:
            obj = getattr(obj, name, MISSING)
            if obj is MISSING:
                return MISSING
        return obj
    return MISSING


def _instance_attribute(cls, name: str) -> bool:
    """Whether instances of ``cls`` have the attribute ``name``: annotated, or assigned to ``self`` in its code
    (``self.name = ...``, ``self.a, self.name = ...``)."""
    for klass in inspect.getmro(cls):
        if name in getattr(klass, "__annotations__", {}):
            return True
        try:
            source = inspect.getsource(klass)
        except (OSError, TypeError):
            continue
        if re.search(rf"^\s*(self\.\w+\s*,\s*)*self\.{re.escape(name)}\b[^=\n]*=(?!=)", source, re.MULTILINE):
            return True
    return False


def contexts(node) -> list[str]:
    """The dotted prefixes a relative name is tried under: the documented object's name and each of its parents
    (from the node's source, "docstring of mocapviz.x.y.f"), then the directive's module and class."""
    found = DOCSTRING_OF.search(str(node.source or node.parent.source or ""))
    names = found.group(1).split(".") if found else []
    prefixes = [".".join(names[:cut]) for cut in range(len(names), 0, -1)]
    module, cls = node.get("py:module"), node.get("py:class")
    prefixes += [p for p in (f"{module}.{cls}" if module and cls else None, module) if p]
    return list(dict.fromkeys(prefixes))


def named_object(target: str, prefixes: list[str]):
    """The object ``target`` names, tried within each prefix, then as written; ``ATTRIBUTE`` for an instance
    attribute (``positions`` of a MotionDB), ``MISSING`` if none."""
    for prefix in [*prefixes, ""]:
        dotted = f"{prefix}.{target}" if prefix else target
        obj = _import(dotted)
        if obj is not MISSING:
            return obj
        owner, _, last = dotted.rpartition(".")
        cls = _import(owner) if owner else MISSING
        if inspect.isclass(cls) and _instance_attribute(cls, last):
            return ATTRIBUTE
    return MISSING


def _external(target: str) -> bool:
    """A name of Python or of a library mocapviz uses (not of mocapviz), which the site cannot link to."""
    head = target.split(".")[0]
    if head in ALIASES or hasattr(builtins, head):
        return True
    if head == "mocapviz":
        return False
    return _import(ALIASES.get(head, head)) is not MISSING and _import(target) is not MISSING


def _documented_names(obj) -> list[str]:
    """The names under which ``obj`` may be documented: where it is defined, and the top level."""
    if inspect.ismodule(obj):
        return [obj.__name__]
    qualname, module = getattr(obj, "__qualname__", None), getattr(obj, "__module__", None)
    return [f"{module}.{qualname}", f"mocapviz.{qualname}"] if qualname and module else []


def resolve(app, env, node, contnode):
    """``missing-reference`` for the py domain (see the module's docstring)."""
    target = node.get("reftarget", "")
    if node.get("refdomain") != "py":
        return None
    obj = named_object(target, contexts(node))
    if obj is MISSING:
        return contnode if _external(target) else None  # None: a stale name, the warning stays
    if obj is ATTRIBUTE or not (getattr(obj, "__module__", None) or getattr(obj, "__name__", "")).startswith("mocapviz"):
        return contnode
    domain = env.get_domain("py")
    for name in _documented_names(obj):
        if name in domain.objects and name != target:
            found = domain.resolve_any_xref(env, node["refdoc"], app.builder, name, node, contnode)
            if found:
                return found[0][1]
    return contnode  # a real object the site does not document: code, unlinked


def setup(app):
    app.connect("missing-reference", resolve)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
