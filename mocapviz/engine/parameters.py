"""Every parameter of the engine's use cases, declared once: its name, kind, bounds or choices, default and a
one-line doc (scikit-learn's ``_parameter_constraints`` is the model).

The :class:`~mocapviz.engine.engine.Engine` checks its keyword arguments against this table at its boundary
(:func:`checked`); the command line's options (:meth:`Parameter.add_to`: type check, default and ``--help``), the
dashboard's widgets (:meth:`Parameter.widget`: bounds, step, default, choices) and docs/parameters.md
(:func:`markdown`) are made from it, so no front offers a default, a bound or a choice the run does not share.
A use case may give a parameter its own default (:data:`USE_DEFAULTS`: kNN lists 16 neighbours, the lazy
neighbourhood graph asks 256 per frame); every front uses that default for that use case.
"""
from __future__ import annotations

import argparse
import functools
import inspect
from dataclasses import dataclass, field, replace

from .. import validation
from ..errors import ParameterError
from ..export.formats import FORMATS, RIGS
from ..features import NUMERIC_SETS, POSITION_SETS, RELATIONAL_SETS
from ..io.humanml3d import LAYOUTS
from ..validation import (
    MARKERS_ONLY,
    MIN_LENGTH,
    MIN_LENGTH_RANGE,
    count,
    number,
    one_of,
    parse_count,
    parse_names,
    parse_number,
)

__all__ = ["PARAMETERS", "USE_DEFAULTS", "Parameter", "checked", "markdown", "parameter"]


@dataclass(frozen=True)
class Parameter:
    """One parameter: ``kind`` "int", "float", "bool", "choice", "names" (a list of names or ints, checked by
    the kernel that knows its options) or "text" (a printable text of 1 to ``high`` characters, e.g. a segment
    label's name); ``low`` / ``high`` (closed unless ``low_open`` / ``high_open``) bound a
    number, ``choices`` a choice; ``optional``: None is allowed (meaning ``none_means``).

    Examples
    --------
    >>> n = Parameter("n_matches", "int", 10, "matches to report", low=1)
    >>> n.check(3), n.check(None) if n.optional else "required"
    (3, 'required')
    >>> n.check(0)
    Traceback (most recent call last):
    ...
    mocapviz.errors.ParameterError: n_matches must be at least 1; got 0
    """

    name: str
    kind: str
    default: object
    doc: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple = ()
    optional: bool = False
    none_means: str = ""
    flags: tuple = field(default=())  # command-line spellings; default --name-with-dashes

    def check(self, value, where: str = ""):
        """``value`` as this parameter's type inside its bounds, or a ParameterError naming it (``where``: the
        spelling a front used, such as ``-K/--matches``)."""
        name = where or self.name
        if value is None and (self.optional or self.kind == "names"):
            return None
        if self.kind == "int":
            return count(value, name, int(self.low) if self.low is not None else -(2**62),
                         None if self.high is None else int(self.high))  # fmt: skip
        if self.kind == "float":
            return number(value, name, self.low, self.high, self.low_open, self.high_open)
        if self.kind == "bool":
            if not isinstance(value, bool) and type(value).__name__ != "bool_":
                raise ParameterError(f"{name} must be True or False; got {value!r}")
            return bool(value)
        if self.kind == "choice":
            return one_of(str(value) if value is not None else value, self.name.replace("_", " "), self.choices)
        if self.kind == "text":
            return validation.text(value, name, int(self.high))
        return list(value)

    @property
    def bounds(self) -> str:
        """A number's interval as text ("[1, inf)", "(0, 0.5)"), a text's length ("1 to 128 characters"), else ""."""
        if self.kind == "text":
            return f"1 to {self.high:g} printable characters"
        if self.kind not in ("int", "float") or (self.low is None and self.high is None):
            return ""
        lo = "(-inf" if self.low is None else f"{'(' if self.low_open else '['}{self.low:g}"
        hi = "inf)" if self.high is None else f"{self.high:g}{')' if self.high_open else ']'}"
        return f"{lo}, {hi}"

    @property
    def cli_flags(self) -> tuple:
        return self.flags or ("--" + self.name.replace("_", "-"),)

    def help(self, default=None) -> str:
        """The one-line doc with its bounds and default, as ``--help`` prints it."""
        default = self.default if default is None else default
        parts = [self.doc]
        if self.choices:
            parts.append("one of " + ", ".join(map(str, self.choices)))
        elif self.bounds:
            parts.append(self.bounds)
        if self.kind != "bool":
            parts.append(f"default {self.none_means or 'none'}" if default is None else f"default {default}")
        return f"{parts[0]} ({'; '.join(parts[1:])})" if len(parts) > 1 else parts[0]

    def reader(self, shown: str):
        """An argparse ``type`` for this parameter: the text read as its kind, then checked (:meth:`check`);
        ``shown``: the option's spellings, for the message."""

        def parse(text: str):
            try:
                if self.kind == "int":
                    low = -(2**62) if self.low is None else int(self.low)
                    return parse_count(text, shown, low, None if self.high is None else int(self.high))
                if self.kind == "float":
                    return parse_number(text, shown, self.low, self.high, self.low_open, self.high_open)
                if self.kind == "choice":  # one name: a list is refused, not cut to its first name
                    return parse_names(text, shown, self.name.replace("_", " "), self.choices, one=True)[0]
                return self.check(text, shown)
            except ParameterError as exc:
                raise argparse.ArgumentTypeError(str(exc)) from None

        return parse

    def add_to(self, parser: argparse.ArgumentParser, *flags: str, default=None, **kwargs) -> None:
        """This parameter as an option of ``parser`` (``flags``: its spellings there, default :attr:`cli_flags`):
        the text is read, then checked (:meth:`reader`); a bool is a switch; ``default`` the use case's own."""
        flags = flags or self.cli_flags
        default = self.default if default is None else default
        if self.kind == "bool":  # --name, and --no-name where it is on by default
            action = argparse.BooleanOptionalAction if default else "store_true"
            parser.add_argument(*flags, dest=self.name, action=action, default=default,
                                help=self.help(default) + (" (on by default)" if default else ""), **kwargs)
            return
        parser.add_argument(*flags, dest=self.name, type=self.reader("/".join(flags)), default=default,
                            help=self.help(default), **kwargs)  # fmt: skip

    def widget(self, default=None) -> dict:
        """Keyword arguments for a Panel widget of this parameter: ``name``, ``value`` and the bounds
        (``start`` / ``end`` for numbers, an open end moved in by one step) or ``options``."""
        value = self.default if default is None else default
        if self.kind == "choice":
            return {"value": value, "options": list(self.choices)}
        if self.kind in ("int", "float"):
            step = 1 if self.kind == "int" else 0.01
            start = None if self.low is None else self.low + (step if self.low_open else 0)
            end = None if self.high is None else self.high - (step if self.high_open else 0)
            if self.kind == "float":
                start, end = (None if v is None else round(v, 4) for v in (start, end))
            return {"value": value, "start": start, "end": end, "step": step}
        return {"value": value}


