"""HoloViews plots of the sparse-marker reconstruction experiment (:mod:`mocapviz.experiments.marker_reconstruction`,
Krüger, Tautges, Weber & Zinke 2010 §5.2, Tables 3-4).

compare_table3          our Table 3 beside the paper's, matched by what the prior holds (tidy DataFrame).
compare_table4          our Table 4 beside the paper's per feature set (tidy DataFrame).
joint_error_bars        mean error per joint, one bar per prior variant side by side.
error_curves            the per-frame mean joint error of one test motion over time, one line per prior variant.
paper_bars              a tidy comparison (ours / the paper's) as grouped bars: mean error per setting or feature set.
baseline_bars           the local linear model against the nearest-neighbour pose and the neighbours' weighted mean.
reconstruction_figures  all of the above from one experiment result (the figures of ``mocapviz reproduce``).

Every builder is a pure function from DataFrames to a HoloViews object with options for the bokeh backend
(notebooks, the dashboard) and for the matplotlib backend (``hv.save(obj, "x.png", backend="matplotlib")``).
"""

from __future__ import annotations

import holoviews as hv
import pandas as pd

from ..errors import ParameterError
from ..motion.skeleton import CANONICAL_JOINTS
from .paper import comparison_bars, curves

__all__ = ["baseline_bars", "compare_table3", "compare_table4", "error_curves", "joint_error_bars", "paper_bars",
           "reconstruction_figures"]  # fmt: skip

SETTINGS = ("own database, test clip left out", "own database, test actor / collection left out", "other database")
# (ours, the paper's column for its HDM_bk rows, for its CMU_86 rows) per setting
_SETTING_COLUMNS = {SETTINGS[0]: ("HDM", "HDM", "CMU"), SETTINGS[1]: ("HDM-actor", None, "CMU-"),
                    SETTINGS[2]: ("CMU", "CMU", "HDM")}  # fmt: skip
_SET_ORDER = ("F15E", "Fp8", "Fp16", "Fp25", "F30E", "F39E", "F15x3E", "F15x5E", "F30x3E")  # Table 4's
METHOD_NAMES = {"llm": "local linear model", "mean": "weighted mean of neighbours", "nn": "nearest neighbour"}
ERROR_LABEL = "mean joint error (cm)"


def _check(table: pd.DataFrame, columns, what: str) -> None:
    if not isinstance(table, pd.DataFrame) or table.empty:
        raise ParameterError(f"{what}: empty table")
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ParameterError(f"{what}: the table has no column(s) {missing}; it has {list(table.columns)}")


# ============================================================================ tidy comparisons
def compare_table3(ours: pd.DataFrame, paper: pd.DataFrame) -> pd.DataFrame:
    """Our Table 3 beside the paper's, by what the prior holds.

    The paper's columns mean different things for its two kinds of test motion, so they are matched by setting:

    - "own database, test clip left out": ours ``HDM``; the paper's ``HDM`` for its HDM_bk rows, ``CMU`` for CMU_86;
    - "own database, test actor / collection left out": ours ``HDM-actor``; the paper's ``CMU-`` for CMU_86 (its
      HDM_bk rows have no such column);
    - "other database": ours ``CMU``; the paper's ``CMU`` for HDM_bk, ``HDM`` for CMU_86.

    Parameters
    ----------
    ours : pandas.DataFrame
        :func:`mocapviz.experiments.marker_reconstruction.reconstruction`'s ``"table3"`` (its ``avg`` row is used).
    paper : pandas.DataFrame
        :func:`mocapviz.experiments.marker_reconstruction.krueger2010_table3`.

    Returns
    -------
    pandas.DataFrame
        ``setting``, ``source`` ("ours (<frames> frames)", "paper, HDM05 test motions" (the mean of its two HDM_bk
        rows, the larger max), "paper, CMU_86_avg"), ``mean_cm``, ``max_cm``.
    """
    _check(ours, ["motion", "frames"], "compare_table3 (ours)")
    _check(paper, ["motion"], "compare_table3 (paper)")
    avg = ours[ours["motion"] == "avg"]
    if avg.empty:
        raise ParameterError("compare_table3: our table has no 'avg' row")
    avg = avg.iloc[0]
    hdm = paper[paper["motion"].str.startswith("HDM_")]
    cmu = paper[paper["motion"] == "CMU_86_avg"]
    rows = []
    for setting, (mine, for_hdm, for_cmu) in _SETTING_COLUMNS.items():
        if f"{mine}_mean" in avg and pd.notna(avg[f"{mine}_mean"]):
            rows.append({"setting": setting, "source": f"ours ({int(avg['frames'])} frames)",
                         "mean_cm": float(avg[f"{mine}_mean"]), "max_cm": float(avg[f"{mine}_max"])})  # fmt: skip
        if for_hdm is not None and len(hdm):
            rows.append({"setting": setting, "source": "paper, HDM05 test motions",
                         "mean_cm": float(hdm[f"{for_hdm}_mean"].mean()),
                         "max_cm": float(hdm[f"{for_hdm}_max"].max())})  # fmt: skip
        if len(cmu):
            rows.append({"setting": setting, "source": "paper, CMU_86_avg", "mean_cm": float(cmu[f"{for_cmu}_mean"].iloc[0]),
                         "max_cm": float(cmu[f"{for_cmu}_max"].iloc[0])})  # fmt: skip
    return pd.DataFrame(rows)


