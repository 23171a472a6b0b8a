"""Checks of arguments at the public entry points, each failing with one :class:`~mocapviz.errors.ParameterError`
that names the value and says what to pass (the one place such checks are written).

count              an integer within a range (k neighbours, K matches, budgets).
number             a finite number within an interval (thresholds, tolerances).
Interval           such an interval as a value: the one statement of what a parameter accepts, checked by the
                   library (``Interval.check``) and bounding the dashboard's box of that parameter.
one_of, some_of    a name (or several) from a fixed set: numeric sets, relational sets, engines, ...
finite_positions   joint positions without NaN or inf, the first bad frame and joint named.
renamed            a decorator accepting a parameter's old name (see the glossary) with a FutureWarning.
frame_span         a [first, last) span of frames inside a clip of n frames, at least ``least`` of them.
integer_columns    integer columns of a table (a hit table read from CSV), the missing column or first bad row named.
text               a non-empty printable string of at most so many characters (a segment label, an author's name).

MIN_LENGTH_RANGE   the shortest match of a search as a share of the query's frames, (0, 1] (default MIN_LENGTH,
                   0.5): every search by subsequence alignment and its command-line option take it.

Checks of text (command-line values; the command's ``type=`` functions call them):

parse_count        an integer within a range; parse_port a TCP port; parse_integers a list of integers.
parse_number       a finite number within an interval (:func:`number` checks one given in Python).
parse_names        comma-separated names (or exactly one) from a fixed set.
parse_span         ``A:B`` frame numbers (either may be left out), A < B.

The text of messages: :func:`plural`, a count and its word agreeing in number ("1 match", "2 matches"), for every
message and page that states a count.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .errors import ParameterError


def count(value, name: str, least: int = 1, most: int | None = None, most_is: str = "") -> int:
    """``value`` as an int in [least, most], or a ParameterError naming ``name`` (bools and floats are refused:
    2.5 neighbours is a mistake, not a request for 2). ``most_is`` says what the upper limit is ("the number of
    indexed frames").

    Parameters
    ----------
    value : object
        The argument given.
    name : str
        The parameter's name, for the message.
    least : int
        The smallest value allowed.
    most : int, optional
        The largest value allowed (None: no limit).
    most_is : str
        What ``most`` is, for the message.

    Returns
    -------
    int

    Examples
    --------
    >>> count(5, "k", 1, 10)
    5
    >>> count(2.5, "k")
    Traceback (most recent call last):
    ...
    mocapviz.errors.ParameterError: k must be an integer; got 2.5
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ParameterError(f"{name} must be an integer; got {value!r}")
    if most is not None and not least <= value <= most:
        limit = f"{most_is} ({most:,})" if most_is else f"{most:,}"
        raise ParameterError(f"{name} must be between {least} and {limit}; got {value}")
    if value < least:
        raise ParameterError(f"{name} must be at least {least}; got {value}")
    return int(value)


def one_of(value, what: str, options) -> str:
    """``value`` when it is one of ``options``, else a ParameterError "unknown WHAT 'x'; choose one of a, b, c".

    Parameters
    ----------
    value : object
        The argument given.
    what : str
        What it names, for the message ("numeric set").
    options : sequence
        The allowed values.

    Returns
    -------
    object
        ``value``.

    Examples
    --------
    >>> one_of("F15E", "numeric set", ("F15E", "F30E"))
    'F15E'
    """
    return some_of([value], what, options)[0]


def some_of(values, what: str, options) -> list:
    """``values`` (a list) when each is one of ``options``, else a ParameterError naming the unknown ones.

    Parameters
    ----------
    values : iterable
        The arguments given.
    what : str
        What they name, for the message ("feature(s)").
    options : sequence
        The allowed values.

    Returns
    -------
    list
        ``values`` as a list.
    """
    values = list(values)
    unknown = [v for v in values if v not in options]
    if unknown:
        shown = ", ".join(map(repr, unknown))
        raise ParameterError(f"unknown {what} {shown}; choose one of {', '.join(map(str, options))}")
    return values


def finite_positions(positions: np.ndarray, where: Callable[[int], str], joints=None, joint_names=None) -> None:
    """A ParameterError naming the first frame and joint whose position is NaN or infinite.

    Parameters
    ----------
    positions : np.ndarray [shape=(N, 24, 3)]
        Joint positions on the canonical joints, cm.
    where : callable
        ``where(frame) -> str`` names the source of a frame (file or document, and the frame).
    joints : sequence of int, optional
        Only these joints (indices) are checked; default all.
    joint_names : sequence of str, optional
        The joints' names for the message (e.g. ``CANONICAL_JOINTS``); default their indices.

    Raises
    ------
    ParameterError
        A NaN or infinite position.
    """
    picked = positions if joints is None else positions[:, joints]
    ok = np.isfinite(picked).all(axis=2)
    if ok.all():
        return
    t, j = np.argwhere(~ok)[0]
    j = int(j if joints is None else joints[j])
    joint = joint_names[j] if joint_names is not None else j
    raise ParameterError(f"{where(int(t))}: joint {joint} has a non-finite (NaN/inf) position")


def renamed(**old_to_new: str) -> Callable:
    """Decorator: keyword ``old=...`` is passed on as ``new=...`` with a FutureWarning naming the new parameter.

    For the names the glossary (docs/glossary.md) retired that the README or notebooks once used, e.g.
    ``@renamed(k_matches="n_matches")``. Passing both names is a ParameterError.

    Parameters
    ----------
    **old_to_new : str
        Old keyword name -> new keyword name.

    Returns
    -------
    callable
        The decorator.

    Examples
    --------
    >>> import warnings
    >>> @renamed(k="n_matches")
    ... def search(n_matches=10):
    ...     return n_matches
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     search(k=3), caught[0].category.__name__
    (3, 'FutureWarning')
    """

    def wrap(fn: Callable) -> Callable:
        @functools.wraps(fn)
        def call(*args, **kwargs):
            for old, new in old_to_new.items():
                if old in kwargs:
                    if new in kwargs:
                        raise ParameterError(f"{fn.__qualname__}: pass {new}= only ({old}= is its old name)")
                    warnings.warn(f"{fn.__qualname__}: {old}= is deprecated; pass {new}= (see docs/glossary.md)",
                                  FutureWarning, stacklevel=2)
                    kwargs[new] = kwargs.pop(old)
            return fn(*args, **kwargs)

        return call

    return wrap


def frame_span(frames, n: int, what: str, name: str = "frames", least: int = 2) -> tuple[int, int]:
    """``frames`` (``(first, last)`` with either None for "from the start" / "to the end", or None for all) as
    ``(first, last)`` inside a clip of ``n`` frames (``what`` names it: "document 3", a file) holding at least
    ``least`` frames, or a ParameterError naming ``name`` and the clip's frames. Never clamps.

    Parameters
    ----------
    frames : (int or None, int or None) or None
        The span asked for, half-open.
    n : int
        Frames of the clip.
    what : str
        The clip, for the message.
    name : str
        The parameter's name, for the message.
    least : int
        The fewest frames the span must hold.

    Returns
    -------
    (int, int)
        ``(first, last)``, ``0 <= first < last <= n``, half-open.

    Examples
    --------
    >>> frame_span((None, 60), 129, "document 7"), frame_span(None, 129, "document 7")
    ((0, 60), (0, 129))
    """
    first, last = (None, None) if frames is None else frames
    a = 0 if first is None else first
    b = n if last is None else last
    if not 0 <= a < b <= n:
        raise ParameterError(f"{name} {_span_text(first, last)} are outside {what}, which has frames 0..{n - 1} "
                             f"(stop at most {n})")
    if b - a < least:
        raise ParameterError(f"a query needs at least {least} frames; {name} {_span_text(first, last)} of {what} "
                             f"hold {b - a}")
    return int(a), int(b)


def integer_columns(table, names, what: str, hint: str = "") -> dict:
    """The columns ``names`` of ``table`` as int64 arrays, or a ParameterError naming ``what`` (the table), the
    missing columns or the first row (1-based) whose value is not a whole number, and ``hint`` (what to pass).

    Parameters
    ----------
    table : pandas.DataFrame
        The table (a hit table read from a CSV file).
    names : sequence of str
        The columns needed.
    what : str
        The table, for the message ("--hits hits.csv").
    hint : str
        What to pass instead, appended to the message.

    Returns
    -------
    dict
        Column name -> np.ndarray [shape=(rows,)], int64.

    Examples
    --------
    >>> import pandas as pd
    >>> integer_columns(pd.DataFrame({"doc_id": [3], "start": [10.0]}), ["doc_id", "start"], "hits")["start"]
    array([10])
    """
    missing = [n for n in names if n not in table.columns]
    if missing:
        raise ParameterError(f"{what} has no column {', '.join(missing)} (it has {', '.join(map(str, table.columns))})"
                             f"{'; ' + hint if hint else ''}")
    out = {}
    for name in names:
        values = np.asarray(table[name].to_numpy(), dtype=object)
        ok = np.array([isinstance(v, (int, float, np.number)) and not isinstance(v, bool) and np.isfinite(v)
                       and float(v) == int(v) for v in values], dtype=bool)  # fmt: skip
        if not ok.all():
            row = int(np.argmin(ok))
            raise ParameterError(f"{what}, row {row + 1}: {name} must be a whole number, got {values[row]!r}"
                                 f"{'; ' + hint if hint else ''}")
        out[name] = values.astype(np.float64).astype(np.int64)
    return out


def plural(n, one: str, many: str | None = None, number: bool = True) -> str:
    """``n`` and the word that agrees with it: ``one`` for 1, else ``many`` (default ``one`` + "s"); the count
    written with thousands separators. The one way a message or a page states a count.

    Parameters
    ----------
    n : int
        The count.
    one, many : str
        The word for one thing and for any other count (0 too).
    number : bool
        Write the count before the word (False: the word alone, for "template a, b").

    Returns
    -------
    str

    Examples
    --------
    >>> plural(1, "match", "matches"), plural(0, "match", "matches"), plural(12000, "frame")
    ('1 match', '0 matches', '12,000 frames')
    >>> plural(1, "neighbour"), plural(2, "template", number=False)
    ('1 neighbour', 'templates')
    """
    word = one if n == 1 else (many or one + "s")
    return f"{n:,} {word}" if number else word


def text(value, name: str, most: int = 128) -> str:
    """``value`` when it is a non-empty printable string (``str.isprintable``: no newline, tab or control
    character) of at most ``most`` characters, else a ParameterError naming ``name`` and the value.

    Examples
    --------
    >>> text("kick front", "label")
    'kick front'
    >>> text("a\\nb", "label")
    Traceback (most recent call last):
    ...
    mocapviz.errors.ParameterError: label must be a non-empty printable text of at most 128 characters; got 'a\\nb'
    """
    if not isinstance(value, str) or not value or not value.isprintable() or len(value) > most:
        shown = repr(value) if len(repr(value)) <= 80 else f"{repr(value)[:60]}... ({len(value)} characters)"
        raise ParameterError(f"{name} must be a non-empty printable text of at most {most} characters; got {shown}")
    return value


def _span_text(first, last) -> str:
    return f"{'' if first is None else first}:{'' if last is None else last}"


def _range_text(least, most) -> str:
    return f"between {least} and {most:,}" if most is not None else f"of at least {least}"


def parse_count(text: str, name: str, least: int = 1, most: int | None = None, most_is: str = "") -> int:
    """The integer written in ``text``, checked by :func:`count`; a ParameterError naming ``name`` and the range when
    ``text`` is not an integer ("2.5", "x", "").

    Parameters
    ----------
    text : str
        A command-line value.
    name : str
        The option, for the message (``"-k"``).
    least, most, most_is
        As for :func:`count`.

    Returns
    -------
    int

    Examples
    --------
    >>> parse_count(" 16 ", "-k", 1, 1024)
    16
    """
    try:
        value = int(str(text).strip())
    except ValueError:
        raise ParameterError(f"{name} must be an integer {_range_text(least, most)}; got {text!r}") from None
    return count(value, name, least, most, most_is)


def parse_port(text: str, name: str) -> int:
    """A TCP port number (1..65535) written in ``text``, or a ParameterError naming ``name``.

    Parameters
    ----------
    text : str
        A command-line value.
    name : str
        The option, for the message (``"--port"``).

    Returns
    -------
    int
    """
    text = str(text).strip()
    if not (text.isdigit() and 1 <= int(text) <= 65535):
        raise ParameterError(f"{name} must be a port number from 1 to 65535; got {text!r}")
    return int(text)


def parse_integers(text: str, name: str, least: int = 0) -> list[int]:
    """Comma-separated integers, each at least ``least`` (at least one of them), or a ParameterError naming
    ``name``.

    Parameters
    ----------
    text : str
        A command-line value (``"0,2,5"``).
    name : str
        The option, for the message.
    least : int
        The smallest value allowed.

    Returns
    -------
    list of int

    Examples
    --------
    >>> parse_integers("0,2,5", "--mismatch-at")
    [0, 2, 5]
    """
    try:
        values = [int(v) for v in str(text).split(",")]
    except ValueError:
        raise ParameterError(f"{name} must be comma-separated integers from {least}; got {text!r}") from None
    if min(values) < least:
        raise ParameterError(f"{name} takes integers from {least}; got {text!r}")
    return values


def number(value, name: str, low: float | None = None, high: float | None = None, low_open: bool = False,
           high_open: bool = False) -> float:
    """``value`` (an int or float, not a bool) as a finite float inside the interval from ``low`` to ``high``
    (closed ends unless ``low_open`` / ``high_open``; None: unbounded), or a ParameterError naming ``name`` and the
    interval.

    Parameters
    ----------
    value : object
        The argument given.
    name : str
        The parameter's name, for the message.
    low, high : float, optional
        The interval's ends (None: unbounded).
    low_open, high_open : bool
        Leave out the end itself.

    Returns
    -------
    float

    Examples
    --------
    >>> number(0.1, "delta", 0.0, 0.5, high_open=True)
    0.1
    >>> number(0.5, "delta", 0.0, 0.5, high_open=True)
    Traceback (most recent call last):
    ...
    mocapviz.errors.ParameterError: delta must be a number in [0, 0.5); got 0.5
    """
    if low is not None and high is not None:
        interval = f"in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
    elif low is not None:
        interval = f"{'>' if low_open else '>='} {low:g}"
    elif high is not None:
        interval = f"{'<' if high_open else '<='} {high:g}"
    else:
        interval = "(finite)"
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    x = float(value) if ok else float("nan")
    inside = np.isfinite(x) and not (
        low is not None and (x <= low if low_open else x < low)
        or high is not None and (x >= high if high_open else x > high)
    )
    if not inside:
        raise ParameterError(f"{name} must be a number {interval}; got {value!r}")
    return x


@dataclass(frozen=True)
class Interval:
    """The numbers a parameter accepts, from ``low`` to ``high`` (closed ends unless ``low_open`` / ``high_open``;
    None: unbounded): the one statement of a range, checked by the library (:meth:`check`, that is :func:`number`)
    and bounding the dashboard's box of the same parameter (:meth:`closed`), so the box never takes what the run
    refuses.

    Examples
    --------
    >>> delta = Interval(0.0, 0.5, low_open=True, high_open=True)
    >>> delta.check(0.1, "delta"), delta.closed(0.01)
    (0.1, (0.01, 0.49))
    >>> delta.check(0, "delta")
    Traceback (most recent call last):
    ...
    mocapviz.errors.ParameterError: delta must be a number in (0, 0.5); got 0
    """

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False

    def check(self, value, name: str) -> float:
        """``value`` as a float inside the interval, or a ParameterError naming ``name`` and the interval."""
        return number(value, name, self.low, self.high, self.low_open, self.high_open)

    def parse(self, text: str, name: str) -> float:
        """The number written in ``text`` inside the interval (:func:`parse_number`): a command-line value."""
        return parse_number(text, name, self.low, self.high, self.low_open, self.high_open)

    def closed(self, step: float) -> tuple[float | None, float | None]:
        """The closed range of a box stepping by ``step`` inside the interval: an open end moves in by one step
        (δ in (0, 0.5) stepping by 0.01: 0.01..0.49), rounded to the step's decimals."""
        places = max(0, -math.floor(math.log10(step))) + 1

        def end(value, inward, is_open):
            return None if value is None else round(value + inward * step, places) if is_open else value

        return end(self.low, 1, self.low_open), end(self.high, -1, self.high_open)


MIN_LENGTH = 0.5  # the shortest match of a search, a share of the query's frames: half as long as the query
MIN_LENGTH_RANGE = Interval(0.0, 1.0, low_open=True)
MARKERS_ONLY = ("refuse", "keep")  # ingest of a C3D file of no known marker set (mocapviz.db.marker_documents)


def parse_number(text: str, name: str, low: float | None = None, high: float | None = None, low_open: bool = False,
                 high_open: bool = False) -> float:
    """The finite number written in ``text`` inside the interval from ``low`` to ``high`` (see :func:`number`), or a
    ParameterError naming ``name`` and the interval.

    Parameters
    ----------
    text : str
        A command-line value.
    name : str
        The option, for the message.
    low, high, low_open, high_open
        As for :func:`number`.

    Returns
    -------
    float
    """
    try:
        value = float(str(text).strip())
    except ValueError:
        value = float("nan")
    try:
        return number(value, name, low, high, low_open, high_open)
    except ParameterError as exc:
        raise ParameterError(str(exc).rsplit("; got ", 1)[0] + f"; got {text!r}") from None


def parse_names(text: str, name: str, what: str, options, one: bool = False) -> list[str]:
    """Comma-separated names from ``options`` (``one``: exactly one name, not a list), or a ParameterError naming
    ``name`` (the option), the unknown names and the allowed ones; empty text is refused.

    Parameters
    ----------
    text : str
        A command-line value (``"F15E,F30E"``).
    name : str
        The option, for the message.
    what : str
        What the names name, for the message.
    options : sequence of str
        The allowed names.
    one : bool
        Exactly one name.

    Returns
    -------
    list of str

    Examples
    --------
    >>> parse_names("F15E, F30E", "--numeric-sets", "numeric set", ("F15E", "F30E", "F39E"))
    ['F15E', 'F30E']
    """
    names = [n.strip() for n in str(text).split(",")]
    allowed = ", ".join(map(str, options))
    if not all(names):
        raise ParameterError(f"{name} needs {'a' if one else 'comma-separated'} {what} name{'' if one else 's'}; "
                             f"got {text!r}; choose {'one' if one else 'from'}: {allowed}")
    if one and len(names) > 1:
        raise ParameterError(f"{name} takes one {what}, not a list; got {text!r}; choose one of {allowed}")
    unknown = [n for n in names if n not in options]
    if unknown:
        raise ParameterError(f"{name}: unknown {what} {', '.join(unknown)}; choose {'one of' if one else 'from'} "
                             f"{allowed}")
    return names


def parse_span(text: str, name: str) -> tuple[int | None, int | None]:
    """``"A:B"`` as ``(A, B)``: frame numbers from 0, either left out (None: from the start / to the end), A < B;
    or a ParameterError naming ``name``. Whether the span lies inside a clip is :func:`frame_span`'s check.

    Parameters
    ----------
    text : str
        A command-line value (``"120:360"``, ``":60"``).
    name : str
        The option, for the message (``"--frames"``).

    Returns
    -------
    (int or None, int or None)
        First frame and stop (excluded).

    Examples
    --------
    >>> parse_span("120:360", "--frames"), parse_span(":60", "--frames")
    ((120, 360), (None, 60))
    """
    parts = str(text).split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        first, last = (int(p) if p.strip() else None for p in parts)
    except ValueError:
        raise ParameterError(f"{name} must look like A:B (frame numbers from 0, B excluded; A or B may be left out), "
                             f"got {text!r}") from None
    if any(v is not None and v < 0 for v in (first, last)):
        raise ParameterError(f"{name} {text}: frames count from 0 (A:B, B excluded)")
    if first is not None and last is not None and first >= last:
        raise ParameterError(f"{name} {text}: the first frame must come before the last (A < B, B excluded)")
    return first, last
