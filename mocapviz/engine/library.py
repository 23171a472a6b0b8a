"""What the fronts may use of the library below the engine: the constants, types and small helpers the runners
(``app/``, ``cli/``, ``reproduction.py``, ``integrity.py``) need beside :class:`~mocapviz.engine.Engine`, re-exported
here so that no runner imports a module of ``motion``, ``db``, ``export``, ``features``, ``match``, ``relational``,
``similarity`` or ``experiments`` (docs/architecture.md; tests/test_architecture.py checks it).

A search of the database or its derived data is a method of the Engine; what is here is not: set and joint names,
types (MotionDB, Motion, MotionTemplate, the description language's nodes), frame conversions, the description
language and its vocabulary, and the paper tables and figures of ``experiments`` that the dashboard's statistics,
correlations, reconstruction and retrieval pages and ``mocapviz reproduce`` show.

Every name is imported when first used (:func:`mocapviz._lazy.lazy_exports`), from the module that defines it, so
that ``mocapviz --help`` (whose parser takes the set names and the frame-rate range from here) loads neither pandas
nor numba. ``mocapviz.engine`` offers each name too.
"""
# ruff: noqa: F822 - the names of __all__ are the lazy table's, bound when first used
from __future__ import annotations

from .._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__package__, {
    # motion: the clip type, the canonical joints, the frame rates a clip may have
    **dict.fromkeys(["FPS_RANGE", "Motion"], "..motion"),
    **dict.fromkeys(["CANONICAL_JOINTS", "CANONICAL_PARENTS"], "..motion.joints"),
    # motion: marker clips, which marker set they carry (mocapviz c3d markers)
    **dict.fromkeys(["marker_gaps", "match_set"], "..motion.markers"),
    # db: the database type, frame conversions of the hit table's convention
    "MotionDB": "..db.database",
    "expand_paths": "..db.ingest",
    **dict.fromkeys(["database_frames", "first_frames"], "..db.hits"),
    # storage: the database folder's files and the readers of its derived data (mocapviz check reads them back)
    "layout": "..db.layout",
    "load_markers": "..db.markers",
    **dict.fromkeys(["PCAModel", "add_block_checksums", "load_numeric"], "..features.numeric"),
    "InvertedIndex": "..relational.index",
    # export: a hit's files as one zip archive
    "zipped": "..export.hits",
    # features: set names, column names and groups, segmentation of a clip's feature values
    **dict.fromkeys(["NUMERIC_SETS", "RELATIONAL_SETS"], "..features"),
    **dict.fromkeys(["feature_groups", "feature_names"], "..features.relational"),
    "numeric_columns": "..features.numeric",
    "segment": "..features.segmentation",
    # match: DTW of two feature sequences, the shortest match a query allows
    **dict.fromkeys(["dtw", "shortest_match"], "..match.time_warping"),
    # relational: a query's segmentation, the description language, its vocabulary, templates and their files
    "query_segmentation": "..relational.query",
    **dict.fromkeys(["Description", "Event", "Named", "Progression", "declared_set", "named_descriptions",
                     "parse_description", "template_names", "walk"], "..relational.description"),
    **dict.fromkeys(["vocabulary_of", "vocabulary_table"], "..relational.vocabulary"),
    "describe": "..relational.scene",
    "describe_clip": "..relational.scene",
    **dict.fromkeys(["DELTA", "DELTA_RANGE", "DONT_CARE", "MAX_COST_RANGE", "MotionTemplate", "is_template_name",
                     "shortest_instance", "store_template", "stored_templates", "template_distance",
                     "template_path"], "..relational.templates"),
    # similarity: the lazy neighbourhood graph's k, reconstruction from sparse markers
    **dict.fromkeys(["graph_k", "scaled_k"], "..similarity.motion_matching"),
    **dict.fromkeys(["DEFAULT_K", "MARKERS", "NOISE_RANGE_CM", "PosePrior", "reconstruct", "reconstruction_errors"],
                    "..similarity.reconstruction"),
    # experiments: the papers' tables and figures, and the data they are made from
    **dict.fromkeys(["review_page", "simulated_annotation", "unlabelled_documents"], "..experiments.annotation"),
    "audit_quality": "..experiments.audit",
    **dict.fromkeys(["available_measures", "correlation_sample", "paper_claims", "pose_correlations", "pose_limits",
                     "rank_correlations", "segment_correlations"], "..experiments.correlation"),
    **dict.fromkeys(["clip_quality", "cmu_sequence_quality", "composite_quality", "event_quality",
                     "read_annotations"], "..experiments.descriptions"),
    **dict.fromkeys(["frame_actors", "krueger2010_table3", "krueger2010_table4", "marker_clip", "reconstruction"],
                    "..experiments.marker_reconstruction"),
    **dict.fromkeys(["aligned_takes", "marker_comparison", "marker_reconstruction", "real_marker_clip"],
                    "..experiments.markers"),
    **dict.fromkeys(["PAPER_SECONDS", "PAPER_SPEARMAN", "alignment", "krueger2010_table2", "lng_accuracy",
                     "numerical_search", "similarity_matrices", "summarize_accuracy"], "..experiments.matching"),
    **dict.fromkeys(["base_pose_experiment", "knn_timings", "krueger2010_table1"], "..experiments.numeric"),
    **dict.fromkeys(["index_statistics", "mueller2005_table2", "mueller2005_table3", "query_statistics",
                     "relational_query"], "..experiments.relational"),
    **dict.fromkeys(["METHOD_LABELS", "METHODS", "retrieval_quality"], "..experiments.retrieval"),
    "template_quality": "..experiments.templates",
})  # fmt: skip