def compare_table4(ours: pd.DataFrame, paper: pd.DataFrame) -> pd.DataFrame:
    """Our Table 4 beside the paper's: ``set``, ``source`` ("ours: <motion>" / "paper: CMU_86_03"), ``mean_cm``,
    ``max_cm``; the sets in the paper's order (those only one side has are kept).

    Parameters
    ----------
    ours : pandas.DataFrame
        Our Table 4 (:func:`mocapviz.experiments.marker_reconstruction.reconstruction`'s ``table4``).
    paper : pandas.DataFrame
        :func:`mocapviz.experiments.marker_reconstruction.krueger2010_table4`.

    Returns
    -------
    pandas.DataFrame
        The tidy comparison; errors in cm.
    """
    _check(ours, ["motion"], "compare_table4 (ours)")
    _check(paper, ["motion"], "compare_table4 (paper)")
    rows = []
    for table, label in ((ours, f"ours: {ours['motion'].iloc[0]}"), (paper, f"paper: {paper['motion'].iloc[0]}")):
        row = table.iloc[0]
        for name in _SET_ORDER:
            if f"{name}_mean" in row and pd.notna(row[f"{name}_mean"]):
                rows.append({"set": name, "source": label, "mean_cm": float(row[f"{name}_mean"]),
                             "max_cm": float(row[f"{name}_max"])})  # fmt: skip
    out = pd.DataFrame(rows)
    order = {s: i for i, s in enumerate(_SET_ORDER)}
    return out.sort_values("set", key=lambda s: s.map(order), kind="stable").reset_index(drop=True)


# ============================================================================ builders
def joint_error_bars(joints: pd.DataFrame, title: str = "Mean error per joint", width: int = 950,
                     height: int = 330) -> hv.Bars:  # fmt: skip
    """Mean reconstruction error per joint, one bar per prior variant side by side.

    Parameters
    ----------
    joints : pandas.DataFrame
        Long: ``joint`` (canonical names), ``variant``, ``error_cm`` (the experiment's ``"joints"``).
    title : str
        The figure's title.
    width, height : int
        Pixels.

    Returns
    -------
    hv.Bars
        x = joint in canonical order (root, legs, spine, arms) and variant, y = error in cm. The marker joints
        (wrists, ankles, head, root) are near the noise level; the knees, elbows, toes and fingers carry the error.
    """
    _check(joints, ["joint", "variant", "error_cm"], "joint_error_bars")
    order = {j: i for i, j in enumerate(CANONICAL_JOINTS)}
    data = joints.sort_values("joint", key=lambda s: s.map(order).fillna(len(order)), kind="stable")
    return comparison_bars(data, "joint", "error_cm", source="variant", title=title, ylabel=ERROR_LABEL, width=width,
                           height=height)  # fmt: skip


def error_curves(frames: pd.DataFrame, title: str = "Error over time", x: str = "time_s", width: int = 800,
                 height: int = 300) -> hv.Overlay:  # fmt: skip
    """The per-frame mean joint error of a test motion over time, one line per prior variant.

    Parameters
    ----------
    frames : pandas.DataFrame
        Long: ``x`` (``time_s`` or ``frame``), ``variant``, ``error_cm`` (the experiment's ``"frames"``).
    title : str
        The figure's title.
    x : str
        The time axis column.
    width, height : int
        Pixels.

    Returns
    -------
    hv.Overlay
        One hv.Curve per variant (labelled with it), x = time (s) or frame, y = error (cm).
    """
    _check(frames, [x, "variant", "error_cm"], "error_curves")
    return curves(frames, x, "error_cm", "variant", title=title, xlabel="time (s)" if x == "time_s" else x,
                  ylabel=ERROR_LABEL, markers=False, width=width, height=height)


