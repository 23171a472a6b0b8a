"""mocapviz: content-based retrieval and similarity search in motion-capture databases.

The package is layered (``docs/architecture.md``): the base (errors, validation, parallel, store), ``motion``
(the Motion, the canonical skeleton), ``io`` (readers, label tables, archives), ``db`` (the MotionDB, ingest,
per-document batches, the one hit table), ``features``, ``match`` (DTW and the lazy neighbourhood graph),
``relational`` (Müller et al. 2005 / 2006), ``similarity`` (Krüger et al. 2010), ``experiments``, ``viz``, and the
runners ``app`` and ``cli``. Each imports only from the layers below it.

The names here are imported when first used, so that ``import mocapviz`` is quick.

Examples
--------
>>> import mocapviz
>>> from mocapviz.io import datasets
>>> m = mocapviz.load(datasets.sample() / "hdm05-cut/amc/HDM_mm_kickLFront1Reps_023_120.amc")
>>> m.positions.shape[1:], m.fps
((31, 3), 120.0)
"""
from ._lazy import lazy_exports
from ._moved import install as _install_moved
from ._version import __version__
from .errors import (
    MocapFormatError,
    MocapFormatWarning,
    MocapvizError,
    MotionDBError,
    ParameterError,
    SkeletonMappingError,
)

_install_moved()
__getattr__, _exported = lazy_exports(__name__, {"MotionDB": ".db.database", "load": ".io", "Motion": ".motion",
                                                 "datasets": ".io.datasets", "Engine": ".engine.engine"})  # fmt: skip
__all__ = ["Engine", "MocapFormatError", "MocapFormatWarning", "MocapvizError", "Motion", "MotionDB", "MotionDBError",
           "ParameterError", "SkeletonMappingError", "__version__", "load"]  # fmt: skip


def __dir__():
    return sorted({*globals(), *_exported()})