__all__ = ["CANONICAL_JOINTS", "CANONICAL_PARENTS", "DEFAULT_K", "DELTA", "DELTA_RANGE", "DONT_CARE", "FPS_RANGE",
           "MARKERS", "MAX_COST_RANGE", "METHODS", "METHOD_LABELS", "NOISE_RANGE_CM", "NUMERIC_SETS", "PAPER_SECONDS",
           "PAPER_SPEARMAN", "RELATIONAL_SETS", "Description", "Event", "InvertedIndex", "Motion", "MotionDB",
           "MotionTemplate", "Named", "PCAModel", "PosePrior", "Progression", "add_block_checksums", "aligned_takes",
           "alignment", "audit_quality", "available_measures", "base_pose_experiment", "clip_quality", "cmu_sequence_quality",
           "composite_quality", "correlation_sample", "database_frames", "declared_set", "describe", "describe_clip", "dtw",
           "event_quality", "expand_paths", "feature_groups", "feature_names", "first_frames", "frame_actors",
           "graph_k", "index_statistics", "is_template_name", "knn_timings", "krueger2010_table1",
           "krueger2010_table2", "krueger2010_table3", "krueger2010_table4", "layout", "lng_accuracy", "load_markers",
           "load_numeric", "marker_clip", "marker_comparison", "marker_gaps", "marker_reconstruction", "match_set",
           "mueller2005_table2",
           "mueller2005_table3", "named_descriptions", "numeric_columns", "numerical_search", "paper_claims",
           "parse_description", "pose_correlations", "pose_limits", "query_segmentation", "query_statistics",
           "rank_correlations", "read_annotations", "real_marker_clip", "reconstruct", "reconstruction",
           "reconstruction_errors", "relational_query", "retrieval_quality", "review_page", "scaled_k", "segment",
           "segment_correlations", "shortest_instance", "shortest_match", "similarity_matrices", "simulated_annotation",
           "store_template",
           "stored_templates", "summarize_accuracy", "template_distance", "template_names", "template_path",
           "template_quality", "unlabelled_documents", "vocabulary_of", "vocabulary_table", "walk", "zipped"]  # fmt: skip
