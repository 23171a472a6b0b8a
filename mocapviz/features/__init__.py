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
load_numeric      a stored numeric set, memory-mapped (MotionDBError when missing or stale).
numeric_of        a MotionDB's numeric set: stored when current, else computed.
NUMERIC_SETS      the numeric feature set names.
"""

from .numeric import (
    NUMERIC_SETS,
    PCAModel,
    fit_pca,
    load_numeric,
    numeric_columns,
    numeric_features,
    numeric_of,
    store_numeric,
    window_offsets,
)
from .relational import RELATIONAL_SETS, feature_groups, feature_names, feature_table, relational_features

__all__ = [
    "NUMERIC_SETS",
    "RELATIONAL_SETS",
    "PCAModel",
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
