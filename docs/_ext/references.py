"""Cross-references of the docstrings to mocapviz's own objects, checked against the code (``missing-reference``).

A reference the API reference documents resolves as usual. One it does not document is looked up in the package:
a name through a package that re-exports it (``mocapviz.engine.Engine``: the lazy re-exports are the same objects)
links to where the object is documented; an existing object the site leaves out (a private helper, a module below
the public API) is shown as code, unlinked; a name that imports nothing (a renamed or removed function) is left
unresolved, so that ``nitpicky`` and ``-W`` fail the build on it.
"""
from __future__ import annotations

import importlib
import warnings

MISSING = object()


def named_object(target: str, module: str | None = None, cls: str | None = None):
    """The object the dotted name ``target`` names, tried as written, then within ``module`` and ``module.cls`` (the
    context of the docstring, as Python's domain tries it); ``MISSING`` if none."""
    contexts = [f"{module}.{cls}." if module and cls else None, f"{module}." if module else None, ""]
    for prefix in (c for c in contexts if c is not None):
        found = _import(prefix + target)
        if found is not MISSING:
            return found
    return MISSING


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


def _documented_names(obj) -> list[str]:
    """The names under which ``obj`` may be documented: where it is defined, and the top level."""
    if hasattr(obj, "__path__") or type(obj).__name__ == "module":
        return [obj.__name__]
    qualname = getattr(obj, "__qualname__", None)
    module = getattr(obj, "__module__", None)
    if not qualname or not module:
        return []
    return [f"{module}.{qualname}", f"mocapviz.{qualname}"]


def resolve(app, env, node, contnode):
    """``missing-reference`` for the py domain and mocapviz's objects (see the module's docstring)."""
    target = node.get("reftarget", "")
    if node.get("refdomain") != "py" or "mocapviz" not in (target + str(node.get("py:module"))):
        return None
    obj = named_object(target, node.get("py:module"), node.get("py:class"))
    if obj is MISSING:
        return None  # a stale name: the warning stays
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
