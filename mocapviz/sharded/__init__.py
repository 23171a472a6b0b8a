"""Sharded search on a Dask cluster: a MotionDB split by documents into shards, each kept resident on one worker
(:mod:`~mocapviz.sharded.shard`), every query fanned out and the answers merged into the single-process answer
(:mod:`~mocapviz.sharded.engine`: :class:`ShardedDB`)."""
from __future__ import annotations

from .._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {"ShardedDB": ".engine", "Shard": ".shard"})
