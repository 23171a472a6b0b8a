"""The scene description language (Müller, Röder & Clausen 2005 §6.3, Fig. 10 [1]_; grammar: docs/descriptions.md).

A description says what a motion looks like in the words of the relational features, without an example clip::

    define kick_right:
        rknee: straight bent straight bent straight
        and rfoot: lowered raised lowered
        and overlap rknee bent, rfoot raised
        and rfoot raised for 0.1..1.5 s;
    kick_right then punch_left within 2 s

- a **progression** ``part: state state ...`` is one feature's run of states (``*``: either state);
- an **event** joins progressions with ``and``: they run concurrently (all share some frame); ``overlap A, B`` asks
  for a frame where two of their states hold together; ``A for LO..HI s`` bounds how long a state lasts;
  ``somewhere part state`` / ``never part state``: a state of any feature holds at some / no frame of the hit;
- ``template:NAME`` is a stored motion template's instances, ``NAME`` a defined or shipped description;
- ``A then B within T s``: B starts after A ends, at most T seconds later; ``A | B``: either.

:func:`parse_description` turns the text into the tree of this module's classes, every name resolved against one
relational set's :mod:`~mocapviz.relational.vocabulary`; :mod:`mocapviz.relational.scene` evaluates it.

References
----------
.. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH 2005,
   §6.3 "Towards scene descriptions", Fig. 10.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from functools import cache
from importlib import resources

from lark import Lark, Token, Transformer, Tree, v_args
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken, VisitError

from ..errors import DescriptionError, ParameterError
from ..features import RELATIONAL_SETS
from .vocabulary import vocabulary_of

__all__ = ["DEFAULT_WITHIN", "EXCERPT", "MAX_CHARS", "MAX_DEFINITIONS", "MAX_DEPTH", "MAX_PAIRS", "MAX_PARENS",
           "MAX_THEN", "MAX_WORD", "Alternatives", "Condition", "Description", "Duration", "Event", "Named", "Overlap",
           "Progression", "Sequence", "StateRef", "TemplateAtom", "declared_set", "excerpt", "named_descriptions",
           "parse_description", "template_names", "walk"]

DEFAULT_WITHIN = 2.0  # seconds: "A then B" without "within"
LIBRARY = "named_descriptions.txt"  # the shipped descriptions, beside this module

# Limits (docs/descriptions.md, "Limits"): checked before anything recursive or costly runs, each a DescriptionError
# with the line and column where the text passes it. Far above any real description (the shipped library: 6,497
# characters, 15 definitions, no parentheses, no `then`) and far below Python's recursion limit of 1,000 frames, even
# in a dashboard thread that is already a few hundred frames deep (reading and evaluating a tree of MAX_DEPTH levels
# takes about 3 frames a level).
MAX_CHARS = 20_000  # characters of one description text
MAX_WORD = 137  # characters of one name, number or template:NAME (9 + a stored template's name, at most 128)
MAX_PARENS = 20  # parentheses inside one another
MAX_THEN = 50  # `then` in one chain (A then B then C ...)
MAX_DEFINITIONS = 100  # `define` statements in one text
MAX_DEPTH = 100  # levels of the description tree, through the names it uses (a chain of n `then`s is n levels)
EXCERPT = 80  # characters of the text a message quotes at most (cut with "…")
MAX_PAIRS = 5_000_000  # pairs of hits one `then` or `and` of the evaluation may join (about 80 MB of row numbers)

GRAMMAR = r"""
start: set_statement? definition* expr?
set_statement: "set" NUMBER ";"
definition: "define" NAME ":" expr ";"
?expr: sequence ("|" sequence)*  -> alternatives
?sequence: primary then*
then: "then" primary within?
within: "within" NUMBER "s"
?primary: event
        | NAME -> named
        | TEMPLATE -> template
        | "(" expr ")"
event: clause ("and" clause)*
?clause: progression | overlap | duration | condition
progression: NAME ":" step+
step: NAME | NUMBER | STAR
overlap: "overlap" ref ("," | "with") ref
ref: NAME NAME ("[" NUMBER "]")?
duration: ref "for" range "s"
condition: CONDITION NAME NAME
range: NUMBER? RANGE NUMBER?

