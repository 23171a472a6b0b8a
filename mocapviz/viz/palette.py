"""The colours, dashes and markers of every figure, defined once, so that a colour means one thing everywhere.

SIDES            the body's sides: right red, left blue, centre dark grey: the bones of the dashboard's skeleton
                 player (sent to ``mocapviz/app/player.js``) and of the skeleton pictures; ``joint_sides`` tells each
                 joint's side.
PARTS            the parts of the body a relational feature describes (its feature group): lower green, upper purple,
                 mix brown, on the feature timelines. Never red or blue, which mean sides.
OTHERS           what a query is compared with (the kNN picture, Krüger et al. 2010 Fig. 1): grey, the query drawn
                 by side over it.
SERIES           distinct colours of different things drawn together (search methods, measures, coordinates), none of
                 them a side's red or blue; DASHES and MARKERS tell apart lines that lie on each other.
series_style     the (colour, dash) of line i of n: every pair distinct while n <= len(SERIES) * len(DASHES).
legend           a line of HTML naming what each colour of SIDES or PARTS means (the dashboard's one legend of each).
"""

from __future__ import annotations

from ..motion.skeleton import CANONICAL_JOINTS

SIDES = {"r": "#d1452f", "l": "#1f5fa8", "c": "#3c3c3c"}
SIDE_NAMES = {"r": "right", "l": "left", "c": "centre"}
PARTS = {"lower": "#2ca02c", "upper": "#9467bd", "mix": "#8c564b"}
PART_NAMES = {"lower": "lower body", "upper": "upper body", "mix": "mix (both)"}
OTHERS = "#a6a6a6"
SERIES = ("#ff7f0e", "#2ca02c", "#9467bd", "#17becf", "#8c564b", "#e377c2", "#bcbd22", "#7f7f7f", "#393b79",
          "#637939", "#e7ba52", "#7b4173", "#a55194")  # fmt: skip
DASHES = ("solid", "dashed", "dotted", "dotdash")  # bokeh's names
MPL_DASHES = {"solid": "-", "dashed": "--", "dotted": ":", "dotdash": "-."}  # the same for matplotlib
MARKERS = ("circle", "square", "triangle", "diamond", "inverted_triangle", "hex")  # bokeh's names
MPL_MARKERS = {"circle": "o", "square": "s", "triangle": "^", "diamond": "D", "inverted_triangle": "v", "hex": "h"}


def joint_sides(names=CANONICAL_JOINTS) -> list[str]:
    """``"l"``, ``"r"`` or ``"c"`` (centre) per joint: a name starting with l/r whose twin (r/l + the rest) exists.

    Parameters
    ----------
    names : sequence of str
        Joint names (default the canonical joints).

    Returns
    -------
    list of str
        The keys of :data:`SIDES`.

    Examples
    --------
    >>> joint_sides(["root", "lhip", "rhip", "lefty"])
    ['c', 'l', 'r', 'c']
    """
    names = list(names)
    twin = {"l": "r", "r": "l"}
    return [n[0] if n[:1] in twin and twin[n[0]] + n[1:] in names else "c" for n in names]


def legend(colours: dict, names: dict, what: str) -> str:
    """One line of HTML: ``what``, then a square in each colour with its name.

    Parameters
    ----------
    colours : dict
        Key -> colour (:data:`SIDES`, :data:`PARTS`).
    names : dict
        Key -> name (:data:`SIDE_NAMES`, :data:`PART_NAMES`), in the order shown.
    what : str
        What the colours tell ("bones by side").

    Returns
    -------
    str

    Examples
    --------
    >>> legend(SIDES, {"r": "right"}, "bones")
    'bones: <span style="color: #d1452f">■</span> right'
    """
    return f"{what}: " + " · ".join(f'<span style="color: {colours[k]}">■</span> {n}' for k, n in names.items())


def series_style(i: int) -> tuple[str, str]:
    """The colour and dash of the ``i``-th of several lines: colours first, then the next dash with the colours again.

    Parameters
    ----------
    i : int
        The line's number, from 0.

    Returns
    -------
    (str, str)
        A colour of :data:`SERIES` and a dash of :data:`DASHES`.

    Examples
    --------
    >>> series_style(0), series_style(len(SERIES))
    (('#ff7f0e', 'solid'), ('#ff7f0e', 'dashed'))
    """
    return SERIES[i % len(SERIES)], DASHES[(i // len(SERIES)) % len(DASHES)]
