"""Checks of arguments at the public entry points, each failing with one :class:`~mocapviz.errors.ParameterError`
that names the value and says what to pass (the one place such checks are written).

count              an integer within a range (k neighbours, K matches, budgets).
one_of, some_of    a name (or several) from a fixed set: numeric sets, relational sets, engines, ...
finite_positions   joint positions without NaN or inf, the first bad frame and joint named.
renamed            a decorator accepting a parameter's old name (see the glossary) with a FutureWarning.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable

import numpy as np

from .errors import ParameterError


def count(value, name: str, least: int = 1, most: int | None = None, most_is: str = "") -> int:
    """``value`` as an int in [least, most], or a ParameterError naming ``name`` (bools and floats are refused:
    2.5 neighbours is a mistake, not a request for 2). ``most_is`` says what the upper limit is ("the number of
    indexed frames")."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ParameterError(f"{name} must be an integer; got {value!r}")
    if most is not None and not least <= value <= most:
        limit = f"{most_is} ({most:,})" if most_is else f"{most:,}"
        raise ParameterError(f"{name} must be between {least} and {limit}; got {value}")
    if value < least:
        raise ParameterError(f"{name} must be at least {least}; got {value}")
    return int(value)


def one_of(value, what: str, options) -> str:
    """``value`` when it is one of ``options``, else a ParameterError "unknown WHAT 'x'; choose one of a, b, c"."""
    return some_of([value], what, options)[0]


def some_of(values, what: str, options) -> list:
    """``values`` (a list) when each is one of ``options``, else a ParameterError naming the unknown ones."""
    values = list(values)
    unknown = [v for v in values if v not in options]
    if unknown:
        shown = ", ".join(map(repr, unknown))
        raise ParameterError(f"unknown {what} {shown}; choose one of {', '.join(map(str, options))}")
    return values


def finite_positions(positions: np.ndarray, where: Callable[[int], str], joints=None) -> None:
    """A ParameterError naming the first frame and joint whose position is NaN or infinite.

    Parameters
    ----------
    positions : np.ndarray [shape=(N, 24, 3)], cm, on the canonical joints.
    where : ``where(frame) -> str`` names the source of a frame (file or document, and the frame).
    joints : sequence of int, optional: only these joints (indices) are checked; default all.
    """
    from .skeleton import CANONICAL_JOINTS

    picked = positions if joints is None else positions[:, joints]
    ok = np.isfinite(picked).all(axis=2)
    if ok.all():
        return
    t, j = np.argwhere(~ok)[0]
    joint = CANONICAL_JOINTS[j if joints is None else joints[j]]
    raise ParameterError(f"{where(int(t))}: joint {joint} has a non-finite (NaN/inf) position")


def renamed(**old_to_new: str) -> Callable:
    """Decorator: keyword ``old=...`` is passed on as ``new=...`` with a FutureWarning naming the new parameter.

    For the names the glossary (docs/glossary.md) retired that the README or notebooks once used, e.g.
    ``@renamed(k_matches="n_matches")``. Passing both names is a ParameterError.
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