TEMPLATE.2: /template:[^\s()|;,]+/
CONDITION.2: /(never|somewhere)\b/
NAME: /(?!(define|then|and|within|overlap|with|for|set|never|somewhere)\b)[A-Za-z_][A-Za-z0-9_]*/
NUMBER: /\d+(\.\d+)?/
RANGE: ".."
STAR: "*"
COMMENT: /#[^\n]*/
%import common.WS
%ignore WS
%ignore COMMENT
"""

_EXPECTED = {"NAME": "a name", "NUMBER": "a number", "STAR": "*", "TEMPLATE": "template:NAME", "RANGE": "..",
             "CONDITION": "never or somewhere",
             "SEMICOLON": "';' (the end of a definition)", "COLON": "':'", "LPAR": "'('", "RPAR": "')'",
             "VBAR": "'|'", "COMMA": "','", "LSQB": "'['", "RSQB": "']'", "$END": "the end of the text"}  # fmt: skip


# ================================================================================================ the tree
@dataclass(frozen=True)
class Progression:
    """One feature's progression of states (the paper's "rknee straight/bent/straight").

    Attributes
    ----------
    part : str
        As written (``rknee``).
    feature : str
        The relational feature (``rknee_bent``).
    values : tuple of {0, 1, None}
        One per step; None: either state (``*``).
    words : tuple of str
        The steps as written.
    """

    part: str
    feature: str
    values: tuple
    words: tuple

    def __str__(self) -> str:
        return f"{self.part}: {' '.join(self.words)}"


@dataclass(frozen=True)
class StateRef:
    """A state of one progression of an event: ``rknee bent`` (every step in that state) or ``rknee bent[2]``.

    Attributes
    ----------
    progression : int
        Index of the progression within its event.
    steps : tuple of int
        The 0-based steps meant.
    text : str
        As written.
    """

    progression: int
    steps: tuple
    text: str

    def __str__(self) -> str:
        return self.text


@dataclass(frozen=True)
class Overlap:
    """Some frame where state ``a`` and state ``b`` hold together (Fig. 10's arrows)."""

    a: StateRef
    b: StateRef

    def __str__(self) -> str:
        return f"overlap {self.a}, {self.b}"


@dataclass(frozen=True)
class Duration:
    """Every run of state ``ref`` lasts from ``low`` to ``high`` seconds (None: unbounded), at the document's rate."""

    ref: StateRef
    low: float | None
    high: float | None

    def __str__(self) -> str:
        low = "" if self.low is None else f"{self.low:g}"
        high = "" if self.high is None else f"{self.high:g}"
        return f"{self.ref} for {low}..{high} s"


@dataclass(frozen=True)
class Condition:
    """A state that holds at some frame of the event's hit (``somewhere rhand above_neck``) or at none of them
    (``never arms crossed``); any feature of the set, described by a progression or not."""

    kind: str
    feature: str
    value: int
    text: str

    def __str__(self) -> str:
        return f"{self.kind} {self.text}"


@dataclass(frozen=True)
class Event:
    """Concurrent progressions with their overlap, duration and state conditions."""

    progressions: tuple
    overlaps: tuple = ()
    durations: tuple = ()
    conditions: tuple = ()

    def __str__(self) -> str:
        clauses = (*self.progressions, *self.overlaps, *self.durations, *self.conditions)
        return "\n    and ".join(str(c) for c in clauses)


@dataclass(frozen=True)
class TemplateAtom:
    """The instances of a stored motion template (``template:NAME``: a name under ``DB/templates/``, never a path; a
    template from a file comes only through ``find(..., templates=...)`` / the CLI's ``--template-file``)."""

    name: str

    def __str__(self) -> str:
        return f"template:{self.name}"


@dataclass(frozen=True)
class Named:
    """A defined or shipped description used by its name."""

    name: str
    body: object = field(compare=False)

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True)
class Sequence:
    """``first then second within`` seconds: ``second`` starts after ``first`` ends, at most ``within`` s later."""

    first: object
    second: object
    within: float

    def __str__(self) -> str:
        return f"{_inner(self.first)} then {_inner(self.second)} within {self.within:g} s"


@dataclass(frozen=True)
class Alternatives:
    """Any of ``options``."""

    options: tuple

    def __str__(self) -> str:
        return " | ".join(_inner(o) for o in self.options)


def _inner(node) -> str:
    text = str(node)
    return f"({text})" if isinstance(node, (Alternatives, Event)) and ("\n" in text or "|" in text) else text


