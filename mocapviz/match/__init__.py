"""Alignment of motions (docs/architecture.md, the match layer, used by relational templates and similarity search).

- ``time_warping.py``: DTW, band-restricted DTW, subsequence DTW and the shared choice of non-overlapping matches.
- ``neighbourhood_graph.py``: the lazy neighbourhood graph of Krüger, Tautges, Weber & Zinke 2010 §4.1 (the
  function ``lng``).

The names are imported when first used (``mocapviz._lazy``).
"""
from .._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "lng": ".neighbourhood_graph",
    **dict.fromkeys(["STEP_SETS", "band_from_path", "best_ends", "dtw", "select_matches", "subsequence_costs",
                     "subsequence_dtw"], ".time_warping"),
})  # fmt: skip

__all__ = ["STEP_SETS", "band_from_path", "best_ends", "dtw", "lng", "select_matches", "subsequence_costs", "subsequence_dtw"]
