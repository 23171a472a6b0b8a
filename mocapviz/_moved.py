"""Old module paths that still import, with a FutureWarning naming the new place (the layout of issue 24).

``import mocapviz.search`` (before the subpackages) now gives :mod:`mocapviz.similarity.search` and warns; a module
that was split in two (``mocapviz.database``, ``mocapviz.batch``, ``mocapviz.cluster``) gives a stand-in whose
attributes come from the new modules. The table is :data:`MOVED`; ``docs/glossary.md`` lists it too.
"""
from __future__ import annotations

import importlib
import importlib.util
import sys
import types
import warnings

MOVED = {
    "mocapviz.skeleton": ("mocapviz.motion.skeleton",),
    "mocapviz.rotations": ("mocapviz.motion.rotations",),
    "mocapviz.labels": ("mocapviz.io.labels",),
    "mocapviz.datasets": ("mocapviz.io.datasets",),
    "mocapviz.segmentation": ("mocapviz.features.segmentation",),
    "mocapviz.index": ("mocapviz.relational.index",),
    "mocapviz.query": ("mocapviz.relational.query",),
    "mocapviz.templates": ("mocapviz.relational.templates",),
    "mocapviz.knn": ("mocapviz.similarity.knn",),
    "mocapviz.search": ("mocapviz.similarity.search",),
    "mocapviz.hybrid": ("mocapviz.similarity.hybrid",),
    "mocapviz.reconstruction": ("mocapviz.similarity.reconstruction",),
    "mocapviz.evaluation": ("mocapviz.experiments.evaluation",),
    "mocapviz.database": ("mocapviz.db.database", "mocapviz.db.ingest", "mocapviz.db.batches"),
    "mocapviz.batch": ("mocapviz.parallel", "mocapviz.db.batches"),
    "mocapviz.cluster": ("mocapviz.parallel", "mocapviz.db.batches"),
    "mocapviz.sharded": ("mocapviz.engine",),
    "mocapviz.sharded.engine": ("mocapviz.engine.engine",),
    "mocapviz.sharded.shard": ("mocapviz.engine.shard",),
}


class _Split(types.ModuleType):
    """A module split in several: each attribute from the first new module that has it."""

    def __init__(self, name: str, targets: tuple[str, ...]):
        super().__init__(name, f"moved to {', '.join(targets)}")
        self._targets = targets

    def __getattr__(self, attr: str):
        for target in self._targets:
            module = importlib.import_module(target)
            if hasattr(module, attr):
                return getattr(module, attr)
        raise AttributeError(f"{self.__name__}.{attr} is gone; look in {', '.join(self._targets)}")


class _Loader:  # the importlib.abc.Loader protocol (not the ABC: importlib.abc costs every command 10 ms)
    def __init__(self, targets: tuple[str, ...]):
        self.targets = targets

    def create_module(self, spec):
        warnings.warn(f"{spec.name} moved to {' and '.join(self.targets)}; import it from there", FutureWarning,
                      stacklevel=4)  # fmt: skip
        if len(self.targets) == 1:
            return importlib.import_module(self.targets[0])
        return _Split(spec.name, self.targets)

    def exec_module(self, module):
        """Nothing to run: the new modules are imported already (or on first attribute access)."""


class _Finder:  # the importlib.abc.MetaPathFinder protocol
    def find_spec(self, fullname, path, target=None):
        targets = MOVED.get(fullname)
        if targets is None:
            return None
        return importlib.util.spec_from_loader(fullname, _Loader(targets))


def install() -> None:
    """Let the old module paths import (once per process)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
