"""Plot builders (docs/architecture.md, the viz layer: DataFrames, arrays -> plots): pure functions from experiment outputs to
HoloViews objects with bokeh options.

matching.py   Krüger et al. 2010 Fig. 3 (similarity_layout), §4.2 (accuracy_plot); Müller et al. 2005 §7 Fig. 11
              (alignment_layout).
correlation.py Krüger et al. 2010 Fig. 2 (correlation_heatmap: a rank-correlation matrix with its values).
reconstruction.py Krüger et al. 2010 Tables 3-4 (reconstruction_figures, joint_error_bars, error_curves, ...).
paper.py      ours beside the paper's numbers (comparison_bars, curves): the figures of `mocapviz reproduce`.
timeline.py   a clip's features over time: relational_timeline (Müller et al. 2005 §3-4), numeric_curves (Krüger
              et al. 2010 §3.2).
skeleton.py   PyVista offscreen drawings of canonical poses: render_skeletons (side by side or together),
              neighbour_poses (Krüger et al. 2010 Fig. 1); the dashboard's player draws with them.
query.py      precision_recall, precision_recall_plot: relational hits judged by the query's label.
retrieval.py  retrieval quality of the search methods: class_ap_bars (AP per class and method), pr_curves (mean
              interpolated precision at 11 recall levels), summary_bars, retrieval_layout.
statistics.py query_time_scatter: query time against hit count (Müller et al. 2005 §6.2, Table 3).
templates.py  template_image: a motion template as features × time, white 0, black 1, grey don't care (Müller &
              Röder 2006).
palette.py    the colours, dashes and markers of every figure and of the dashboard's player, defined once: SIDES
              (right red, left blue), PARTS (lower, upper, mix), OTHERS, SERIES.
"""
from .correlation import correlation_heatmap
from .matching import accuracy_plot, accuracy_table, alignment_layout, band_polygon, similarity_layout
from .paper import comparison_bars, curves
from .query import precision_recall, precision_recall_plot
from .reconstruction import reconstruction_figures
from .retrieval import class_ap_bars, pr_curves, retrieval_layout, summary_bars
from .skeleton import neighbour_poses, render_skeletons
from .statistics import query_time_scatter
from .templates import template_image
from .timeline import numeric_curves, relational_timeline

__all__ = ["accuracy_plot", "accuracy_table", "alignment_layout", "band_polygon", "class_ap_bars",
           "comparison_bars", "correlation_heatmap", "curves", "neighbour_poses", "numeric_curves", "pr_curves",
           "precision_recall", "precision_recall_plot", "query_time_scatter", "reconstruction_figures",
           "relational_timeline", "render_skeletons", "retrieval_layout", "similarity_layout", "summary_bars",
           "template_image"]
