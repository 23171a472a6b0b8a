"""The words of scene descriptions (docs/descriptions.md): each relational feature as a body part and its two states.

A boolean feature of the 2005 or 2006 set is named ``<part>_<state>`` (``rknee_bent``, ``rfoot_raised_2006``); a
description says ``rknee: straight bent straight``, so every feature gets a *part* (``rknee``) and two *state words*,
the one for 0 (``straight``) and the one for 1 (``bent``). Within one relational set every (part, word) pair names
one feature and one value. ``not_<word>`` always names the 0 state, and the feature's own name with ``0`` / ``1``
works too (``rknee_bent: 0 1 0``).

References
----------
.. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH 2005,
   §3 (the features) and §6.3 (scene descriptions).
"""
from __future__ import annotations

import difflib
from functools import cache

import pandas as pd

from ..errors import ParameterError
from ..features import RELATIONAL_SETS, feature_groups

__all__ = ["Vocabulary", "vocabulary_of", "vocabulary_table"]

# the word for a feature's 0 state, by its 1-state word (else "not_<word>")
ANTONYMS = {
    "behind": "front", "raised": "lowered", "sideways": "in", "bent": "straight", "crossed": "uncrossed",
    "fast": "slow", "in_front": "back", "above_neck": "below_neck", "touching": "apart", "touching_leg": "off_leg",
    "touching_head": "off_head", "touching_hip": "off_hip", "moving": "still", "apart": "together",
    "abducted": "down", "low": "high", "horizontal": "upright",
}  # fmt: skip
# features whose part or words do not follow from their name: feature -> (part, 0 word, 1 word)
OVERRIDES = {
    "torso_bent": ("torso", "upright", "bent"),
    "vertical_extent_small": ("body", "tall", "crouched"),
    "horizontal_extent_large": ("body", "compact", "spread"),
    "hands_apart": ("hands", "close", "apart"),
}  # fmt: skip


def _part_and_words(feature: str) -> tuple[str, str, str]:
    if feature in OVERRIDES:
        return OVERRIDES[feature]
    part, _, state = feature.removesuffix("_2006").partition("_")
    return part, ANTONYMS.get(state, f"not_{state}"), state


