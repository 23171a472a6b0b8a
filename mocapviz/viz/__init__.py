"""Plot builders (ARCHITECTURE: "DataFrames, arrays -> mocapviz.viz"): pure functions from experiment outputs to
HoloViews objects with bokeh options.

matching.py   Krüger et al. 2010 Fig. 3 (similarity_layout), §4.2 (accuracy_plot); Müller et al. 2005 §7 Fig. 11
              (alignment_layout).
"""
from .matching import accuracy_plot, accuracy_table, alignment_layout, band_polygon, similarity_layout

__all__ = ["accuracy_plot", "accuracy_table", "alignment_layout", "band_polygon", "similarity_layout"]
