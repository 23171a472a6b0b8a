"""The relational commands (Müller et al.): ``mocapviz query`` (query by example on chosen relational features)
and ``mocapviz find`` (what a scene description describes), through the engine."""
from __future__ import annotations

import time
from pathlib import Path

import pandas as pd

from ..engine import MotionTemplate, feature_groups, feature_names, is_template_name, named_descriptions, segment
from ..engine.parameters import default
from ..errors import MotionDBError, ParameterError
from ..validation import plural
from .inputs import engine_of, example_of
from .output import csv_folder, printed, write_csv


def run_query(args) -> None:
    csv_folder(args.csv)
    engine = engine_of(args)
    example = example_of(engine.db, args.example)
    features = None if args.features is None else [f.strip() for f in args.features.split(",") if f.strip()]
    known = feature_names(args.relational_set)
    if features == []:
        raise ParameterError(f"--features {args.features!r} names no feature; choose from the {args.relational_set} "
                             f"set: {', '.join(known)}")
    if args.allowed is not None and not args.mismatches:
        raise ParameterError("--mismatch-at lists the query segments that may disagree: it needs --mismatch M (M >= 1)")
    if args.mismatches and args.query_mode not in ("adaptive", "mismatch"):
        raise ParameterError(f"--mismatch {args.mismatches} answers in mismatch mode (adaptive hits with up to M "
                             f"segments disagreeing); leave out --mode {args.query_mode}")
    motion = engine._motion(example, args.frames)
    suggested = None
    if features is None:  # the clip's suggested query, as the Relational page poses it (docs/relational.md)
        suggested = engine.suggest_query(example, frames=args.frames, relational_set=args.relational_set)
        features = list(suggested.features)
    if args.mismatches and all(f in known for f in features):  # unknown names: the engine says which
        n = _query_segments(engine, motion, features, args.relational_set)
        if args.mismatches > n - 1:
            raise ParameterError(f"--mismatch must be between 0 and {n - 1}, one less than the query's {n} "
                                 f"segment(s) on the chosen features; got {args.mismatches}")
        outside = sorted({i for i in args.allowed or () if i >= n})
        if outside:
            raise ParameterError(f"--mismatch-at lists query segments from 0 to {n - 1} (the query has {n} on the "
                                 f"chosen features); got {', '.join(map(str, outside))}")
    mode, m = ("mismatch", args.mismatches) if args.mismatches else (args.query_mode, default("query", "mismatches"))
    if suggested is not None and not args.mismatches and mode == "adaptive":  # --mode left at its default
        mode, m = suggested.mode, suggested.mismatches
    t0 = time.perf_counter()
    with engine:
        hits = engine.query(example, frames=args.frames, features=features, mode=mode, mismatches=m,
                            relational_set=args.relational_set, allowed=args.allowed,
                            exclude_document=args.exclude_document)  # fmt: skip
    ms = 1000 * (time.perf_counter() - t0)
    how = f"{mode}, m = {m}" if mode == "mismatch" else mode
    chosen = "suggested features" if suggested is not None else "features"
    print(f"{plural(len(hits), 'hit')} in {ms:.1f} ms ({how}, {chosen}: {', '.join(features)})")
    cols = [c for c in ("rank", "doc_id", "name", "start", "end", "start_s", "end_s", "score", "label") if c in hits]
    with pd.option_context("display.width", 160, "display.max_rows", args.rows + 5):
        print(printed(hits[cols].head(args.rows).round(3)))
    write_csv(hits.head(args.rows), args.csv)


def _query_segments(engine, example, features: list[str], relational_set: str) -> int:
    """The segments of the example on the chosen features, fewest over the feature groups they touch: the L of an
    m-mismatch query (query_by_example segments each group's chosen features separately, m < L in each)."""
    values, names = engine.clip_relational(example, relational_set=relational_set)
    counts = [len(segment(values[:, [names.index(f) for f in features if f in members]]).codes)
              for members in feature_groups(relational_set).values() if any(f in members for f in features)]
    return min(counts)


def run_find(args) -> None:
    if args.list:
        for name, body in named_descriptions().items():
            print(f"{name}:\n    {body}")
        return
    if (args.description is None) == (args.file is None):
        raise ParameterError("give a description (in quotes) or --file FILE, not both; `mocapviz find --list` lists "
                             "the shipped names")  # fmt: skip
    if args.db is None:
        raise ParameterError("give the database: mocapviz find DB \"DESCRIPTION\"")
    text = args.description
    if args.file is not None:
        try:
            text = Path(args.file).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ParameterError(f"--file {args.file}: {exc.strerror if isinstance(exc, OSError) else exc}") from None
    csv_folder(args.csv)
    given = _template_files(args.template_files)
    with engine_of(args) as engine:
        hits = engine.find(text, n_matches=args.n_matches if args.label is None else None,
                           relational_set=args.relational_set, template_cost=args.template_cost,
                           templates=given or None)  # fmt: skip
        if args.label is not None:
            found, hits = len(hits), engine.with_label(hits, label=args.label).head(args.n_matches)
            if hits.empty and found:
                hits.attrs["empty_reason"] = f"none of its {plural(found, 'hit')} overlaps a stretch of {args.label!r}"
    if args.explain:
        print(hits.attrs["description"])
        print("matched: " + "; ".join(f"{label}: {n}" for label, n in hits.attrs["counts"]))
    print(f"{plural(len(hits), 'hit')} in {hits.attrs['ms']:.1f} ms ({hits.attrs['candidates']} before overlaps were "
          f"resolved; {hits.attrs['relational_set']} set" + ("" if args.label is None else
                                                             f"; those overlapping label {args.label!r}") + ")")  # fmt: skip
    if hits.empty:
        print(f"no hit: {hits.attrs['empty_reason']}")
        write_csv(hits, args.csv)
        return
    cols = [c for c in ("rank", "doc_id", "name", "start", "end", "start_s", "end_s", "score", "label") if c in hits]
    cols += ["parts"] if args.explain else []
    with pd.option_context("display.width", 200, "display.max_rows", len(hits) + 5, "display.max_colwidth", 120):
        print(printed(hits[cols].round(3)))
    write_csv(hits, args.csv)


def _template_files(items: list[str] | None) -> dict:
    """``find --template-file NAME=FILE`` (repeatable): name -> the MotionTemplate of FILE, for the description's
    ``template:NAME`` atoms. Only a file named here, on the command line, is ever opened; the description's text
    names stored templates only."""
    given: dict = {}
    for item in items or ():
        name, sep, file = item.partition("=")
        if not sep or not file or not is_template_name(name):
            raise ParameterError(f"--template-file {item[:80]!r}: give NAME=FILE, NAME as written after 'template:' "
                                 "(letters, digits, '.', '_' and '-', not first '.', at most 128 characters)")
        if name in given:
            raise ParameterError(f"--template-file {name}: given twice")
        try:
            given[name] = MotionTemplate.load(file)
        except MotionDBError as exc:
            raise ParameterError(f"--template-file {name}: {exc}") from None
    return given
