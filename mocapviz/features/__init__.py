"""Per-frame motion features (ARCHITECTURE: MotionDB -> mocapviz.features -> per-frame feature arrays).

relational        boolean relational features of Müller, Röder & Clausen 2005 (31) and Müller & Röder 2006 (39).
feature_names     the column names of a relational feature set.
feature_groups    lower / upper / mix members of a set, in column order.
feature_table     one row per feature: name, group, spec row, definition, thresholds, unit.
FEATURE_SETS      the known relational feature sets, ("2005", "2006").
"""
from .relational import FEATURE_SETS, feature_groups, feature_names, feature_table, relational

__all__ = ["FEATURE_SETS", "feature_groups", "feature_names", "feature_table", "relational"]