@dataclass(frozen=True)
class Description:
    """A parsed description: its tree, the relational set its words name, and its own definitions.

    Attributes
    ----------
    root : Event, Named, TemplateAtom, Sequence or Alternatives
    relational_set : {"2005", "2006"}
    definitions : dict
        Name -> tree, the text's own ``define`` statements.
    text : str
    """

    root: object
    relational_set: str
    definitions: dict
    text: str
    declared: bool = False

    def __str__(self) -> str:
        defs = [f"define {name}:\n    {body};" for name, body in self.definitions.items()]
        return "\n".join([*([f"set {self.relational_set};"] if self.declared else []), *defs, str(self.root)])

    def templates(self) -> list[str]:
        """The names of the template atoms the description uses (through its names too)."""
        return list(dict.fromkeys(node.name for node in walk(self.root) if isinstance(node, TemplateAtom)))


def _children(node) -> tuple:
    if isinstance(node, Named):
        return (node.body,)
    if isinstance(node, Sequence):
        return (node.first, node.second)
    return node.options if isinstance(node, Alternatives) else ()


def walk(node):
    """Every distinct node of a description tree once, through the names it uses, first to last as written; without
    recursion, and once per node however often a name is used (a chain of definitions each using the previous one
    twice is walked in linear, not exponential, time).

    Parameters
    ----------
    node : Event, Named, TemplateAtom, Sequence or Alternatives

    Yields
    ------
    Event, Named, TemplateAtom, Sequence or Alternatives

    Examples
    --------
    >>> d = parse_description("define k: kick_left | kick_left; k then k")
    >>> [type(n).__name__ for n in walk(d.root)]
    ['Sequence', 'Named', 'Alternatives', 'Named', 'Event', 'Named', 'Named']
    """
    seen, stack = set(), [node]
    while stack:
        node = stack.pop()
        if id(node) not in seen:
            seen.add(id(node))
            yield node
            stack.extend(reversed(_children(node)))


def _depth(root, known: dict) -> int:
    """Levels of a description tree through the names it uses, without recursion (``known``: id -> (levels, node)
    of the nodes already measured, filled in)."""
    stack = [root]
    while stack:
        node = stack[-1]
        below = [c for c in _children(node) if id(c) not in known]
        if below:
            stack.extend(below)
            continue
        known[id(node)] = (1 + max((known[id(c)][0] for c in _children(node)), default=0), node)
        stack.pop()
    return known[id(root)][0]


# ================================================================================================ parsing
@cache
def _parser() -> Lark:
    return Lark(GRAMMAR, parser="lalr", propagate_positions=True, maybe_placeholders=False)


def excerpt(text: str) -> str:
    """``text`` quoted for a message: at most :data:`EXCERPT` characters of it, cut with "…".

    Examples
    --------
    >>> excerpt("rkne"), len(excerpt("x" * 100_000))
    ("'rkne'", 82)
    """
    return repr(text if len(text) <= EXCERPT else text[: EXCERPT - 1] + "…")


def _syntax(text: str, source: str | None) -> Tree:
    """The lark tree of a text within the limits (:data:`MAX_CHARS` ... :data:`MAX_DEFINITIONS`), or the
    DescriptionError at the line and column of the first syntax error or limit passed."""
    if len(text) > MAX_CHARS:
        line, column = _line_column(text, MAX_CHARS)
        raise DescriptionError(f"the description is {len(text):,} characters long; at most {MAX_CHARS:,}", line,
                               column, source)  # fmt: skip
    try:
        tree = _parser().parse(text)
    except UnexpectedInput as exc:
        raise DescriptionError(_syntax_reason(exc, text), *_where(exc, text), source) from None
    _check_limits(tree, source)
    return tree


def _line_column(text: str, at: int) -> tuple[int, int]:
    """1-based (line, column) of character ``at`` of ``text`` (``len(text)``: the end of the text)."""
    return text.count("\n", 0, at) + 1, at - text.rfind("\n", 0, at)


def _where(exc: UnexpectedInput, text: str) -> tuple[int, int]:
    """(line, column) of a syntax error: the unexpected character or token; the end of the text when that is what
    came too early (just after its last token)."""
    token = getattr(exc, "token", None)
    if token is not None and token.type == "$END" and getattr(token, "end_line", None):
        return token.end_line, token.end_column
    if exc.line > 0 and exc.column > 0 and not isinstance(exc, UnexpectedEOF):
        return exc.line, exc.column
    return _line_column(text, len(text.rstrip()))


