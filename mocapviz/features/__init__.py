"""Per-frame motion features (docs/architecture.md, the features layer: MotionDB -> per-frame feature arrays).

relational_features  boolean relational features of Müller, Röder & Clausen 2005 (31) and Müller & Röder 2006 (39).
feature_names        the column names of a relational set.
feature_groups       lower / upper / mix members of a relational set, in column order.
feature_table        one row per feature: name, group, spec row, definition, thresholds, unit.
RELATIONAL_SETS      the relational sets, ("2005", "2006").

numeric_features  float numeric features of Krüger et al. 2010 §3.2 (F15E ... F30x3E, PCA Fp8 Fp16 Fp25).
numeric_columns   the column names of a numeric set.
window_offsets    frame offsets of the windowed sets' samples (0.3 s window) at a frame rate.
fit_pca           PCAModel of body-frame poses of a reference set (the Fp baselines, §3.1).
PCAModel          mean, principal axes, variances; project / reconstruct; save / load (.npz).
store_numeric     compute numeric sets of a MotionDB and store them in <db>/features/.
extend_numeric    stored numeric sets extended with the documents appended since (after an ingest).
load_numeric      a stored numeric set, memory-mapped (MotionDBError when missing or stale).
numeric_of        a MotionDB's numeric set: stored when current, else extended, else computed.
NUMERIC_SETS      the numeric feature set names.
POSITION_SETS     those of joint positions in the body frame (not the PCA sets).

The set names are defined here and the rest is imported when first used (``mocapviz._lazy``): the command line's
parser lists the sets without loading numba, pandas or the feature modules.
"""
from .._lazy import lazy_exports

NUMERIC_SETS = ("F15E", "F30E", "F39E", "F15x3E", "F15x5E", "F30x3E", "Fp8", "Fp16", "Fp25")
"""The numeric feature sets, in the order of ``numeric.py`` (which defines each)."""
POSITION_SETS = tuple(name for name in NUMERIC_SETS if not name.startswith("Fp"))
"""The numeric sets of joint positions in the body frame (the PCA sets are fitted to one database)."""
RELATIONAL_SETS = ("2005", "2006")
"""The relational feature sets: Müller, Röder & Clausen 2005 (31 features) and Müller & Röder 2006 (39)."""

__getattr__, __dir__ = lazy_exports(__name__, {
    **dict.fromkeys(["PCAModel", "extend_numeric", "fit_pca", "load_numeric", "numeric_columns", "numeric_features", "numeric_of",
                     "store_numeric", "window_offsets"], ".numeric"),
    **dict.fromkeys(["feature_groups", "feature_names", "feature_table", "relational_features"], ".relational"),
    "NUMERIC_SETS": ".numeric", "RELATIONAL_SETS": ".relational",
})  # fmt: skip

__all__ = [
    "NUMERIC_SETS",
    "RELATIONAL_SETS",
    "PCAModel",
    "extend_numeric",
    "feature_groups",
    "feature_names",
    "feature_table",
    "fit_pca",
    "load_numeric",
    "numeric_columns",
    "numeric_features",
    "numeric_of",
    "relational_features",
    "store_numeric",
    "window_offsets",
]