def paper_bars(table: pd.DataFrame, category: str = "setting", value: str = "mean_cm", title: str = "",
               width: int = 800, height: int = 330) -> hv.Bars:  # fmt: skip
    """A tidy comparison (:func:`compare_table3` with ``category="setting"``, :func:`compare_table4` with
    ``category="set"``) as bars per category, one per ``source`` (ours, the paper's).

    Parameters
    ----------
    table : pandas.DataFrame
        The tidy comparison, with ``source``, ``category`` and ``value`` columns.
    category : str
        The column on the x axis (``"setting"`` or ``"set"``).
    value : str
        The column drawn (``"mean_cm"`` or ``"max_cm"``).
    title : str
        The figure's title.
    width, height : int
        Pixels.

    Returns
    -------
    hv.Bars
        x = category and source, y = ``value`` (cm; ``max_cm`` for the worst frames).
    """
    _check(table, [category, "source", value], "paper_bars")
    label = ERROR_LABEL if value == "mean_cm" else "worst frame's mean joint error (cm)" if value == "max_cm" else value
    return comparison_bars(table, category, value, title=title, ylabel=label, width=width, height=height)


def baseline_bars(baselines: pd.DataFrame, title: str = "Local linear model against baselines", width: int = 700,
                  height: int = 330) -> hv.Bars:  # fmt: skip
    """Mean error per prior variant and method (frame-weighted over the test clips).

    Parameters
    ----------
    baselines : pandas.DataFrame
        The experiment's ``"baselines"``: ``variant``, ``method`` (llm / mean / nn), ``frames``, ``mean_cm``.
    title : str
        The figure's title.
    width, height : int
        Pixels.

    Returns
    -------
    hv.Bars
        x = variant and method (named in full), y = error (cm).
    """
    _check(baselines, ["variant", "method", "frames", "mean_cm"], "baseline_bars")
    b = baselines.assign(weighted=baselines["mean_cm"] * baselines["frames"])
    g = b.groupby(["variant", "method"], sort=False)[["weighted", "frames"]].sum().reset_index()
    g["mean_cm"] = g["weighted"] / g["frames"]
    g["method"] = g["method"].map(METHOD_NAMES).fillna(g["method"])
    return comparison_bars(g, "variant", "mean_cm", source="method", title=title, ylabel=ERROR_LABEL, width=width,
                           height=height)  # fmt: skip


def reconstruction_figures(result: dict, paper_table3: pd.DataFrame | None = None,
                           paper_table4: pd.DataFrame | None = None) -> dict[str, hv.Element]:  # fmt: skip
    """The figures of one :func:`mocapviz.experiments.marker_reconstruction.reconstruction` result, by file stem.

    Parameters
    ----------
    result : dict
        Name -> pandas.DataFrame (``table3``, ``table4``, ``baselines``, ``frames``, ``joints``; missing ones
        skipped).
    paper_table3, paper_table4 : pandas.DataFrame, optional
        The paper's tables (``krueger2010_table3()``, ``krueger2010_table4()``), for the comparisons.

    Returns
    -------
    dict
        File stem -> HoloViews element: ``table3`` (mean error by setting, ours beside the paper's), ``table3_max``
        (the same for the worst frame), ``table4`` (per feature set), ``joints``, ``frames``, ``baselines``.
    """
    figures: dict[str, hv.Element] = {}
    if paper_table3 is not None and isinstance(result.get("table3"), pd.DataFrame):
        both = compare_table3(result["table3"], paper_table3)
        figures["table3"] = paper_bars(both, "setting", "mean_cm", "Krüger 2010 Table 3: average error per joint")
        figures["table3_max"] = paper_bars(both, "setting", "max_cm", "Table 3: max (worst frame)")
    if paper_table4 is not None and isinstance(result.get("table4"), pd.DataFrame):
        figures["table4"] = paper_bars(compare_table4(result["table4"], paper_table4), "set", "mean_cm",
                                       "Krüger 2010 Table 4: average error per joint by feature set")  # fmt: skip
    if isinstance(result.get("joints"), pd.DataFrame) and len(result["joints"]):
        figures["joints"] = joint_error_bars(result["joints"])
    if isinstance(result.get("frames"), pd.DataFrame) and len(result["frames"]):
        figures["frames"] = error_curves(result["frames"])
    if isinstance(result.get("baselines"), pd.DataFrame) and len(result["baselines"]):
        figures["baselines"] = baseline_bars(result["baselines"])
    if not figures:
        raise ParameterError("reconstruction_figures: the result holds none of table3, table4, joints, frames, baselines")
    return figures