def _check_limits(tree: Tree, source: str | None) -> None:
    """Every limit the parse tree can show, without recursion: definitions, words, parentheses, `then` chains."""
    definitions = [c for c in tree.children if isinstance(c, Tree) and c.data == "definition"]
    if len(definitions) > MAX_DEFINITIONS:
        meta = definitions[MAX_DEFINITIONS].meta
        raise DescriptionError(f"{len(definitions)} definitions; at most {MAX_DEFINITIONS} in one description",
                               meta.line, meta.column, source)  # fmt: skip
    stack = [(tree, 0)]
    while stack:
        node, parens = stack.pop()
        if node.data == "alternatives":  # every expression: the top one, a definition's, each in parentheses
            parens += 1
            if parens > MAX_PARENS + 1:
                raise DescriptionError(f"parentheses inside one another more than {MAX_PARENS} deep; at most "
                                       f"{MAX_PARENS}", node.meta.line, node.meta.column, source)  # fmt: skip
        if node.data == "sequence" and len(node.children) > MAX_THEN + 1:
            meta = node.children[MAX_THEN + 1].meta
            raise DescriptionError(f"a chain of {len(node.children) - 1} 'then'; at most {MAX_THEN} in one chain",
                                   meta.line, meta.column, source)  # fmt: skip
        for child in node.children:
            if isinstance(child, Tree):
                stack.append((child, parens))
            elif len(child) > MAX_WORD:
                raise DescriptionError(f"{excerpt(str(child))} is {len(child):,} characters long; names, numbers and "
                                       f"template names have at most {MAX_WORD}", child.line, child.column,
                                       source)  # fmt: skip


def _syntax_reason(exc: UnexpectedInput, text: str) -> str:
    if isinstance(exc, UnexpectedCharacters):
        char = text[exc.pos_in_stream]
        if char == "-":
            return "unexpected '-': times and counts are numbers >= 0 (e.g. within 2 s, for 0.1..1 s)"
        return f"unexpected character {char!r}"
    if isinstance(exc, UnexpectedEOF):
        return "the description ends too early"
    if isinstance(exc, UnexpectedToken):
        got = "end of the text" if exc.token.type == "$END" else excerpt(str(exc.token))
        expected = sorted({_EXPECTED[t] if t in _EXPECTED else repr(_parser().get_terminal(t).pattern.value).lower()
                           for t in exc.expected})  # fmt: skip
        hint = ""
        if "SEMICOLON" in exc.expected and str(exc.token) == "define":
            hint = "; end each definition with ';'"
        return f"unexpected {got}; expected {' or '.join(expected)}{hint}"
    return str(exc)


def declared_set(text: str) -> str | None:
    """The relational set a description's text names in its ``set 2006;`` statement, or None.

    Examples
    --------
    >>> declared_set("set 2006; rknee: straight bent straight"), declared_set("kick_left")
    ('2006', None)
    """
    token = _set_token(_syntax(text, None))
    return None if token is None else str(token)


def _set_token(tree: Tree) -> Token | None:
    """The number of the text's ``set`` statement (one of RELATIONAL_SETS), or None."""
    for child in tree.children:
        if isinstance(child, Tree) and child.data == "set_statement":
            token = child.children[0]
            if str(token) not in RELATIONAL_SETS:
                raise DescriptionError(f"set {token}: the relational sets are {', '.join(RELATIONAL_SETS)}",
                                       token.line, token.column)  # fmt: skip
            return token
    return None


def template_names(text: str) -> list[str]:
    """The template atoms (``template:NAME``) a description's text names, in order, without resolving anything
    else (to decide its relational set from the templates' before :func:`parse_description`).

    Examples
    --------
    >>> template_names("template:kickLFront1Reps-bd-dg then template:squat1Reps-bd-dg within 4 s")
    ['kickLFront1Reps-bd-dg', 'squat1Reps-bd-dg']
    """
    tree = _syntax(text, None)
    return list(dict.fromkeys(str(t)[len("template:"):] for t in tree.scan_values(
        lambda v: isinstance(v, Token) and v.type == "TEMPLATE")))  # fmt: skip


