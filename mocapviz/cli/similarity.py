"""The similarity commands (Krüger et al.): ``mocapviz features`` (the numeric feature sets they search, stored
with the database), ``mocapviz knn`` (the nearest frames of a frame), ``mocapviz match`` (stretches that move like
an example: lazy neighbourhood graph or subsequence DTW) and ``mocapviz search`` (clips or stretches by DTW),
through the engine."""
from __future__ import annotations

import time
from pathlib import Path

import pandas as pd

from .. import io as readers  # lazy: a reader loads when a file is given
from ..engine import NUMERIC_SETS, Engine, MotionDB, PCAModel, layout, load_numeric, stored_sets, update_derived
from ..engine.parameters import arguments
from ..errors import MocapvizError, ParameterError
from ..validation import plural
from .inputs import engine_of, example_of
from .options import STRETCH_POOL, scheduler_of
from .output import csv_folder, print_paths, print_ranked, printed, write_csv

PCA_SETS = tuple(n for n in NUMERIC_SETS if n.startswith("Fp"))
"""The numeric sets made by PCA (``features --pca``)."""


def run_features(args) -> None:
    engine = Engine(args.db)
    db = engine.db
    names = list(args.numeric_sets or NUMERIC_SETS)
    reference = _pca_reference(args.pca, args.numeric_sets)
    if reference is None:  # sets stored before an ingest: extended with the new documents
        stale = [n for n in names if n in stored_sets(db)["numeric"]]
        table = update_derived(db, [], stale, progress=not args.quiet, rebuild=False)
        extended = table[table["how"] == "extended"]
        if len(extended):
            print(f"{db}: {plural(len(extended), 'numeric feature set')} in {layout.features_folder(db.path)} "
                  f"extended with the {plural(extended['documents'].iloc[0], 'document')} "
                  f"({plural(extended['frames'].iloc[0], 'frame')}) added since they were stored, in {extended['seconds'].sum():.1f} s")  # fmt: skip
        names = [n for n in names if n not in set(extended["set"])]
        if not names:
            return
    t0 = time.perf_counter()
    stored = engine.store_numeric(names, pca=reference, progress=not args.quiet, scheduler=scheduler_of(args))
    print(f"{db}: {len(stored)} numeric feature sets in {time.perf_counter() - t0:.1f} s, "
          f"written to {layout.features_folder(db.path)}")
    rows = [{"set": n, "dims": a.shape[1], "MB": a.nbytes / 2**20} for n, a in stored.items()]
    print(pd.DataFrame(rows).round(1).to_string(index=False))


def _pca_reference(text: str | None, names: list[str] | None) -> MotionDB | PCAModel | None:
    """``--pca``: a MotionDB to fit the PCA model on, or a saved model; refused when no Fp set is asked for."""
    if text is None:
        return None
    if names is not None and not set(names) & set(PCA_SETS):
        raise ParameterError(f"--pca is the reference of the PCA sets {', '.join(PCA_SETS)}; --numeric-sets "
                             f"{','.join(names)} has none of them")
    ref = Path(text)
    if not ref.exists():
        raise ParameterError(f"--pca {text}: no such file or folder; give a saved PCA model (.npz) or a MotionDB")
    try:
        return MotionDB.open(ref) if ref.is_dir() else PCAModel.load(ref)
    except MocapvizError as exc:
        raise ParameterError(f"--pca: {exc}") from None


def run_knn(args) -> None:
    csv_folder(args.csv)
    doc, frame = args.frame
    with engine_of(args) as engine:
        try:
            engine.db.frames(doc)
        except ParameterError as exc:
            raise ParameterError(f"--frame {doc}:{frame}: {exc}") from None
        span = engine.db.frames(doc)
        n = span.stop - span.start
        if not 0 <= frame < n:
            raise ParameterError(f"--frame {doc}:{frame}: document {doc} has frames 0..{n - 1}")
        hits = engine.neighbours(doc, frame, **arguments(args, "neighbours"))
        how = repr(engine)
    each = f"; one row per document: the nearest in each of {len(hits)}" if args.per_document else ""
    print(f"{plural(hits.attrs['found'], 'neighbour')} of document {doc} frame {frame} by {args.numeric_set} in "
          f"{hits.attrs['ms']:.2f} ms ({how}){each}")  # fmt: skip
    cols = [c for c in ("rank", "doc_id", "name", "start", "start_s", "distance", "label") if c in hits]
    with pd.option_context("display.width", 160, "display.max_rows", args.k + 5):
        print(printed(hits[cols].round(3)))
    write_csv(hits, args.csv)