def _p(*args, interval=None, **kwargs) -> Parameter:
    """A Parameter; ``interval``: the kernel's own :class:`~mocapviz.validation.Interval` of a number, whose bounds
    it takes (declared once, where the kernel checks them for its direct callers)."""
    if interval is not None:
        kwargs.update(low=interval.low, high=interval.high, low_open=interval.low_open, high_open=interval.high_open)
    return Parameter(*args, **kwargs)


PARAMETERS: dict[str, Parameter] = {p.name: p for p in [
    _p("n_matches", "int", 10, "matches to report", low=1, flags=("-K", "--matches")),
    _p("numeric_set", "choice", "F15E", "numeric feature set (Krüger et al. 2010 §3.2)", choices=NUMERIC_SETS),
    _p("mode", "choice", "exact", "similarity search: exact (brute force's answer, pruned by lower bounds), fast "
       "(aligns only where kNN and a coarse pass point) or brute (every cell)", choices=("exact", "fast", "brute")),
    _p("min_length", "float", MIN_LENGTH, "the shortest match, a share of the query's frames",
       interval=MIN_LENGTH_RANGE, optional=True, none_means="any length"),
    _p("exclude_document", "bool", True, "leave out the example's own document (an example that is a document of "
       "the database finds itself first otherwise; no effect for a Motion or a file)"),
    _p("paths", "bool", False, "also return each match's warping path"),
    _p("k", "int", 16, "neighbours per query frame", low=1),
    _p("radius", "float", None, "only neighbours closer than this (feature units, cm)", low=0.0, low_open=True,
       optional=True, none_means="no limit"),
    _p("eps", "float", 0.0, "approximate kNN: the k-th distance within (1 + eps)", low=0.0),
    _p("method", "choice", "lng", "global matching by the lazy neighbourhood graph or subsequence DTW",
       choices=("lng", "dtw")),
    _p("relational_set", "choice", "2005", "relational feature set (2005: Müller et al.; 2006: Müller & Röder)",
       choices=RELATIONAL_SETS),
    _p("query_mode", "choice", "adaptive", "relational query: exact, fuzzy, adaptive fuzzy or m-mismatch hits "
       "(Müller et al. 2005 §5)", choices=("exact", "fuzzy", "adaptive", "mismatch"), flags=("--mode",)),
    _p("mismatches", "int", 1, "query segments that may disagree (mismatch mode)", low=0, flags=("--mismatch",)),
    _p("allowed", "names", None, "the query segments that may disagree (default any)", flags=("--mismatch-at",)),
    _p("features", "names", None, "relational features of the query (default all of the set)"),
    _p("delta", "float", 0.2, "template quantisation threshold δ: < δ is 0, > 1 - δ is 1, else don't care (0.2: "
       "at the paper's 0.1, 5 of 8 class templates gave all their 20 hits at cost 0 on the shared archives)",
       low=0.0, high=0.5, low_open=True, high_open=True),  # relational.templates.DELTA_RANGE (a test keeps them equal)
    _p("max_cost", "float", None, "only matches of normalised cost at most this", low=0.0, high=1.0, optional=True,
       none_means="the K best, whatever their cost"),  # relational.templates.MAX_COST_RANGE
    _p("prefilter", "bool", False, "align only where the template's keyframes occur in order in the inverted "
       "indexes (faster; may miss a hit)"),
    _p("lower_bounds", "bool", True, "align the documents best lower bound first and stop when no other can hold "
       "one of the K best (the full pass's answer, aligning a fraction of the frames); off: the full pass over every "
       "frame"),
    _p("max_examples", "int", 16, "learn from at most this many of the class's documents, spread over them (a "
       "template of 16 found 20 of 20 of its class on every shared archive)", low=1),
    _p("iterations", "int", 10, "learning a template: at most this many rounds of warping and averaging the examples "
       "(Müller & Röder 2006 §3; it stops sooner when the template settles)", low=1),
    _p("template_cost", "float", None, "a description's template atoms: the largest normalised cost of a hit",
       low=0.0, high=1.0, optional=True, none_means="each template's learned threshold"),
    _p("overlapping", "bool", False, "keep hits of a description that overlap"),
    _p("per_document", "bool", False, "kNN: one row per document, its nearest frame"),
    _p("label", "text", None, "a segment label's name (the class of a stretch)", high=128, optional=True,
       none_means="every label"),
    _p("author", "text", None, "who made the change (recorded with it)", high=128, optional=True,
       none_means="the user name of the operating system"),
    _p("source", "choice", "manual", "where a segment label comes from (a rejected hit says the stretch is not of "
       "its label)", choices=("manual", "accepted hit", "rejected hit", "imported")),  # db.segments.SOURCES
    _p("note", "text", None, "a note kept with a segment label", high=1000, optional=True, none_means="no note"),
    _p("audit_set", "choice", "F15E", "the audit's numeric feature set: body-frame joint positions (Krüger et al. "
       "2010 §3.2; no PCA set)", choices=POSITION_SETS, flags=("--numeric-set",)),
    _p("audit_length", "float", 1.0, "the shortest stretch of a pair of copies, seconds", low=0.1, high=60.0,
       flags=("--min-length",)),
    _p("threshold", "float", None, "the largest mean DTW cost of a pair of copies (cm on the common body)", low=0.0,
       low_open=True, optional=True, none_means="learned from the collection's own copies (docs/audit.md)"),
    _p("max_scale", "float", 1.25, "time scalings of a copy within [1 / max_scale, max_scale]", low=1.0,
       high=4.0),
    _p("mirrored", "bool", True, "also find left/right-mirrored copies", flags=("--mirrored",)),
    _p("marker_mapping", "text", None, "C3D marker mapping file: CSV lines 'label,marker' renaming a lab's marker "
       "labels onto a marker set's names (docs/c3d.md)", high=4096, optional=True, none_means="the file's labels",
       flags=("--marker-mapping",)),
    _p("markers_only", "choice", "refuse", "a C3D file whose markers match no marker set: refuse it, or keep it as a "
       "marker-only document (its markers stored, no canonical joints; searched by its markers only: docs/c3d.md)",
       choices=MARKERS_ONLY),
    _p("take", "text", None, "FBX: the take (animation stack) to read from each FBX file, one document per file "
       "(docs/fbx.md)", high=1024, optional=True, none_means="every take, a document each"),
    _p("label_format", "choice", "csv", "segment labels' file: CSV with the hit table's columns, or BABEL-style "
       "JSON (per sequence, segments in seconds with action names)", choices=("csv", "babel"), flags=("--format",)),
    _p("export_format", "choice", "bvh", "exported files: bvh (BVH), amc (AMC with its ASF; ASF/AMC sources only), "
       "glb (glTF binary) or humanml3d (HumanML3D's joints: one (T, 22, 3) .npy per hit at 20 fps in metres, and "
       "manifest.csv)", choices=FORMATS, flags=("--format",)),
    _p("rig", "choice", None, "exported skeleton: source (the source file's frames on its own rig) or canonical "
       "(the 24 canonical joints posed to the database's frames)", choices=RIGS, optional=True,
       none_means="canonical for glb and humanml3d, source otherwise"),
    _p("layout", "choice", None, "what the joints of a .npy array are: humanml3d (HumanML3D's 22 joints, (T, 22, 3) "
       "in metres, y up, 20 fps)", choices=LAYOUTS, optional=True, none_means="none: a .npy file needs one"),
]}
"""The table, by name."""