class _Resolve(Transformer):
    """The lark tree -> the description tree, every name resolved in one vocabulary (position on each error)."""

    def __init__(self, relational_set: str, names: dict, source: str | None):
        super().__init__()
        self.words, self.names, self.source = vocabulary_of(relational_set), names, source

    def _fail(self, reason: str, where) -> DescriptionError:
        line = getattr(where, "line", None)
        column = getattr(where, "column", None)
        return DescriptionError(reason, line, column, self.source)

    @v_args(meta=True)
    def progression(self, meta, children):
        part, steps = children[0], children[1:]
        try:
            feature, values = self.words.resolve(str(part), [str(s) for s in steps])
        except ParameterError as exc:
            raise self._fail(str(exc), next((s for s in steps if repr(str(s)) in str(exc)), part)) from None
        if len(values) < 2:
            raise self._fail(f"{part}: a progression needs at least two states (one state alone holds in every "
                             f"stretch where it holds); write e.g. '{part}: {self._states(feature)}'", part)
        for a, b, token in zip(values, values[1:], steps[1:]):
            if a is not None and a == b:
                raise self._fail(f"{part}: '{token}' twice in a row can never be seen (a state lasts until the "
                                 "other begins); write it once", token)  # fmt: skip
        return Progression(str(part), feature, tuple(values), tuple(str(s) for s in steps))

    def _states(self, feature: str) -> str:
        zero, one = self.words.states(feature)
        return f"{zero} {one} {zero}"

    def step(self, children):
        return children[0]

    @v_args(meta=True)
    def ref(self, meta, children):
        return ("ref", children, meta)

    def range(self, children):
        numbers = [c for c in children if c.type == "NUMBER"]
        low = float(numbers[0]) if numbers and children[0].type == "NUMBER" else None
        high = float(numbers[-1]) if numbers and children[-1].type == "NUMBER" else None
        return (low, high, children[0])

    def overlap(self, children):
        return ("overlap", children)

    def duration(self, children):
        return ("duration", children)

    def condition(self, children):
        kind, part, word = children
        try:
            feature, values = self.words.resolve(str(part), [str(word)])
        except ParameterError as exc:
            raise self._fail(str(exc), word if repr(str(word)) in str(exc) else part) from None
        if values[0] is None:
            raise self._fail(f"{kind} {part} *: name a state ({' or '.join(self.words.states(feature))})", word)
        return ("condition", Condition(str(kind), feature, int(values[0]), f"{part} {word}"))

    @v_args(meta=True)
    def event(self, meta, children):
        progressions = [c for c in children if isinstance(c, Progression)] or self._implied(children, meta)
        seen = {}
        for p in progressions:
            if p.feature in seen:
                raise self._fail(f"two progressions of {p.feature} in one event; join them into one", meta)
            seen[p.feature] = p
        overlaps, durations, conditions = [], [], []
        for kind, args in (c for c in children if isinstance(c, tuple)):
            if kind == "condition":
                conditions.append(args)
            elif kind == "overlap":
                overlaps.append(Overlap(self._ref(args[0], progressions), self._ref(args[1], progressions)))
            else:
                ref, (low, high, token) = self._ref(args[0], progressions), args[1]
                if low is not None and high is not None and low > high:
                    raise self._fail(f"{ref} for {low:g}..{high:g} s: the shortest time is longer than the longest",
                                     token)  # fmt: skip
                if low is None and high is None:
                    raise self._fail(f"{ref} for ..: give a shortest or a longest time (e.g. 0.1..1 s)", token)
                durations.append(Duration(ref, low, high))
        return Event(tuple(progressions), tuple(overlaps), tuple(durations), tuple(conditions))

    def _implied(self, children, meta) -> list[Progression]:
        """The progressions of an event written without any (``rfoot raised for 0.1..1 s``, ``overlap rknee bent,
        rfoot raised``, ``somewhere rhand above_neck``): each state it names, framed by the other state
        (``rfoot: lowered raised lowered``), so that its hit is that state's run. ``never`` alone is refused: it
        only drops hits."""
        states = []  # (part token, word token) in the order written
        for kind, args in (c for c in children if isinstance(c, tuple)):
            if kind == "condition" and args.kind == "somewhere":
                part, word = args.text.split(" ", 1)
                states.append((part, word))
            elif kind in ("overlap", "duration"):
                states += [(str(ref[1][0]), str(ref[1][1])) for ref in args if isinstance(ref, tuple) and ref[0] == "ref"]
        if not states:
            never = next(c[1].text for c in children if isinstance(c, tuple) and c[0] == "condition")
            raise self._fail(f"'never {never}' only drops the hits of an event where it holds: give the event a "
                             f"progression to drop them from, e.g. 'rknee: straight bent straight and never {never}'",
                             meta)  # fmt: skip
        implied = {}
        for part, word in states:
            feature, (value,) = self.words.resolve(part, [word])
            if part not in implied and value is not None:
                other = self.words.states(feature)[1 - value]
                implied[part] = Progression(part, feature, (1 - value, value, 1 - value), (other, word, other))
        return list(implied.values())

    def _ref(self, ref, progressions) -> StateRef:
        _, tokens, _meta = ref
        part, word = str(tokens[0]), str(tokens[1])
        matches = [i for i, p in enumerate(progressions) if p.part == part or p.feature == part]
        if not matches:
            raise self._fail(f"{part} {word}: no progression of this event describes {part} (it has "
                             f"{', '.join(p.part for p in progressions)})", tokens[0])  # fmt: skip
        for i in matches:
            p = progressions[i]
            try:
                value = self.words.state_of(part, word, p.feature)
            except ParameterError:
                continue
            steps = [k for k, v in enumerate(p.values) if v == value]
            text = f"{part} {word}"
            if len(tokens) > 2:
                n = tokens[2]
                if "." in n or not 1 <= int(n) <= len(steps):
                    raise self._fail(f"{part} {word}[{n}]: {excerpt(str(p))} has {len(steps)} '{word}' state(s); "
                                     f"number them 1..{len(steps)}", n)  # fmt: skip
                steps, text = [steps[int(n) - 1]], f"{text}[{n}]"
            if not steps:
                raise self._fail(f"{part} {word}: the progression {excerpt(str(p))} has no step '{word}'", tokens[1])
            return StateRef(i, tuple(steps), text)
        states = " or ".join(f"{progressions[i].part}: {'/'.join(self.words.states(progressions[i].feature))}"
                             for i in matches)  # fmt: skip
        raise self._fail(f"{part} {word}: not a state of this event's progression ({states})", tokens[1])

    def named(self, children):
        token = children[0]
        name = str(token)
        if name not in self.names:
            raise self._fail(f"unknown description {name!r}" + _closest(name, self.names)
                             + ("" if _closest(name, self.names) else "; see `mocapviz find --list`"), token)
        found = self.names[name]
        if isinstance(found, DescriptionError):
            raise self._fail(f"{name} cannot be used with the {self.words.relational_set} relational set: "
                             f"{found.reason}", token)  # fmt: skip
        return Named(name, found)

    def template(self, children):
        return TemplateAtom(str(children[0])[len("template:"):])

    def within(self, children):
        return (float(children[0]), children[0])

    def then(self, children):
        return ("then", children)

    def sequence(self, children):
        node = children[0]
        for _, (second, *within) in children[1:]:
            seconds = within[0][0] if within else DEFAULT_WITHIN
            node = Sequence(node, second, seconds)
        return node

    def alternatives(self, children):
        return children[0] if len(children) == 1 else Alternatives(tuple(children))

    def definition(self, children):
        return ("define", children[0], children[1])

    def start(self, children):
        return children


