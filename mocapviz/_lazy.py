"""Lazy re-exports: a package names its public objects without importing their modules until one is used.

``import mocapviz`` therefore costs only what the command at hand needs (``mocapviz --help`` loads neither pandas
nor numba). See ``docs/architecture.md`` (the base layer).
"""
from __future__ import annotations

import importlib


def lazy_exports(package: str, exports: dict[str, str]):
    """``__getattr__`` and ``__dir__`` for a package whose attribute ``name`` lives in module ``exports[name]``.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    exports : dict of str to str
        Public name -> the module (relative to the package, e.g. ``".database"``) that defines it; a module given
        as its own name (``{"datasets": ".datasets"}`` under ``mocapviz.io``) is the module itself.

    Returns
    -------
    (getattr, dir) : the two functions to assign to the package's ``__getattr__`` and ``__dir__``.

    Examples
    --------
    >>> get, names = lazy_exports("mocapviz.db", {"MotionDB": ".database"})
    >>> get("MotionDB").__name__
    'MotionDB'
    """

    def __getattr__(name: str):
        where = exports.get(name)
        if where is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module = importlib.import_module(where, package)
        value = module if where.rsplit(".", 1)[-1] == name and not hasattr(module, name) else getattr(module, name)
        return value

    def __dir__():
        return sorted(exports)

    return __getattr__, __dir__
