"""One function per paper table or figure, each returning pandas DataFrames (docs/architecture.md, the experiments
layer).

index_statistics      Müller, Röder & Clausen 2005, Table 2: relational index construction statistics.
query_statistics      Müller, Röder & Clausen 2005, Table 3: random exact / adaptive fuzzy query statistics.
relational_query      Müller, Röder & Clausen 2005, Figs. 7-9: query by example per class, precision and recall.
knn_timings           Krüger, Tautges, Weber & Zinke 2010, Table 1: k-NN search times per numeric set.
base_pose_experiment  Krüger et al. 2010, §5.3: fat-graph base poses, kd-tree against the O(n²) construction.
lng_accuracy          Krüger et al. 2010, §4.2: the lazy neighbourhood graph against subsequence DTW (Spearman, eps).
similarity_matrices   Krüger et al. 2010, Fig. 3: distance matrices per numeric set, the cells the graph computed,
                      its warping paths, subsequence DTW on Dpc1.
alignment             Müller, Röder & Clausen 2005, §7 / Fig. 11: segment-wise alignment refined by band DTW.
numerical_search      Krüger et al. 2010, Table 2: numerical and logical similarity search hits per numeric set.
reconstruction        Krüger et al. 2010, §5.2, Tables 3-4: full-body motion from six sparse markers (local linear
                      models of the kNN poses, after Chai & Hodgins 2005) with priors from different databases.
rank_correlations     Krüger et al. 2010, Fig. 2 / §3.3: Spearman rank-correlation matrices between feature sets and
                      distance measures, pose-based (sample and large database) and segment-based (DTW).
marker_comparison     issue 27: joints estimated from a C3D take's markers against the AMC of the same take
                      (relational 2005 agreement, F15E distance, DTW rank of the AMC).
retrieval_quality     every search method of the product (brute / exact / fast DTW, the lazy neighbourhood graph,
                      relational query by example, hybrid) on a labelled database: mAP leave-one-out and
                      leave-actor-out, P@1, P@10, per-class AP, P/R curves, recall of DTW's top 10, ms per query.

The papers' own figures, named by paper: :func:`mocapviz.experiments.relational.mueller2005_table2` and
``mueller2005_table3``, :func:`mocapviz.experiments.numeric.krueger2010_table1`,
:func:`mocapviz.experiments.matching.krueger2010_table2`,
:func:`mocapviz.experiments.marker_reconstruction.krueger2010_table3` and ``krueger2010_table4``.
"""
from .correlation import paper_claims, pose_correlations, rank_correlations, segment_correlations
from .marker_reconstruction import reconstruction
from .markers import marker_comparison
from .matching import alignment, lng_accuracy, numerical_search, similarity_matrices, summarize_accuracy
from .numeric import base_pose_experiment, knn_timings
from .relational import index_statistics, query_statistics, relational_query
from .retrieval import retrieval_quality

__all__ = ["alignment", "base_pose_experiment", "index_statistics", "knn_timings", "lng_accuracy", "marker_comparison",
           "numerical_search", "paper_claims", "pose_correlations", "query_statistics", "rank_correlations", "reconstruction",
           "relational_query", "retrieval_quality", "segment_correlations", "similarity_matrices", "summarize_accuracy"]