class Vocabulary:
    """The parts and state words of one relational set.

    Parameters
    ----------
    relational_set : {"2005", "2006"}

    Examples
    --------
    >>> words = vocabulary_of("2005")
    >>> words.resolve("rknee", ["straight", "bent", "straight"])
    ('rknee_bent', [0, 1, 0])
    >>> words.states("rfoot_raised")
    ('lowered', 'raised')
    """

    def __init__(self, relational_set: str):
        self.relational_set = relational_set
        # group by group (lower, upper, mix); never a column position: the 2006 set's columns are in another order
        self.features = [f for names in feature_groups(relational_set).values() for f in names]
        self.group = {f: g for g, names in feature_groups(relational_set).items() for f in names}
        self.table = {f: _part_and_words(f) for f in self.features}
        self.by_part: dict[str, dict[str, tuple[str, int]]] = {}
        for f, (part, zero, one) in self.table.items():
            words = self.by_part.setdefault(part, {})
            for word, value in ((zero, 0), (one, 1), (f"not_{one}", 0)):
                if words.get(word, (f, value)) != (f, value):
                    raise AssertionError(f"{relational_set}: {part} {word} names two features")
                words[word] = (f, value)

    def states(self, feature: str) -> tuple[str, str]:
        """The (0, 1) state words of ``feature``."""
        return self.table[feature][1], self.table[feature][2]

    def part(self, feature: str) -> str:
        """The body part ``feature`` is written under (``rknee`` for ``rknee_bent``)."""
        return self.table[feature][0]

    def resolve(self, part: str, words: list[str]) -> tuple[str, list[int | None]]:
        """The feature and values of a progression ``part: words`` (``*`` -> None).

        Parameters
        ----------
        part : str
            A body part (``rknee``) or a feature's own name (``rknee_bent``).
        words : list of str
            State words of that part, ``0`` / ``1`` (with a feature's name), or ``*`` (either state).

        Returns
        -------
        feature : str
        values : list of {0, 1, None}

        Raises
        ------
        ParameterError
            An unknown part or word (naming the closest ones), or words of two different features.
        """
        if part in self.table:
            zero, one = self.states(part)
            known = {zero: 0, one: 1, f"not_{one}": 0, "0": 0, "1": 1}
            values = []
            for w in words:
                if w != "*" and w not in known:
                    raise ParameterError(f"{w!r} is not a state of {part} ({zero} or {one}, 0 or 1, or *)")
                values.append(None if w == "*" else known[w])
            return part, values
        if part not in self.by_part:
            raise ParameterError(f"unknown body part or feature {part!r} in the {self.relational_set} set"
                                 + _closest(part, [*self.by_part, *self.table]))  # fmt: skip
        words_of = self.by_part[part]
        feature = None
        values = []
        for w in words:
            if w == "*":
                values.append(None)
                continue
            if w not in words_of:
                raise ParameterError(f"{w!r} is not a state of {part} in the {self.relational_set} set"
                                     + _closest(w, [x for x in words_of if not x.startswith("not_")]))  # fmt: skip
            f, value = words_of[w]
            if feature not in (None, f):
                a, b = self.states(feature), self.states(f)
                raise ParameterError(f"{part}: mixes the states of two features ({feature}: {a[0]}/{a[1]} and "
                                     f"{f}: {b[0]}/{b[1]}); write one progression per feature")
            feature = f
            values.append(value)
        if feature is None:
            raise ParameterError(f"{part}: a progression needs at least one state other than *")
        return feature, values

    def state_of(self, part: str, word: str, feature: str) -> int:
        """The value (0 or 1) ``word`` names for ``feature`` (written under ``part``), or a ParameterError."""
        got = self.resolve(part, [word])
        if got[0] != feature:
            raise ParameterError(f"{part} {word} is a state of {got[0]}, not of {feature}")
        return int(got[1][0])


@cache
def vocabulary_of(relational_set: str = "2005") -> Vocabulary:
    """The :class:`Vocabulary` of a relational set (cached)."""
    if relational_set not in RELATIONAL_SETS:
        raise ParameterError(f"relational set must be one of {', '.join(RELATIONAL_SETS)}; got {relational_set!r}")
    return Vocabulary(relational_set)


def vocabulary_table(relational_set: str = "2005") -> pd.DataFrame:
    """Every feature of a set with its part and state words, as the description language reads them.

    Parameters
    ----------
    relational_set : {"2005", "2006"}

    Returns
    -------
    pandas.DataFrame
        Columns ``feature``, ``group``, ``part``, ``state_0``, ``state_1``; one row per feature, group by group
        (lower, upper, mix: :attr:`Vocabulary.features`). For the 2006 set that is not the order of the values'
        columns (:func:`mocapviz.features.feature_names`: upper first): find a feature's column by its name.

    Examples
    --------
    >>> print(vocabulary_table("2005").query("part == 'rfoot'")[["feature", "state_0", "state_1"]].to_string(index=False))
         feature state_0 state_1
    rfoot_behind   front  behind
    rfoot_raised lowered  raised
      rfoot_fast    slow    fast
    """
    words = vocabulary_of(relational_set)
    return pd.DataFrame([{"feature": f, "group": words.group[f], "part": words.part(f), "state_0": words.states(f)[0],
                          "state_1": words.states(f)[1]} for f in words.features])  # fmt: skip


def _closest(word: str, options) -> str:
    near = difflib.get_close_matches(word, list(options), n=3, cutoff=0.6)
    return f"; did you mean {' or '.join(repr(n) for n in near)}?" if near else ""