def _closest(word: str, options) -> str:
    near = difflib.get_close_matches(word, list(options), n=3, cutoff=0.6)
    return f"; did you mean {' or '.join(repr(n) for n in near)}?" if near else ""


def _resolve(tree, relational_set: str, names: dict, source: str | None):
    try:
        return _Resolve(relational_set, names, source).transform(tree)
    except VisitError as exc:
        if isinstance(exc.orig_exc, DescriptionError):
            raise exc.orig_exc from None
        raise


def _program(tree: Tree, relational_set: str, names: dict, source: str | None, keep_errors: bool = False):
    """(definitions, expression) of a text's tree; definitions are added to ``names`` in order (later ones see
    earlier)."""
    definitions, root, levels = {}, None, {}
    for child in tree.children:
        if isinstance(child, Tree) and child.data == "set_statement":
            continue
        if isinstance(child, Tree) and child.data == "definition":
            name_token, body = child.children
            try:
                definitions[str(name_token)] = _shallow(_resolve(body, relational_set, names, source), levels,
                                                        name_token, source)  # fmt: skip
            except DescriptionError as exc:
                if not keep_errors:
                    raise
                definitions[str(name_token)] = exc
            names = {**names, str(name_token): definitions[str(name_token)]}
        else:
            root = _shallow(_resolve(child, relational_set, names, source), levels, child.meta, source)
    return definitions, root


