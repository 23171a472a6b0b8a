"""Global motion matching (ARCHITECTURE: "frames / kNN results -> mocapviz.match").

dtw.py   DTW, band-restricted DTW, subsequence DTW and the shared choice of non-overlapping matches.
lng.py   the lazy neighbourhood graph of Krüger, Tautges, Weber & Zinke 2010 §4.1.
"""
from .dtw import STEP_SETS, band_from_path, best_ends, dtw, select_matches, subsequence_costs, subsequence_dtw
from .lng import lng

__all__ = ["STEP_SETS", "band_from_path", "best_ends", "dtw", "lng", "select_matches", "subsequence_costs", "subsequence_dtw"]
