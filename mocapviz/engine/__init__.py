"""The engine: one object over a MotionDB (:class:`Engine`) through which every front asks every use case, its
database split into shards in this process or on a Dask cluster (:mod:`~mocapviz.engine.shard`), every parameter
declared once (:mod:`~mocapviz.engine.parameters`), its stored derived data kept up to date after an ingest
(:mod:`~.derived`), and what the fronts may use of the library (:mod:`~.library`)."""
from __future__ import annotations

from .._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {"Engine": ".engine", "ShardedDB": ".engine", "Shard": ".shard",
                                               "PARAMETERS": ".parameters", "Parameter": ".parameters",
                                               "stored_sets": ".derived", "update_derived": ".derived",
                                               **dict.fromkeys([
    # library.py's names: what the fronts (the runners) may use of the library below the engine
    "CANONICAL_JOINTS", "CANONICAL_PARENTS", "DEFAULT_K", "DELTA", "DELTA_RANGE", "DONT_CARE", "Description",
    "Event", "FPS_RANGE", "InvertedIndex", "MARKERS", "MAX_COST_RANGE", "METHODS", "METHOD_LABELS", "Motion",
    "MotionDB", "MotionTemplate", "NOISE_RANGE_CM", "NUMERIC_SETS", "Named", "PAPER_SECONDS", "PAPER_SPEARMAN",
    "PCAModel", "PosePrior", "Progression", "RELATIONAL_SETS", "add_block_checksums", "aligned_takes", "alignment",
    "audit_quality", "available_measures", "base_pose_experiment", "clip_quality", "cmu_sequence_quality", "composite_quality",
    "correlation_sample", "database_frames", "declared_set", "describe", "describe_clip", "dtw", "event_quality", "expand_paths",
    "feature_groups", "feature_names", "first_frames", "frame_actors", "graph_k", "index_statistics",
    "is_template_name", "knn_timings", "krueger2010_table1", "krueger2010_table2", "krueger2010_table3",
    "krueger2010_table4", "layout", "lng_accuracy", "load_markers", "load_numeric", "marker_clip", "marker_comparison",
    "marker_gaps", "marker_reconstruction", "match_set", "mueller2005_table2", "mueller2005_table3", "named_descriptions", "numeric_columns",
    "numerical_search", "paper_claims", "parse_description", "pose_correlations", "pose_limits", "query_segmentation",
    "query_statistics", "rank_correlations", "read_annotations", "real_marker_clip", "reconstruct", "reconstruction",
    "reconstruction_errors", "relational_query", "retrieval_quality", "review_page", "scaled_k", "segment",
    "segment_correlations",
    "shortest_instance", "shortest_match", "similarity_matrices", "simulated_annotation", "store_template", "stored_templates",
    "summarize_accuracy", "template_distance", "template_names", "template_path", "template_quality", "vocabulary_of",
    "unlabelled_documents", "vocabulary_table", "walk", "zipped",
], ".library")})  # fmt: skip
