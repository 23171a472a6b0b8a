"""Checks of arguments at the public entry points, each failing with one :class:`~mocapviz.errors.ParameterError`
that names the value and says what to pass (the one place such checks are written).

count              an integer within a range (k neighbours, K matches, budgets).
finite_positions   joint positions without NaN or inf, the first bad frame and joint named.
"""

from __future__ import annotations

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
