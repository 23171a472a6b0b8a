"""Per-frame motion features (ARCHITECTURE: MotionDB -> mocapviz.features -> per-frame feature arrays).

relational        boolean relational features of Müller, Röder & Clausen 2005 (31) and Müller & Röder 2006 (39).
feature_names     the column names of a relational feature set.
feature_groups    lower / upper / mix members of a set, in column order.
feature_table     one row per feature: name, group, spec row, definition, thresholds, unit.
FEATURE_SETS      the known relational feature sets, ("2005", "2006").

numeric           float numeric features of Krüger et al. 2010 §3.2 (F15E ... F30x3E, PCA Fp8 Fp16 Fp25).
numeric_columns   the column names of a numeric feature set.
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
    numeric,
    numeric_columns,
    numeric_of,
    store_numeric,
    window_offsets,
)
from .relational import FEATURE_SETS, feature_groups, feature_names, feature_table, relational

__all__ = [
    "FEATURE_SETS",
    "NUMERIC_SETS",
    "PCAModel",
    "feature_groups",
    "feature_names",
    "feature_table",
    "fit_pca",
    "load_numeric",
    "numeric",
    "numeric_columns",
    "numeric_of",
    "relational",
    "store_numeric",
    "window_offsets",
]