def run_match(args) -> None:
    if args.method == "dtw":
        given = [o for o, v in (("-k", args.k), ("--radius", args.radius), ("--eps", args.eps)) if v is not None]
        if given:
            raise ParameterError(f"{', '.join(given)} shape the neighbourhood graph of --method lng; subsequence DTW "
                                 "(--method dtw) compares every frame: leave them out")
    csv_folder(args.csv)
    with engine_of(args) as engine:
        load_numeric(engine.db, args.numeric_set)  # a clear error naming `mocapviz features DB` when not stored
        example = example_of(engine.db, args.example)
        table = engine.match(example, frames=args.frames,
                             **arguments(args, "match", eps=... if args.eps is None else args.eps))
    k = table.attrs.get("k", "")
    what = "subsequence DTW" if args.method == "dtw" else f"lazy neighbourhood graph, k={k}" + (
        f", r={args.radius:g}" if args.radius else "")  # fmt: skip
    own = isinstance(example, int) and args.exclude_document
    print(f"{plural(len(table), 'match', 'matches')} of a {table.attrs['query_frames']}-frame query by {args.numeric_set} ({what}), each "
          f"at least {args.min_length:g} × the query long, in {table.attrs['ms']:.1f} ms"
          + (" (the query's own document excluded)" if own else ""))  # fmt: skip
    print_ranked(table, args.n_matches, "the lazy neighbourhood graph needs a neighbour of every query frame along a "
                  "whole path: try a larger -k such as 1024, --method dtw, or `mocapviz search DB --stretches`"
                  if args.method == "lng" else "no document long enough outside the query's own")  # fmt: skip
    print_paths(table, args.paths)
    write_csv(table, args.csv)


def run_markers(args) -> None:
    csv_folder(args.csv)
    engine = Engine(args.db)
    example = _marker_example(engine.db, args.example)
    table = engine.marker_stretches(example, frames=args.frames, **arguments(args, "marker_stretches"))
    left = [plural(table.attrs[k], "marker-only document") + why for k, why in
            (("other_markers", " of other marker labels"), ("other_rate", " at another frame rate")) if table.attrs[k]]
    print(f"{plural(len(table), 'stretch', 'stretches')} like {args.example} "
          f"({plural(table.attrs['query_frames'], 'frame')}) by DTW on the marker numeric set, among "
          f"{plural(table.attrs['searched'], 'marker-only document')}, in {table.attrs['ms']:.1f} ms"
          + (" (its own document excluded)" if args.exclude_document else "")
          + (f"; not compared: {', '.join(left)}" if left else ""))  # fmt: skip
    print_ranked(table, args.n_matches, "no marker-only document of the example's marker labels and rate is long "
                 "enough: try a shorter --frames span or --no-exclude-document")  # fmt: skip
    write_csv(table, args.csv)


def _marker_example(db: MotionDB, text: str):
    """``markers --example``: a marker-only document's id (a negative integer) or a C3D file (its markers)."""
    if text.startswith("-") and text[1:].isdigit():
        return int(text)
    if Path(text).is_file():
        return readers.load(text)
    raise ParameterError(f"--example {text} is neither a marker-only document id (negative) of {db.path} nor a file")


def run_search(args) -> None:
    if args.min_length is not None and not args.stretches:
        raise ParameterError("--min-length is the shortest stretch as a share of the query: it needs --stretches")
    csv_folder(args.csv)
    with engine_of(args) as engine:
        example = example_of(engine.db, args.example)
        pool = {} if args.label is None else {"n_matches": STRETCH_POOL * args.n_matches if args.stretches else
                                                            max(len(engine.db), 1)}  # fmt: skip
        if args.stretches:
            table = engine.stretches(example, frames=args.frames, **arguments(
                args, "stretches", min_length=... if args.min_length is None else args.min_length, **pool))
        else:
            table = engine.clips(example, frames=args.frames, **arguments(args, "clips", **pool))
        if args.label is not None:
            table = engine.with_label(table, label=args.label).head(args.n_matches)
    what = ("stretch", "stretches") if args.stretches else ("clip", "clips")
    print(f"{plural(len(table), *what)} like {args.example} ({plural(table.attrs['query_frames'], 'frame')}) by DTW on {args.numeric_set}"
          f", {args.mode} mode, in {table.attrs['ms']:.1f} ms" + (" (its own document excluded)" if
                                                                 args.exclude_document else "")
          + ("" if args.label is None else f"; those overlapping label {args.label!r}"))  # fmt: skip
    print_ranked(table, args.n_matches, "the query's own document is the only one long enough; try whole clips, a "
                  "shorter --frames span or a smaller --min-length" if args.stretches else "no other document to "
                  "compare")  # fmt: skip
    print_paths(table, args.paths)
    write_csv(table, args.csv)