def _shallow(node, levels: dict, where, source: str | None):
    """``node`` if its tree, through the names it uses, is at most :data:`MAX_DEPTH` levels deep (``levels``: as
    :func:`_depth`), else the DescriptionError at ``where`` (a token or a lark meta)."""
    depth = _depth(node, levels)
    if depth > MAX_DEPTH:
        raise DescriptionError(f"the description is {depth} levels deep through the names it uses (a chain of n "
                               f"'then' is n levels); at most {MAX_DEPTH}", where.line, where.column,
                               source)  # fmt: skip
    return node


@cache
def named_descriptions(relational_set: str = "2005") -> dict:
    """The shipped descriptions (``named_descriptions.txt`` beside this module), resolved in a relational set.

    Parameters
    ----------
    relational_set : {"2005", "2006"}

    Returns
    -------
    dict
        Name -> description tree, or the DescriptionError saying why that name cannot be used with this set.

    Examples
    --------
    >>> shipped = named_descriptions()
    >>> {"kick_right", "punch_left", "squat"} <= set(shipped), type(shipped["kick_right"]).__name__
    (True, 'Event')
    """
    text = resources.files(__package__).joinpath(LIBRARY).read_text(encoding="utf-8")
    source = f"{__package__}/{LIBRARY}"
    definitions, root = _program(_syntax(text, source), relational_set, {}, source, keep_errors=True)
    assert root is None, "the shipped library holds definitions only"
    return definitions


def parse_description(text: str, relational_set: str | None = None) -> Description:
    """Read a scene description: its definitions and its query, every name resolved.

    Parameters
    ----------
    text : str
        The description (docs/descriptions.md): optional ``define NAME: ...;`` statements, then one expression.
    relational_set : {"2005", "2006"}, optional
        The set whose features the part and state words name (and whose relational index answers it); default:
        the one the text names (``set 2006;`` before everything else), else "2005".

    Returns
    -------
    Description

    Raises
    ------
    DescriptionError
        A syntax error, an unknown part, state or name (with the closest valid ones), a progression of one state,
        a negative or reversed time, a text beyond one of the limits (:data:`MAX_CHARS`, :data:`MAX_WORD`,
        :data:`MAX_PARENS`, :data:`MAX_THEN`, :data:`MAX_DEFINITIONS`, :data:`MAX_DEPTH`; checked before anything
        recursive runs); the message starts with the line and column and quotes at most :data:`EXCERPT` characters
        of the text.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH
       2005, §6.3, Fig. 10.

    Examples
    --------
    >>> d = parse_description("kick_right then punch_left within 2 s")
    >>> type(d.root).__name__, d.root.within
    ('Sequence', 2.0)
    >>> parse_description("rknee: straight bnt straight")
    Traceback (most recent call last):
    ...
    mocapviz.errors.DescriptionError: line 1, column 17: 'bnt' is not a state of rknee in the 2005 set; did you mean 'bent'?
    """
    if not isinstance(text, str):
        raise ParameterError(f"a description must be text; got {type(text).__name__}")
    tree = _syntax(text, None)
    declared = _set_token(tree)
    if relational_set is not None and declared is not None and relational_set != declared:
        raise DescriptionError(f"the description says 'set {declared};' but is read with the {relational_set} set",
                               declared.line, declared.column)  # fmt: skip
    relational_set = relational_set or (declared and str(declared)) or "2005"
    names = dict(named_descriptions(vocabulary_of(relational_set).relational_set))
    definitions, root = _program(tree, relational_set, names, None)
    if root is None:
        raise DescriptionError("the description has no query: after the definitions, write what to find (e.g. "
                               f"{next(iter(definitions), 'kick_right')})", *_line_column(text, len(text)))  # fmt: skip
    return Description(root, relational_set, definitions, text, declared is not None)
