"""No module of mocapviz is hidden by a function or class of its own name: ``import mocapviz.x.y as m`` gives the
module, and ``mocapviz.x.y`` is that same module (a package that re-exports a function ``y`` from ``.y`` would
rebind the name over the submodule, as ``mocapviz.features`` once did with ``relational`` and ``numeric``)."""

from __future__ import annotations

import importlib
import pkgutil
import types

import mocapviz


def _modules(package):
    for info in pkgutil.iter_modules(package.__path__, package.__name__ + "."):
        module = importlib.import_module(info.name)
        yield module
        if info.ispkg:
            yield from _modules(module)


def test_the_feature_modules_are_modules():
    import mocapviz.features.numeric as numeric_module
    import mocapviz.features.relational as relational_module

    assert isinstance(relational_module, types.ModuleType) and isinstance(numeric_module, types.ModuleType)
    assert relational_module.relational_features is mocapviz.features.relational_features
    assert numeric_module.numeric_features is mocapviz.features.numeric_features


def test_no_module_is_shadowed_by_a_name_of_its_package():
    modules = list(_modules(mocapviz))
    assert len(modules) > 40
    shadowed = []
    for module in modules:
        parent, _, name = module.__name__.rpartition(".")
        found = getattr(importlib.import_module(parent), name)
        if found is not module:
            shadowed.append(f"{module.__name__} is {type(found).__name__} {getattr(found, '__qualname__', found)!r}")
    assert not shadowed, "; ".join(shadowed)


def _walked_modules():
    """Every module of the package, found by :func:`pkgutil.walk_packages` and imported (``mocapviz.app`` too: its
    modules build no server on import)."""
    failed = []
    infos = list(pkgutil.walk_packages(mocapviz.__path__, mocapviz.__name__ + ".", onerror=failed.append))
    assert not failed, f"packages that did not import: {failed}"
    return [mocapviz] + [importlib.import_module(info.name) for info in infos]


def test_no_module_defines_or_exports_a_function_or_class_of_its_own_name():
    """Project convention: a module per concept, named after it; never a function with the same name as its module
    (so the modules of ``segment``, ``dtw``, ``reproduce``, ``reconstruct`` and of the experiment ``reconstruction``
    are ``segmentation``, ``match.time_warping``, ``reproduction``, ``reconstruction`` and
    ``experiments.marker_reconstruction``)."""
    modules = _walked_modules()
    names = {module.__name__ for module in modules}
    assert len(modules) > 40 and {"mocapviz.app", "mocapviz.app.pages.reconstruction"} <= names
    offenders = []
    for module in modules:
        own = module.__name__.rpartition(".")[2]
        found = vars(module).get(own)
        if callable(found):  # a function, a class or any other callable (a numba dispatcher); never a module
            kind = "class" if isinstance(found, type) else "function"
            offenders.append(f"{module.__name__} defines {kind} {own!r}")
        if own in getattr(module, "__all__", ()):
            offenders.append(f"{module.__name__} exports {own!r} in __all__")
    assert not offenders, "; ".join(offenders)
