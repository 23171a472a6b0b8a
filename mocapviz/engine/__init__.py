"""The engine: one object over a MotionDB (:class:`Engine`) through which every front asks every use case, its
database split into shards in this process or on a Dask cluster (:mod:`~mocapviz.engine.shard`), every parameter
declared once (:mod:`~mocapviz.engine.parameters`)."""
from __future__ import annotations

from .._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {"Engine": ".engine", "ShardedDB": ".engine", "Shard": ".shard",
                                               "PARAMETERS": ".parameters", "Parameter": ".parameters"})
