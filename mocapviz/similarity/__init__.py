"""Numeric similarity search (Krüger, Tautges, Weber & Zinke 2010) over the numeric feature sets.

knn.py             :class:`KnnIndex`: kd-tree k nearest neighbours of poses (§3-4), base poses (§5.3).
search.py          :class:`SimilaritySearch`: whole clips and stretches ranked by DTW, exact or fast.
hybrid.py          relational hits re-ranked by DTW (query by example, then similarity).
reconstruction.py  full-body motion from sparse markers by local linear models of the kNN poses (§5.2).

The alignment algorithms (DTW, subsequence DTW, the lazy neighbourhood graph) are in :mod:`mocapviz.match`,
below this layer, because motion templates use them too. See ``docs/architecture.md``.
"""
from .._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "KnnIndex": ".knn", "SimilaritySearch": ".search", "hybrid_search": ".hybrid", "reconstruct": ".reconstruction",
    "PosePrior": ".reconstruction",
})  # fmt: skip
__all__ = ["KnnIndex", "PosePrior", "SimilaritySearch", "hybrid_search", "reconstruct"]