USE_DEFAULTS = {
    ("find", "n_matches"): 20,  # a description's hits shown at first (None in Python: every hit)
    ("search_template", "n_matches"): 20,  # as many as the classes' hits the templates page measures
    ("match", "k"): None,  # the graph's neighbours per frame: 256 at 30 Hz, scaled with the rate and the database's
    # size (mocapviz.similarity.motion_matching.graph_k: Krüger et al. 2010 §4.2's 256 find no path in a large one)
    ("learn_template", "relational_set"): "2006",  # Müller & Röder 2006 learn on their own set
}
"""A use case's own default of a parameter, for every front: (use case, parameter) -> default (None: a rule of the
use case, :data:`RULES`)."""

RULES = {("match", "k"): "256 at 30 Hz, scaled with the rate and with the database's frames past 100,000 at 30 Hz "
                         "(graph_k)"}
"""What a use case does when its default is None, in words (docs/parameters.md)."""


USES = {
    "knn": {"k": "k", "numeric_set": "numeric_set", "radius": "radius", "eps": "eps"},
    "neighbours": {"k": "k", "numeric_set": "numeric_set", "radius": "radius", "eps": "eps",
                   "exclude_document": "exclude_document", "per_document": "per_document"},
    "clips": {"n_matches": "n_matches", "numeric_set": "numeric_set", "mode": "mode",
              "exclude_document": "exclude_document", "paths": "paths"},
    "stretches": {"n_matches": "n_matches", "numeric_set": "numeric_set", "mode": "mode", "min_length": "min_length",
                  "exclude_document": "exclude_document", "paths": "paths"},
    "match": {"numeric_set": "numeric_set", "method": "method", "n_matches": "n_matches", "k": "k", "radius": "radius",
              "eps": "eps", "exclude_document": "exclude_document", "paths": "paths", "min_length": "min_length"},
    "query": {"features": "features", "mode": "query_mode", "mismatches": "mismatches",
              "relational_set": "relational_set", "allowed": "allowed", "exclude_document": "exclude_document"},
    "suggest_query": {"relational_set": "relational_set"},
    "find": {"template_cost": "template_cost", "overlapping": "overlapping"},
    "learn_template": {"relational_set": "relational_set", "max_examples": "max_examples", "iterations": "iterations"},
    "search_template": {"n_matches": "n_matches", "delta": "delta", "max_cost": "max_cost", "prefilter": "prefilter",
                        "lower_bounds": "lower_bounds"},
    "segment_labels": {"label": "label"},
    "add_label": {"label": "label", "author": "author", "source": "source", "note": "note"},
    "remove_label": {"author": "author"},
    "undo_label": {"author": "author"},
    "export_labels": {"format": "label_format", "label": "label"},
    "import_labels": {"author": "author"},
    "audit": {"numeric_set": "audit_set", "min_length": "audit_length", "threshold": "threshold",
              "max_scale": "max_scale", "mirrored": "mirrored"},
    "audit_path": {"numeric_set": "audit_set"},
    "export": {"format": "export_format", "rig": "rig"},
    "marker_stretches": {"n_matches": "n_matches", "min_length": "min_length", "exclude_document": "exclude_document"},
}  # fmt: skip
"""Each use case's keyword arguments and the declared parameter each one is (most have its name): the engine
checks them (:func:`checked`), the command line offers them (:func:`add_options`, :func:`arguments`)."""


