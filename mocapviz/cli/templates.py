"""The template commands (Müller & Röder 2006): ``mocapviz template learn`` (a class's motion template from its
labelled documents, stored with the database) and ``mocapviz template search`` (its instances), through the
engine."""
from __future__ import annotations

import time
from pathlib import Path

from ..engine import DONT_CARE, shortest_instance, store_template
from ..engine.parameters import arguments, default
from ..errors import ParameterError
from ..validation import one_of, plural, some_of
from .inputs import engine_of
from .output import csv_folder, print_ranked, write_csv


def run_template_learn(args) -> None:
    if args.out and not Path(args.out).parent.is_dir():
        raise ParameterError(f"--out {args.out}: no folder {Path(args.out).parent} to write it in")
    engine = engine_of(args)
    db = engine.db
    docs = db.documents
    examples = args.examples or []
    try:
        if not examples:  # takes given: the label may be new
            one_of(args.label, "label", sorted({*map(str, docs["label"].dropna().unique()),
                                                *engine.segment_labels()["label"]}))  # fmt: skip
    except ParameterError as exc:
        raise ParameterError(f"--label: {exc} (file-name labels and segment labels)") from None
    actors = None
    if args.actors is not None:
        if "actor" not in docs.columns:
            raise ParameterError(f"--actors: the documents of {db.path} have no actor column; leave --actors out")
        try:
            actors = some_of(args.actors.split(","), "actor", sorted(map(str, docs["actor"].dropna().unique())))
        except ParameterError as exc:
            raise ParameterError(f"--actors: {exc}") from None
    t0 = time.perf_counter()
    template = engine.learn_template(args.label, actors=actors, examples=examples,
                                     **arguments(args, "learn_template"))  # fmt: skip
    seconds = time.perf_counter() - t0
    stored = store_template(db, template)
    delta = default("search_template", "delta")
    dont_care = float((template.quantised(delta) == DONT_CARE).mean())
    n = template.n_examples
    meta = template.meta
    print(f"template {template.label!r} of {db.path} ({', '.join(actors) if actors else 'every actor'}): "
          f"{plural(n, 'example')} ({plural(meta['file_examples'], 'document')} with that file-name label, "
          f"{plural(meta['segment_examples'], 'segment label')}"
          + (f", {plural(meta['extra_examples'], 'take')} given with --example" if examples else "")
          + f"), {plural(len(template.values), 'frame')} x "
          f"{plural(len(template.features), 'feature')} of the "
          f"{args.relational_set} set, {dont_care:.0%} don't care (δ = {delta}), {plural(template.iterations, 'iteration')}, "
          f"{seconds:.1f} s")  # fmt: skip
    print(f"its examples' own best matches cost up to {meta['example_threshold']:.3f} per frame; its learned threshold "
          f"is {meta['threshold']:.3f} (`--max-cost {meta['threshold']:.3f}`: the cost that best separates them from "
          f"the {plural(meta['negatives'], 'clip')} of other labels, the nearest of which costs "
          + ("-" if meta["nearest_negative"] is None else f"{meta['nearest_negative']:.3f}") + ")")
    print(f"stored in {stored} (search it: `mocapviz template search {db.path} {stored.stem}`)")
    if args.out:
        template.save(args.out)
        print(f"written to {args.out}")


def run_template_search(args) -> None:
    csv_folder(args.csv)
    with engine_of(args) as engine:
        template = engine.template(args.template)
        try:
            table = engine.search_template(template, **arguments(args, "search_template"))
        except ParameterError as exc:
            raise ParameterError(f"{args.template}: {exc}") from None
    limit = "" if args.max_cost is None else f", normalised cost <= {args.max_cost:g}"
    n = template.n_examples
    aligned = f", keyframe pre-filter: {table.attrs['aligned']:.0%} of the frames aligned" if args.prefilter else ""
    print(f"{plural(len(table), 'match', 'matches')} of template {template.label!r} "
          f"({plural(len(template.values), 'frame')}, {plural(n, 'example')}, {table.attrs['relational_set']} set) in {engine.db.path}{limit}{aligned}, in "
          f"{table.attrs['ms']:.1f} ms")  # fmt: skip
    own = template.meta.get("threshold")
    if args.max_cost is not None:
        empty = "try a larger --max-cost" + ("" if own is None else f"; the template's learned threshold is {own:.3f}")
    else:
        empty = f"no document holds the template's shortest instance, {plural(shortest_instance(template), 'frame')}"
    print_ranked(table, args.n_matches, empty)
    write_csv(table, args.csv)
