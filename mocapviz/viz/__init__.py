"""Plot builders (ARCHITECTURE: "DataFrames, arrays -> mocapviz.viz"): pure functions from experiment outputs to
HoloViews objects with bokeh options.

matching.py   Krüger et al. 2010 Fig. 3 (similarity_layout), §4.2 (accuracy_plot); Müller et al. 2005 §7 Fig. 11
              (alignment_layout).
correlation.py Krüger et al. 2010 Fig. 2 (correlation_heatmap: a rank-correlation matrix with its values).
reconstruction.py Krüger et al. 2010 Tables 3-4 (reconstruction_figures, joint_error_bars, error_curves, ...).
paper.py      ours beside the paper's numbers (comparison_bars, curves): the figures of `mocapviz reproduce`.
"""
from .correlation import correlation_heatmap
from .matching import accuracy_plot, accuracy_table, alignment_layout, band_polygon, similarity_layout
from .paper import comparison_bars, curves
from .reconstruction import reconstruction_figures

__all__ = ["accuracy_plot", "accuracy_table", "alignment_layout", "band_polygon", "comparison_bars",
           "correlation_heatmap", "curves", "reconstruction_figures", "similarity_layout"]
