"""Relational retrieval (Müller, Röder & Clausen 2005; Müller & Röder 2006) over the boolean features.

index.py      inverted lists per feature group: exact, fuzzy, adaptive fuzzy and m-mismatch hits (2005 §4-6).
query.py      query by example: a clip's features, segmented on a selection, looked up in the indexes (§5-6).
templates.py  motion templates learned from labelled examples and matched by DTW (Müller & Röder 2006).

See ``docs/architecture.md``.
"""
from .._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "InvertedIndex": ".index", "build": ".index", "load_or_build": ".index",
    "query_by_example": ".query", "MotionTemplate": ".templates", "learn_class": ".templates",
    "find_instances": ".templates", "load_template": ".templates", "store_template": ".templates",
})  # fmt: skip
__all__ = ["InvertedIndex", "MotionTemplate", "build", "find_instances", "learn_class", "load_or_build",
           "load_template", "query_by_example", "store_template"]  # fmt: skip