def parameter(name: str) -> Parameter:
    """The declared parameter ``name``."""
    return PARAMETERS[name]


def default(use: str, name: str):
    """The default of parameter ``name`` in use case ``use`` (:data:`USE_DEFAULTS`, else the table's)."""
    return USE_DEFAULTS.get((use, name), PARAMETERS[name].default)


def checked(use: str):
    """Decorator of the engine's method of use case ``use``: its keyword arguments of :data:`USES` are checked
    against the table once, at the call; a default of ``...`` in the method's signature is the table's default for
    the use case.

    Examples
    --------
    >>> @checked("search_template")
    ... def f(*, n_matches=..., delta=..., max_cost=..., prefilter=..., lower_bounds=...):
    ...     return n_matches, delta
    >>> f(), f(n_matches=3)
    ((20, 0.2), (3, 0.2))
    """

    def wrap(function):
        signature = inspect.signature(function)
        declared = {arg: PARAMETERS[p] for arg, p in USES[use].items()}
        defaults = {arg: default(use, p.name) for arg, p in declared.items()}
        if any(signature.parameters[arg].kind is not inspect.Parameter.KEYWORD_ONLY for arg in declared):
            raise TypeError(f"{function.__qualname__}: the parameters of {use} must be keyword-only")

        @functools.wraps(function)
        def run(*args, **kwargs):
            for arg, p in declared.items():
                value = kwargs.get(arg, ...)
                none = value is None and defaults[arg] is None
                kwargs[arg] = defaults[arg] if value is ... or none else p.check(value, arg)
            return function(*args, **kwargs)

        run.__signature__ = signature.replace(parameters=[
            q.replace(default=default(use, declared[q.name].name)) if q.name in declared else q
            for q in signature.parameters.values()])  # fmt: skip
        run.use_case = use
        run.parameters = {arg: replace(p, default=default(use, p.name)) for arg, p in declared.items()}
        return run

    return wrap


