"""The ``mocapviz`` command.

    mocapviz ingest PATH... --out DB [--fps N] [--labels FILE] [--skip-bad] [--scheduler ADDRESS | [--no-cluster] [--jobs N]]
    mocapviz info DB [--documents]
    mocapviz index DB [--relational-set 2005|2006] [--scheduler ADDRESS | --no-cluster]
    mocapviz query DB --example FILE|DOC_ID [--frames A:B] --features NAMES [--mode M] [--mismatch M [--mismatch-at I,J]]
                      [--relational-set 2005|2006] [-K 20]
    mocapviz features DB [--numeric-sets F15E,F30E,...] [--pca FILE|DB] [--scheduler ADDRESS | --no-cluster]
    mocapviz knn DB --frame DOC:FRAME [--numeric-set F15E] [-k 16] [--radius R] [--eps E] [--exclude-document]
    mocapviz match DB --example FILE|DOC_ID [--frames A:B] [--numeric-set F15E] [-K 10] [-k 256] [--radius R] [--eps E]
                                                                                    [--method lng|dtw] [--paths]
    mocapviz search DB --example FILE|DOC_ID [--frames A:B] [--numeric-set F15E] [-K 10] [--mode fast|exact|brute]
                       [--stretches [--min-length 0.5]] [--exclude-document] [--csv FILE] [--paths]
    mocapviz reproduce NAME|all [--full] --out DIR   (NAME: an experiment, e.g. rank_correlations, reconstruction)
    mocapviz serve [DB] [--port 5006] [--address 127.0.0.1] [--show]   (no DB: the embedded sample)
    mocapviz datasets list
    mocapviz datasets fetch NAME        (NAME: a shared archive, or ``sample`` for the embedded sample)

``ingest``, ``features`` and ``index`` run their work as Dask tasks: on the scheduler at ``--scheduler ADDRESS``
(``tcp://host:8786``), else on a local cluster started for the command (one single-threaded worker process per
core, or ``ingest --jobs N`` workers; :mod:`mocapviz.cluster`). ``--no-cluster`` runs in this process instead, on
threads (for ``ingest``, ``--jobs N`` of them), as the library functions do by default.

Options follow docs/glossary.md: ``-K`` / ``--matches`` is how many results (hits, clips, stretches) to report,
``-k`` how many neighbours per query frame, ``--relational-set`` / ``--numeric-set(s)`` which features. The older
spellings still work: ``--top`` (query, for ``-K``), ``--feature-set`` (for ``--relational-set``), ``--features``
(knn, match, search: for ``--numeric-set``) and ``--sets`` (features: for ``--numeric-sets``).

Errors print one line (``mocapviz: error: ...``) and exit with status 1.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from . import datasets
from .cluster import LOCAL, dask_client, optional_client
from .database import MotionDB, expand_paths
from .errors import MocapvizError, ParameterError
from .features import (
    NUMERIC_SETS,
    PCAModel,
    fit_pca,
    load_numeric,
    numeric_features,
    numeric_of,
    relational_features,
    store_numeric,
)
from .features.numeric import default_pca
from .index import build
from .io import load
from .knn import KnnIndex, describe_frames
from .match import lng, subsequence_dtw
from .query import query_by_example
from .validation import count


def _scheduler(args):
    """The ``scheduler=`` of the ingest / features / index commands: None (--no-cluster), an address, or local."""
    if args.no_cluster:
        if args.scheduler:
            raise ParameterError("--scheduler and --no-cluster exclude each other")
        return None
    return args.scheduler or LOCAL


def _ingest(args) -> None:
    mapping = None
    if args.mapping:
        with open(args.mapping) as fh:
            try:
                mapping = json.load(fh)
            except json.JSONDecodeError as exc:
                raise ParameterError(f"--mapping {args.mapping}: not JSON ({exc})") from None
    options = {k: v for k, v in (("asf", args.asf), ("up", args.up)) if v is not None}
    if args.jobs is not None and args.jobs < 1:
        raise ParameterError(f"--jobs must be at least 1, got {args.jobs}")
    scheduler = _scheduler(args)
    if args.jobs is not None and scheduler not in (None, LOCAL):
        raise ParameterError("--jobs sizes the local cluster (or, with --no-cluster, the reader threads); the "
                         "workers of --scheduler are the scheduler's")
    expand_paths(args.paths)  # the input and the output checked before any cluster starts
    _check_out_folder(Path(args.out))
    with contextlib.ExitStack() as stack:
        if scheduler == LOCAL:  # the local cluster, with --jobs workers if given
            scheduler = stack.enter_context(dask_client(LOCAL, n_workers=args.jobs))
        db = MotionDB.ingest(args.paths, args.out, fps=args.fps, labels=args.labels, mapping=mapping,
                             skip_bad=args.skip_bad, threads=args.jobs, progress=not args.quiet,
                             scheduler=scheduler, **options)
    print(db)


def _check_out_folder(out: Path) -> None:
    """A NotADirectoryError unless ``out`` is a folder or can become one (no file in the way)."""
    for folder in (out, *out.parents):
        if folder.exists():
            if not folder.is_dir():
                raise NotADirectoryError(f"--out {out}: {folder} is a file, not a folder")
            return


def _info(args) -> None:
    db = MotionDB.open(args.db)
    print(db)
    with pd.option_context("display.max_rows", 200, "display.width", 160):
        print(db.summary().round(2).to_string())
        if args.documents:
            cols = [c for c in db.documents.columns if c not in ("path", "sha256")]
            print(db.documents[cols].to_string(index=False))


def _index(args) -> None:
    from .experiments import index_statistics

    db = MotionDB.open(args.db)
    t0 = time.perf_counter()
    values, _ = relational_features(db, args.relational_set, progress=not args.quiet, scheduler=_scheduler(args))
    t_features = time.perf_counter() - t0
    build(db, args.relational_set, values=values)
    stats = index_statistics(db, args.relational_set, values=values, t_features=t_features)
    print(f"{db}: {args.relational_set} relational indexes written to {Path(db.path) / 'index'}")
    print(stats.drop(columns=["t_read", "t_total"]).round(3).to_string(index=False))


def _frames(text: str | None) -> slice:
    if not text:
        return slice(None)
    try:
        a, b = (int(x) if x else None for x in text.split(":"))
    except ValueError:
        raise ParameterError(f"--frames must look like A:B (frame numbers), got {text!r}") from None
    return slice(a, b)


def _integers(text: str, option: str) -> list[int]:
    """Comma-separated integers, or a ParameterError naming the option."""
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ParameterError(f"{option} must be comma-separated integers, got {text!r}") from None


def _query(args) -> None:
    db = MotionDB.open(args.db)
    if args.example.isdigit():
        example = db.motion(int(args.example))
    else:
        example = load(args.example)
    sl = _frames(args.frames)
    example = example[sl]
    if example.n_frames < 2:
        raise ParameterError(f"--frames {args.frames} selects {example.n_frames} frame(s) of {example.source}; need at least 2")
    features = None if args.features is None else [f.strip() for f in args.features.split(",") if f.strip()]
    mode = "mismatch" if args.mismatch else args.mode
    t0 = time.perf_counter()
    allowed = None if args.mismatch_at is None else _integers(args.mismatch_at, "--mismatch-at")
    hits = query_by_example(db, example, features, mode=mode, mismatches=args.mismatch or 0,
                            relational_set=args.relational_set, allowed=allowed)
    ms = 1000 * (time.perf_counter() - t0)
    print(f"{len(hits)} hits in {ms:.1f} ms ({mode}, features: {', '.join(features or ['all'])})")
    cols = [c for c in ("rank", "doc_id", "name", "start_frame", "end_frame", "score", "label") if c in hits]
    with pd.option_context("display.width", 160, "display.max_rows", args.n_matches + 5):
        print(hits[cols].head(args.n_matches).round(3).to_string(index=False))


def _names(text: str | None, known, what: str) -> list[str] | None:
    """Comma-separated names, each checked against ``known``."""
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in known]
    if unknown or not names:
        raise ParameterError(f"unknown {what} {', '.join(unknown) or repr(text)}; choose from {', '.join(known)}")
    return names


def _features(args) -> None:
    db = MotionDB.open(args.db)
    names = _names(args.numeric_sets, NUMERIC_SETS, "numeric set")
    ref = Path(args.pca) if args.pca else None
    reference_db = MotionDB.open(ref) if ref is not None and ref.is_dir() else None
    t0 = time.perf_counter()
    with optional_client(_scheduler(args)) as client:  # one cluster for the PCA fit and every set
        pca = None
        if reference_db is not None:
            pca = fit_pca(reference_db, progress=not args.quiet, scheduler=client)
        elif ref is not None:
            pca = PCAModel.load(ref)
        stored = store_numeric(db, names, pca=pca, progress=not args.quiet, scheduler=client)
    print(f"{db}: {len(stored)} numeric feature sets in {time.perf_counter() - t0:.1f} s, "
          f"written to {Path(db.path) / 'features'}")
    rows = [{"set": n, "dims": a.shape[1], "MB": a.nbytes / 2**20} for n, a in stored.items()]
    print(pd.DataFrame(rows).round(1).to_string(index=False))


def _doc_frame(text: str) -> tuple[int, int]:
    try:
        doc, frame = (int(x) for x in text.split(":"))
    except ValueError:
        raise ParameterError(f"--frame must look like DOC:FRAME (document id and frame within it), got {text!r}") from None
    return doc, frame


def _knn(args) -> None:
    db = MotionDB.open(args.db)
    doc, frame = _doc_frame(args.frame)
    span = db.frames(doc)
    if not 0 <= frame < span.stop - span.start:
        raise ParameterError(f"document {doc} has frames 0..{span.stop - span.start - 1}; --frame asks for {frame}")
    features = numeric_of(db, _names(args.numeric_set, NUMERIC_SETS, "numeric set")[0], progress=not args.quiet)
    index = KnnIndex(features)
    own = (span.start, span.stop) if args.exclude_document else None
    t0 = time.perf_counter()
    dist, idx = index.query(features[span.start + frame], args.k, radius=args.radius, eps=args.eps, exclude=own)
    ms = 1000 * (time.perf_counter() - t0)
    hits = describe_frames(db, idx, dist)
    print(f"{len(hits)} neighbours of document {doc} frame {frame} by {args.numeric_set} in {ms:.2f} ms "
          f"({index})")
    cols = [c for c in ("rank", "doc_id", "name", "doc_frame", "time_s", "distance", "label") if c in hits]
    with pd.option_context("display.width", 160, "display.max_rows", args.k + 5):
        print(hits[cols].round(3).to_string(index=False))


def _example_features(db: MotionDB, example: str, frames: str | None, name: str, X) -> tuple[object, tuple | None]:
    """The query's features: frames of a document of the DB (taken from the stored set) or of a motion file
    (resampled to the DB's rate), and the [start, stop) database frames of its document (None for a file)."""
    sl = _frames(frames)
    if example.isdigit():
        span = db.frames(int(example))
        rows = range(span.start, span.stop)[sl]
        return np.asarray(X[rows.start : rows.stop]), (span.start, span.stop)
    motion = load(example)
    if db.typical_fps and abs(motion.fps - db.typical_fps) > 1e-6:
        motion = motion.resample(db.typical_fps)
    pca = default_pca(db) if name.startswith("Fp") else None  # the model the database's features were computed with
    return numeric_features(motion[sl], name, pca=pca, progress=False), None


def _match(args) -> None:
    count(args.n_matches, "-K")  # matches to report
    db = MotionDB.open(args.db)
    name = _names(args.numeric_set, NUMERIC_SETS, "numeric set")[0]
    X = load_numeric(db, name)  # a clear error naming `mocapviz features DB` when the set is not stored
    query, own = _example_features(db, args.example, args.frames, name, X)
    starts = db.documents["start"].to_numpy()
    t0 = time.perf_counter()
    if args.method == "dtw":
        n = args.n_matches
        found = subsequence_dtw(query, X, starts, n_matches=n + (n if own else 0), paths=args.paths)
        if own:
            found = found[(found["end"] < own[0]) | (found["start"] >= own[1])].head(n)
        what = "subsequence DTW"
    else:
        found = lng(query, KnnIndex(X), k=args.k, radius=args.radius, n_matches=args.n_matches, starts=starts,
                    eps=args.eps, exclude=own, paths=args.paths)  # fmt: skip
        what = f"lazy neighbourhood graph, k={args.k}" + (f", r={args.radius:g}" if args.radius else "")
    ms = 1000 * (time.perf_counter() - t0)
    print(f"{len(found)} matches of a {len(query)}-frame query by {name} ({what}) in {ms:.1f} ms"
          + (" (the query's own document excluded)" if own else ""))  # fmt: skip
    docs = db.documents.set_index("doc_id")
    table = pd.DataFrame({
        "rank": np.arange(1, len(found) + 1), "doc_id": found["doc_id"].to_numpy(),
        "name": docs["name"].reindex(found["doc_id"]).to_numpy(),
        "start_frame": (found["start"] - docs["start"].reindex(found["doc_id"]).to_numpy()).to_numpy(),
        "end_frame": (found["end"] - docs["start"].reindex(found["doc_id"]).to_numpy()).to_numpy(),
        "cost": found["cost"].to_numpy(), "cost_per_frame": (found["cost"] / len(query)).to_numpy(),
    })  # fmt: skip
    for col in db.label_columns:
        table[col] = docs[col].reindex(found["doc_id"]).to_numpy()
    _print_ranked(table, args.n_matches, "the lazy neighbourhood graph needs a neighbour of every query frame along a whole "
                  "path: try a larger -k such as 1024, --method dtw, or `mocapviz search DB --stretches`"
                  if args.method == "lng" else "no document long enough outside the query's own")  # fmt: skip
    if args.paths:
        for rank, doc, path in zip(table["rank"], table["doc_id"], found["path"]):
            first = int(docs.loc[doc, "start"])
            print(f"path {rank} (query frame:frame of document {doc}): " + " ".join(f"{i}:{j - first}" for i, j in path))


def _print_ranked(table: pd.DataFrame, n_rows: int, empty: str) -> None:
    """A ranked result table without its path column, or one line saying there is none and what to try."""
    if table.empty:
        print(f"no matches ({empty})")
        return
    with pd.option_context("display.width", 160, "display.max_rows", n_rows + 5):
        shown = table.drop(columns=["path"], errors="ignore").dropna(axis=1, how="all")  # label columns of others
        print(shown.round(3).to_string(index=False))


def _search(args) -> None:
    from .search import SimilaritySearch
    from .store import atomic_write

    count(args.n_matches, "-K")  # matches to report
    if not 0 < args.min_length <= 1:
        raise ParameterError(f"--min-length must be a share of the query's frames in (0, 1]; got {args.min_length}")
    db = MotionDB.open(args.db)
    example = int(args.example) if args.example.isdigit() else args.example
    if isinstance(example, str) and not Path(example).is_file():
        raise ParameterError(f"--example {example!r} is neither a document id of {args.db} nor a motion file")
    search = SimilaritySearch(db, _names(args.numeric_set, NUMERIC_SETS, "numeric set")[0])
    options = {"n_matches": args.n_matches, "mode": args.mode, "exclude_document": args.exclude_document, "paths": args.paths}
    if args.stretches:
        table = search.stretches(example, frames=_frames(args.frames), min_length=args.min_length, **options)
    else:
        table = search.clips(example, frames=_frames(args.frames), **options)
    what = "stretches" if args.stretches else "clips"
    print(f"{len(table)} {what} like {args.example} ({table.attrs['query_frames']} frames) by DTW on {search.numeric_set}"
          f", {args.mode} mode, in {table.attrs['ms']:.1f} ms" + (" (its own document excluded)" if
                                                                 args.exclude_document else ""))  # fmt: skip
    _print_ranked(table, args.n_matches, "the query's own document is the only one long enough; try whole clips, a shorter "
                  "--frames span or a smaller --min-length" if args.stretches else "no other document to compare")
    if args.paths:
        for rank, doc, path in zip(table["rank"], table["doc_id"], table["path"]):
            if path is not None:
                print(f"path {rank} (query frame:frame of document {doc}): " + " ".join(f"{i}:{j}" for i, j in path))
    if args.csv:
        atomic_write(args.csv, table.drop(columns=["path"], errors="ignore").to_csv(index=False).encode())
        print(f"ranked table written to {args.csv}")


def _reproduce(args) -> None:
    from .reproduction import reproduce

    reproduce(args.names, args.out, full=args.full, progress=not args.quiet)


def _datasets(args) -> None:
    if args.action == "list":
        for row in datasets.info().itertuples(index=False):
            where = "embedded in the package, no download" if row.embedded else "shared archive"
            state = "unpacked in the cache" if row.cached else "not unpacked yet"
            print(f"{row.name}: {row.description}")
            print(f"    {row.files}; {row.frames:,} frames at {row.fps} Hz; {row.size / 1e6:.1f} MB .tar.xz; "
                  f"{where}; {state}")
            print(f"    licence: {row.licence}")
            print(f"    source: {row.source}")
        try:
            located = f"shared archives from {datasets.data_url()}"
        except datasets.DatasetError:
            located = (f"shared archives not found: set {datasets.DATA_URL_ENV} to a folder or URL holding them "
                       "(a source checkout also finds ../shared/data)")
        print(f"{located}; cache {datasets.cache_dir()} ({datasets.HOME_ENV})")
    else:
        if not args.name:
            raise ParameterError(f"datasets fetch needs a NAME: {', '.join(datasets.names())} or {datasets.SAMPLE}")
        print(datasets.fetch(args.name, progress=True))


def _cluster_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scheduler", metavar="ADDRESS", help="run the tasks on this dask.distributed scheduler "
                   "(e.g. tcp://host:8786; its workers must see the same paths); default: a local cluster, one "
                   "worker process per core")  # fmt: skip
    p.add_argument("--no-cluster", action="store_true", help="no Dask: work in this process (threads)")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="mocapviz", description="Content-based retrieval in motion-capture databases.")
    sub = p.add_subparsers(dest="command", required=True)

    ing = sub.add_parser("ingest", help="read ASF/AMC and BVH files into a MotionDB (creates or appends)")
    ing.add_argument("paths", nargs="+", help="files, folders (searched recursively) or glob patterns")
    ing.add_argument("--out", required=True, help="MotionDB directory")
    ing.add_argument("--fps", type=float, help="resample every clip to this frame rate")
    ing.add_argument("--labels", help="label table (TSV/CSV with a 'file' column); default: tables beside the data")
    ing.add_argument("--mapping", help="JSON file {canonical joint: joint name} for rigs the rules cannot map")
    ing.add_argument("--asf", help="ASF skeleton for all AMC files (default: found beside each)")
    ing.add_argument("--up", choices=["auto", "y", "z"], help="up axis of BVH files (default auto)")
    ing.add_argument("--skip-bad", action="store_true", help="skip unreadable files with a warning")
    _cluster_options(ing)
    ing.add_argument("--jobs", type=int, help="worker processes of the local cluster (default: one per core), or "
                     "with --no-cluster reader threads (default: the cores, at most 8)")
    ing.add_argument("--quiet", action="store_true", help="no progress bar")
    ing.set_defaults(func=_ingest)

    info = sub.add_parser("info", help="summarise a MotionDB")
    info.add_argument("db")
    info.add_argument("--documents", action="store_true", help="also list every document")
    info.set_defaults(func=_info)

    idx = sub.add_parser("index", help="compute relational features and build the inverted indexes of a MotionDB")
    idx.add_argument("db")
    idx.add_argument("--relational-set", "--feature-set", dest="relational_set", default="2005",
                     choices=["2005", "2006"], help="relational set (default 2005; --feature-set: its old name)")
    _cluster_options(idx)
    idx.add_argument("--quiet", action="store_true", help="no progress bar")
    idx.set_defaults(func=_index)

    q = sub.add_parser("query", help="query by example: ranked hits of a clip's progression of chosen features")
    q.add_argument("db")
    q.add_argument("--example", required=True, help="a motion file, or a document id of the DB")
    q.add_argument("--frames", help="frame span A:B of the example (default: all of it)")
    q.add_argument("--features", help="comma-separated relational feature names (default: all of the set)")
    q.add_argument("--mode", default="adaptive", choices=["adaptive", "fuzzy", "exact"],
                   help="adaptive fuzzy (default), plain fuzzy or exact hits")
    q.add_argument("--mismatch", type=int, default=0, help="allow M segments of the query (segmented on the chosen "
                   "features) to disagree")
    q.add_argument("--mismatch-at", help="comma-separated 0-based query segments that may disagree (default any)")
    q.add_argument("--relational-set", "--feature-set", dest="relational_set", default="2005",
                   choices=["2005", "2006"], help="relational set (default 2005; --feature-set: its old name)")
    q.add_argument("-K", "--matches", "--top", dest="n_matches", type=int, default=20,
                   help="hits to print (default 20; --top: its old name)")
    q.set_defaults(func=_query)

    feat = sub.add_parser("features", help="compute and store the numeric feature sets of a MotionDB (kNN search)")
    feat.add_argument("db")
    feat.add_argument("--numeric-sets", "--sets", dest="numeric_sets", help=f"comma-separated numeric sets (default "
                      f"all: {','.join(NUMERIC_SETS)}; --sets: its old name)")  # fmt: skip
    feat.add_argument("--pca", help="PCA reference for Fp8/16/25: a saved model (.npz) or a MotionDB to fit it on "
                                    "(default: fitted on DB itself)")
    _cluster_options(feat)
    feat.add_argument("--quiet", action="store_true", help="no progress bar")
    feat.set_defaults(func=_features)

    kn = sub.add_parser("knn", help="the k nearest frames of one frame of a MotionDB (kd-tree)")
    kn.add_argument("db")
    kn.add_argument("--frame", required=True, help="DOC:FRAME, a document id and a frame within it")
    kn.add_argument("--numeric-set", "--features", dest="numeric_set", default="F15E",
                    help="numeric set (default F15E; --features: its old name)")
    kn.add_argument("-k", type=int, default=16, help="neighbours (default 16)")
    kn.add_argument("--radius", type=float, help="only neighbours closer than this (feature units, cm)")
    kn.add_argument("--eps", type=float, default=0.0, help="approximate search: k-th distance within (1+eps)")
    kn.add_argument("--exclude-document", action="store_true", help="leave out the frame's own document")
    kn.add_argument("--quiet", action="store_true", help="no progress bar")
    kn.set_defaults(func=_knn)

    mt = sub.add_parser("match", help="stretches of the DB that move like an example, ranked (lazy neighbourhood "
                        "graph or subsequence DTW)")  # fmt: skip
    mt.add_argument("db")
    mt.add_argument("--example", required=True, help="a motion file, or a document id of the DB (then its own "
                    "document is excluded from the matches)")  # fmt: skip
    mt.add_argument("--frames", help="frame span A:B of the example (default: all of it)")
    mt.add_argument("--numeric-set", "--features", dest="numeric_set", default="F15E", help="stored numeric set "
                    "(default F15E; see `mocapviz features`; --features: its old name)")  # fmt: skip
    mt.add_argument("-K", "--matches", dest="n_matches", type=int, default=10, help="matches to report (default 10)")
    mt.add_argument("-k", type=int, default=256, help="neighbours per query frame (default 256)")
    mt.add_argument("--radius", type=float, help="only neighbours closer than this (feature units)")
    mt.add_argument("--eps", type=float, default=0.0, help="approximate kNN: k-th distance within (1+eps)")
    mt.add_argument("--method", choices=["lng", "dtw"], default="lng", help="lng (default) or subsequence DTW")
    mt.add_argument("--paths", action="store_true", help="also print each match's alignment (query frame:document "
                    "frame pairs)")  # fmt: skip
    mt.set_defaults(func=_match)

    se = sub.add_parser("search", help="the clips (or stretches of long takes) of the DB that move most like an "
                        "example, ranked by DTW on a numeric feature set (exact or fast)")  # fmt: skip
    se.add_argument("db")
    se.add_argument("--example", required=True, help="a motion file, or a document id of the DB")
    se.add_argument("--frames", help="frame span A:B of the example (default: all of it)")
    se.add_argument("--numeric-set", "--features", dest="numeric_set", default="F15E",
                    help="numeric set (default F15E; --features: its old name)")
    se.add_argument("-K", "--matches", dest="n_matches", type=int, default=10, help="matches to report (default 10)")
    se.add_argument("--mode", choices=["fast", "exact", "brute"], default="fast", help="fast (default): aligns only "
                    "where kNN and a coarse pass point; exact: brute force's answer, pruned by lower bounds; brute: "
                    "every cell")  # fmt: skip
    se.add_argument("--stretches", action="store_true", help="the K best non-overlapping stretches inside documents "
                    "(subsequence DTW) instead of whole clips")  # fmt: skip
    se.add_argument("--min-length", type=float, default=0.5, help="with --stretches: the shortest match as a share "
                    "of the query's frames (default 0.5)")  # fmt: skip
    se.add_argument("--exclude-document", action="store_true", help="leave out the example's own document")
    se.add_argument("--csv", help="also write the ranked table (best first) to this CSV file")
    se.add_argument("--paths", action="store_true", help="also print each match's alignment (query frame:document "
                    "frame pairs)")  # fmt: skip
    se.set_defaults(func=_search)

    rp = sub.add_parser("reproduce", help="re-run the papers' experiments on the shared data; write CSV tables and "
                        "PNG/HTML figures")  # fmt: skip
    rp.add_argument("names", nargs="+", metavar="NAME", help="experiment function name(s) (index_statistics, "
                    "query_statistics, relational_query, alignment, knn_timings, rank_correlations, "
                    "similarity_matrices, lng_accuracy, numerical_search, reconstruction, base_poses, retrieval_quality) or "
                    "'all'")
    rp.add_argument("--out", required=True, help="output folder; each experiment writes OUT/NAME/")
    rp.add_argument("--full", action="store_true", help="the papers' sizes (slow; every shared archive as the "
                    "large database)")  # fmt: skip
    rp.add_argument("--quiet", action="store_true", help="no progress bars")
    rp.set_defaults(func=_reproduce)

    sv = sub.add_parser("serve", help="the dashboard in the browser: browse, query by example, kNN, matching, "
                        "correlations, index statistics, reconstruction")
    sv.add_argument("db", nargs="?", help="MotionDB folder (default: the embedded sample, ingested once)")
    sv.add_argument("--port", type=int, default=5006)
    sv.add_argument("--address", default="127.0.0.1",
                    help="interface to listen on (default 127.0.0.1: this machine only; anything else exposes the "
                    "database to the network and prints a warning)")
    sv.add_argument("--show", action="store_true", help="open the dashboard in a web browser")
    sv.set_defaults(func=_serve)

    ds = sub.add_parser("datasets", help="list the registered motion-capture datasets (the shared archives and the "
                        "embedded sample) with sizes, licences and sources, or fetch one")
    ds.add_argument("action", choices=["list", "fetch"])
    ds.add_argument("name", nargs="?", help="for fetch: a shared archive (see list) or 'sample' (embedded)")
    ds.set_defaults(func=_datasets)
    return p


def _serve(args) -> None:
    from .app import serve
    from .app.backend import sample_database

    db = args.db if args.db else sample_database()
    if not 0 < args.port < 65536:
        raise ParameterError(f"--port must be 1..65535, got {args.port}")
    print(f"mocapviz: serving {db} on http://{args.address}:{args.port}/ (Ctrl-C stops)", flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        serve(db, port=args.port, address=args.address, show=args.show)


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"mocapviz: warning: {message}", file=sys.stderr)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            args.func(args)
    except (MocapvizError, OSError) as exc:  # bad input; anything else is a bug and shows its traceback
        print(f"mocapviz: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