def add_options(parser: argparse.ArgumentParser, use: str, spellings: dict | None = None, skip=()) -> None:
    """Every parameter of use case ``use`` (:data:`USES`) as an option of ``parser`` with the use case's default,
    except those in ``skip`` and those the parser has already (a front's own spelling or help); ``spellings``:
    {parameter: flags} where a command spells one differently (an old name kept)."""
    have = {action.dest for action in parser._actions}
    for name in USES[use].values():
        if name not in have and name not in skip:
            PARAMETERS[name].add_to(parser, *(spellings or {}).get(name, ()), default=default(use, name))


def arguments(args, use: str, **given) -> dict:
    """The keyword arguments of use case ``use`` from the command line's ``args`` (an argparse Namespace; what it
    lacks is left to the engine's default), with ``given`` instead where a command decides them itself."""
    found = {arg: getattr(args, name) for arg, name in USES[use].items() if hasattr(args, name)}
    return {**found, **given}


def markdown() -> str:
    """The table as docs/parameters.md shows it (tests/test_parameters.py checks the file equals this)."""
    lines = ["| parameter | kind | bounds or choices | default | what it is |", "|---|---|---|---|---|"]
    for p in PARAMETERS.values():
        bounds = ", ".join(map(str, p.choices)) if p.choices else p.bounds
        shown = p.none_means or "none" if p.default is None else str(p.default)
        own = [f"{use}: {RULES.get((use, name), value)}" for (use, name), value in USE_DEFAULTS.items()
               if name == p.name]
        shown += f" ({'; '.join(own)})" if own else ""
        lines.append(f"| `{p.name}` | {p.kind} | {bounds} | {shown} | {p.doc} |")
    return "\n".join(lines) + "\n"
