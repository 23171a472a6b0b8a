"""The ``mocapviz`` command.

    mocapviz ingest PATH... --out DB [--fps N] [--labels FILE] [--skip-bad] [--scheduler ADDRESS | [--no-cluster] [--jobs N]]
    mocapviz info DB [--documents]
    mocapviz index DB [--relational-set 2005|2006] [--scheduler ADDRESS | --no-cluster]
    mocapviz query DB --example FILE|DOC_ID [--frames A:B] --features NAMES [--mode M] [--mismatch M [--mismatch-at I,J]]
                      [--relational-set 2005|2006] [-K 20] [--csv FILE]
    mocapviz features DB [--numeric-sets F15E,F30E,...] [--pca FILE|DB] [--scheduler ADDRESS | --no-cluster]
    mocapviz knn DB --frame DOC:FRAME [--numeric-set F15E] [-k 16] [--radius R] [--eps E] [--exclude-document]
                    [--per-document] [--csv FILE]
    mocapviz match DB --example FILE|DOC_ID [--frames A:B] [--numeric-set F15E] [-K 10] [-k 256] [--radius R] [--eps E]
                      [--method lng|dtw] [--min-length 0.5] [--paths] [--csv FILE]
    mocapviz search DB --example FILE|DOC_ID [--frames A:B] [--numeric-set F15E] [-K 10] [--mode fast|exact|brute]
                       [--stretches [--min-length 0.5]] [--exclude-document] [--csv FILE] [--paths]
    mocapviz find DB "DESCRIPTION" | --file FILE [--template-file NAME=FILE]... [-K 100] [--explain] [--csv FILE]
    mocapviz template learn DB --label CLASS [--actors A,B,...] [--relational-set 2005|2006] [--out FILE]
    mocapviz template search DB FILE_OR_NAME [-K 10] [--max-cost C] [--csv FILE] [--prefilter]
    mocapviz export DB (--hits HITS.csv | --doc ID [--frames A:B]) --format bvh|amc|glb [--rig source|canonical]
                       --out DIR [--search TEXT]
    mocapviz reproduce NAME|all [--full] --out DIR   (NAME: an experiment, e.g. rank_correlations, reconstruction)
    mocapviz serve [DB] [--port 5006] [--address 127.0.0.1 | --address ADDRESS --allow-origin HOST:PORT...] [--show]
                                                                                (no DB: the embedded sample)
    mocapviz datasets list
    mocapviz datasets fetch NAME        (NAME: a shared archive, or ``sample`` for the embedded sample)

``ingest``, ``features`` and ``index`` run their work as Dask tasks: on the scheduler at ``--scheduler ADDRESS``
(``tcp://host:8786``), else on a local cluster started for the command (one single-threaded worker process per
core, or ``ingest --jobs N`` workers; :mod:`mocapviz.parallel`). ``--no-cluster`` runs in this process instead, on
threads (for ``ingest``, ``--jobs N`` of them), as the library functions do by default.

Options follow docs/glossary.md: ``-K`` / ``--matches`` is how many results (hits, clips, stretches) to report,
``-k`` how many neighbours per query frame, ``--relational-set`` / ``--numeric-set(s)`` which features. The older
spellings still work: ``--top`` (query, for ``-K``), ``--feature-set`` (for ``--relational-set``), ``--features``
(knn, match, search: for ``--numeric-set``) and ``--sets`` (features: for ``--numeric-sets``).

Every command that prints hits (``query``, ``knn``, ``match``, ``search``, ``template search``) prints and, with
``--csv FILE``, writes the one hit table of :func:`mocapviz.db.hits.hit_table`: ``start`` and ``end`` within the
document, half-open, ``start_s`` and ``end_s`` at the document's own rate.

``export`` writes what a search found (``--hits``: the CSV of ``--csv FILE``) or one stretch of a document as files,
one per hit, named ``<rank>_doc<id>_<name>_<start>-<end>.<format>``, all or nothing (a failure or SIGTERM leaves
the output folder as it was; :mod:`mocapviz.export`, docs/export.md).

Errors print one line (``mocapviz: error: ...``): a value the argument parser refuses (not a number, out of its
range, an unknown name, a list where one value is allowed) exits with status 2, one the command refuses (checked
against the database or the clip: frames of a document, the query's segments, k neighbours) with status 1. No
value is clamped or ignored: what runs is what the command line says.
"""
from __future__ import annotations

import argparse
import contextlib
import functools
import json
import re
import sys
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

# Only what the parser needs is imported here (``mocapviz --help`` loads neither pandas nor numba); each command
# imports its modules in its handler (tests/test_startup.py, benchmarks/bench_startup.py).
from .errors import MocapvizError, ParameterError
from .features import NUMERIC_SETS
from .motion import FPS_RANGE
from .parallel import LOCAL, dask_client, optional_client  # light: dask itself is imported by dask_client
from .validation import (
    frame_span,
    parse_count,
    parse_integers,
    parse_names,
    parse_number,
    parse_port,
    parse_span,
)

if TYPE_CHECKING:
    import pandas as pd

    from .db.database import MotionDB
    from .features import PCAModel

MAX_JOBS = 256
"""``ingest --jobs``: worker processes or reader threads at most."""
PCA_SETS = tuple(n for n in NUMERIC_SETS if n.startswith("Fp"))


def _scheduler(args):
    """The ``scheduler=`` of the ingest / features / index commands: None (--no-cluster), an address, or local."""
    if args.no_cluster:
        if args.scheduler:
            raise ParameterError("--scheduler and --no-cluster exclude each other")
        return None
    return args.scheduler or LOCAL


def _mapping(path: str) -> dict[str, str]:
    """``--mapping FILE``: a JSON object {canonical joint: joint name}, its keys checked against the canonical joints
    (the joint names are the skeleton's, checked per file)."""
    from .motion.skeleton import CANONICAL_JOINTS

    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(f"--mapping {path}: cannot read it ({getattr(exc, 'strerror', None) or exc})") from None
    try:
        mapping = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParameterError(f"--mapping {path}: not JSON ({exc})") from None
    if not isinstance(mapping, dict) or not all(isinstance(v, str) for v in mapping.values()):
        raise ParameterError(f"--mapping {path}: must be a JSON object {{canonical joint: joint name}}, e.g. "
                             f'{{"lknee": "LeftLeg"}}; got {type(mapping).__name__}')  # fmt: skip
    unknown = [k for k in mapping if k not in CANONICAL_JOINTS]
    if unknown:
        raise ParameterError(f"--mapping {path}: unknown canonical joint(s) {', '.join(unknown)}; choose from "
                             f"{', '.join(CANONICAL_JOINTS)}")
    return mapping


def _ingest(args) -> None:
    from .db.database import MotionDB
    from .db.ingest import expand_paths
    from .io import read_asf

    mapping = _mapping(args.mapping) if args.mapping else None
    if args.labels and not Path(args.labels).is_file():
        raise ParameterError(f"--labels {args.labels}: no such file (a TSV/CSV label table with a 'file' column)")
    if args.asf:  # read once here: a bad skeleton is one error, not every AMC file failing (or skipped) with it
        try:
            read_asf(args.asf)
        except (MocapvizError, OSError) as exc:
            raise ParameterError(f"--asf: {exc}") from None
    options = {k: v for k, v in (("asf", args.asf), ("up", args.up)) if v is not None}
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
    import pandas as pd

    from .db.database import MotionDB

    db = MotionDB.open(args.db)
    print(db)
    with pd.option_context("display.max_rows", 200, "display.width", 160):
        print(db.summary().round(2).to_string())
        if args.documents:
            cols = [c for c in db.documents.columns if c not in ("path", "sha256")]
            print(_printed(db.documents[cols]))


def _check(args) -> int:
    """Print the report of ``mocapviz.integrity.check``; exit status 1 when a file is damaged, 3 when derived data
    is only stale (with the commands that compute it again), else 0."""
    import pandas as pd

    from .errors import MotionDBError
    from .integrity import check, rebuild_commands

    report = check(args.db)
    shown = report.assign(status=report["status"].replace({"damaged": "DAMAGED"}))[["file", "what", "status", "detail"]]
    with pd.option_context("display.max_rows", 500, "display.width", 200, "display.max_colwidth", 160):
        print(shown.to_string(index=False))
    damaged, stale = (int((report["status"] == s).sum()) for s in ("damaged", "stale"))
    rebuild = "".join(f"\n  {command}" for command in rebuild_commands(report))
    also = f"; {stale} stale" if stale else ""
    if damaged:
        raise MotionDBError(f"{args.db}: {damaged} of {len(report)} files are damaged{also} (see above)" +
                            (f"; derived data is computed again by:{rebuild}" if rebuild else ""))  # fmt: skip
    if stale:
        print(f"mocapviz: {args.db}: {stale} of {len(report)} files are stale derived data (intact, computed before "
              f"the database last changed; nothing is damaged); compute them again with:{rebuild}", file=sys.stderr)
        return 3
    return 0


def _index(args) -> None:
    from .db.database import MotionDB
    from .experiments import index_statistics
    from .features import relational_features
    from .relational.index import build

    db = MotionDB.open(args.db)
    t0 = time.perf_counter()
    values, _ = relational_features(db, args.relational_set, progress=not args.quiet, scheduler=_scheduler(args))
    t_features = time.perf_counter() - t0
    build(db, args.relational_set, values=values)
    stats = index_statistics(db, args.relational_set, values=values, t_features=t_features)
    print(f"{db}: {args.relational_set} relational indexes written to {Path(db.path) / 'index'}")
    print(stats.drop(columns=["t_read", "t_total"]).round(3).to_string(index=False))


def _example(db: MotionDB, text: str) -> int | Path:
    """``--example``: a document id of ``db`` (digits; :meth:`MotionDB.document` refuses one it does not hold) or
    a motion file."""
    if text.isdigit():
        try:
            return int(db.document(int(text))["doc_id"])
        except ParameterError as exc:
            raise ParameterError(f"--example {text}: {exc}") from None
    if Path(text).is_file():
        return Path(text)
    ids = db.documents["doc_id"]
    raise ParameterError(f"--example {text} is neither a document id of {db.path} (doc ids {ids.min()}..{ids.max()}) "
                         "nor a motion file")


def _printed(table: pd.DataFrame) -> str:
    """A table as the commands print it, without its index: a missing cell (the label columns of an unlabelled
    document, a take number another archive has none of) blank, never NaN or <NA>."""
    import pandas as pd

    blank = {c: table[c].astype(object).where(table[c].notna(), "") for c in table.columns
             if pd.api.types.is_integer_dtype(table[c]) and table[c].hasnans}  # to_string's na_rep skips Int64
    return table.assign(**blank).to_string(index=False, na_rep="")


def _write_csv(table: pd.DataFrame, path: str | None) -> None:
    """``--csv FILE``: the ranked hit table, as printed but whole and without warping paths (atomically)."""
    if path:
        from .store import atomic_write

        atomic_write(path, table.drop(columns=["path"], errors="ignore").to_csv(index=False).encode())
        print(f"ranked table written to {path}")


def _csv_folder(path: str | None) -> None:
    """``--csv FILE`` checked before any work: its folder must exist."""
    if path and not Path(path).parent.is_dir():
        raise ParameterError(f"--csv {path}: no folder {Path(path).parent} to write it in")


def _query_segments(example, features: list[str], relational_set: str) -> int:
    """The segments of the example on the chosen features, fewest over the feature groups they touch: the L of an
    m-mismatch query (query_by_example segments each group's chosen features separately, m < L in each)."""
    from .features import feature_groups, relational_features
    from .features.segmentation import segment

    values, names = relational_features(example, relational_set)
    counts = [len(segment(values[:, [names.index(f) for f in features if f in members]]).codes)
              for members in feature_groups(relational_set).values() if any(f in members for f in features)]
    return min(counts)


def _query(args) -> None:
    import pandas as pd

    from .features import feature_names

    _csv_folder(args.csv)
    engine = _engine(args)
    example = _example(engine.db, args.example)
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
    if args.mismatches and all(f in known for f in features or known):  # unknown names: the engine says which
        n = _query_segments(motion, features or list(known), args.relational_set)
        if args.mismatches > n - 1:
            raise ParameterError(f"--mismatch must be between 0 and {n - 1}, one less than the query's {n} "
                                 f"segment(s) on the chosen features; got {args.mismatches}")
        outside = sorted({i for i in args.allowed or () if i >= n})
        if outside:
            raise ParameterError(f"--mismatch-at lists query segments from 0 to {n - 1} (the query has {n} on the "
                                 f"chosen features); got {', '.join(map(str, outside))}")
    mode = "mismatch" if args.mismatches else args.query_mode
    t0 = time.perf_counter()
    with engine:
        hits = engine.query(motion, features=features, mode=mode, mismatches=args.mismatches or ...,
                            relational_set=args.relational_set, allowed=args.allowed)  # fmt: skip
    ms = 1000 * (time.perf_counter() - t0)
    print(f"{len(hits)} hits in {ms:.1f} ms ({mode}, features: {', '.join(features or ['all'])})")
    cols = [c for c in ("rank", "doc_id", "name", "start", "end", "start_s", "end_s", "score", "label") if c in hits]
    with pd.option_context("display.width", 160, "display.max_rows", args.rows + 5):
        print(_printed(hits[cols].head(args.rows).round(3)))
    _write_csv(hits.head(args.rows), args.csv)

def _find(args) -> None:
    import pandas as pd

    from .relational.description import named_descriptions

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
    _csv_folder(args.csv)
    given = _template_files(args.template_files)
    with _engine(args) as engine:
        hits = engine.find(text, n_matches=args.n_matches, relational_set=args.relational_set,
                           template_cost=args.template_cost, templates=given or None)  # fmt: skip
    if args.explain:
        print(hits.attrs["description"])
        print("matched: " + "; ".join(f"{label}: {n}" for label, n in hits.attrs["counts"]))
    print(f"{len(hits)} hits in {hits.attrs['ms']:.1f} ms ({hits.attrs['candidates']} before overlaps were "
          f"resolved; {hits.attrs['relational_set']} set)")  # fmt: skip
    if hits.empty:
        print(hits.attrs["empty_reason"])
        _write_csv(hits, args.csv)
        return
    cols = [c for c in ("rank", "doc_id", "name", "start", "end", "start_s", "end_s", "score", "label") if c in hits]
    cols += ["parts"] if args.explain else []
    with pd.option_context("display.width", 200, "display.max_rows", len(hits) + 5, "display.max_colwidth", 120):
        print(_printed(hits[cols].round(3)))
    _write_csv(hits, args.csv)


def _template_files(items: list[str] | None) -> dict:
    """``find --template-file NAME=FILE`` (repeatable): name -> the MotionTemplate of FILE, for the description's
    ``template:NAME`` atoms. Only a file named here, on the command line, is ever opened; the description's text
    names stored templates only."""
    from .errors import MotionDBError
    from .relational.templates import MotionTemplate, is_template_name

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


def _pca_reference(text: str | None, names: list[str] | None) -> MotionDB | PCAModel | None:
    """``--pca``: a MotionDB to fit the PCA model on, or a saved model; refused when no Fp set is asked for."""
    from .db.database import MotionDB
    from .features import PCAModel

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


def _features(args) -> None:
    import pandas as pd

    from .db.database import MotionDB
    from .features import fit_pca, store_numeric

    db = MotionDB.open(args.db)
    names = args.numeric_sets
    reference = _pca_reference(args.pca, names)
    t0 = time.perf_counter()
    with optional_client(_scheduler(args)) as client:  # one cluster for the PCA fit and every set
        pca = reference
        if isinstance(reference, MotionDB):
            pca = fit_pca(reference, progress=not args.quiet, scheduler=client)
        stored = store_numeric(db, names, pca=pca, progress=not args.quiet, scheduler=client)
    print(f"{db}: {len(stored)} numeric feature sets in {time.perf_counter() - t0:.1f} s, "
          f"written to {Path(db.path) / 'features'}")
    rows = [{"set": n, "dims": a.shape[1], "MB": a.nbytes / 2**20} for n, a in stored.items()]
    print(pd.DataFrame(rows).round(1).to_string(index=False))


def _doc_frame(text: str, name: str) -> tuple[int, int]:
    """``DOC:FRAME``: a document id and a frame within it, both from 0 (whether they exist: :func:`_knn`)."""
    try:
        doc, frame = (int(x) for x in text.split(":"))
    except ValueError:
        raise ParameterError(f"{name} must look like DOC:FRAME (a document id and a frame within it, both from 0), "
                             f"got {text!r}") from None
    if doc < 0 or frame < 0:
        raise ParameterError(f"{name} takes a document id and a frame from 0 (DOC:FRAME), got {text!r}")
    return doc, frame


def _numeric_set(text: str, name: str) -> str:
    """One numeric set (``--numeric-set``): a list is refused, not cut to its first name."""
    return parse_names(text, name, "numeric set", NUMERIC_SETS, one=True)[0]


def _scheduler_address(text: str, name: str) -> str:
    """``--scheduler``: a dask.distributed scheduler address (or ``local``): not empty, no spaces."""
    if not text.strip() or any(c.isspace() for c in text):
        raise ParameterError(f"{name} needs a scheduler address such as tcp://host:8786 (or 'local'); got {text!r}")
    return text


def _engine(args):
    """The engine of a search command's database: its shards in this process, or on the cluster of
    ``--scheduler local|ADDRESS``."""
    from .engine import Engine

    return Engine(args.db, scheduler=getattr(args, "scheduler", None))

def _knn(args) -> None:
    import pandas as pd

    _csv_folder(args.csv)
    doc, frame = args.frame
    with _engine(args) as engine:
        try:
            engine.db.frames(doc)
        except ParameterError as exc:
            raise ParameterError(f"--frame {doc}:{frame}: {exc}") from None
        span = engine.db.frames(doc)
        n = span.stop - span.start
        if not 0 <= frame < n:
            raise ParameterError(f"--frame {doc}:{frame}: document {doc} has frames 0..{n - 1}")
        hits = engine.neighbours(doc, frame, k=args.k, numeric_set=args.numeric_set, radius=args.radius, eps=args.eps,
                                 exclude_document=args.exclude_document, per_document=args.per_document)  # fmt: skip
        how = repr(engine)
    each = f"; one row per document: the nearest in each of {len(hits)}" if args.per_document else ""
    print(f"{hits.attrs['found']} neighbours of document {doc} frame {frame} by {args.numeric_set} in "
          f"{hits.attrs['ms']:.2f} ms ({how}){each}")  # fmt: skip
    cols = [c for c in ("rank", "doc_id", "name", "start", "start_s", "distance", "label") if c in hits]
    with pd.option_context("display.width", 160, "display.max_rows", args.k + 5):
        print(_printed(hits[cols].round(3)))
    _write_csv(hits, args.csv)

def _match(args) -> None:
    from .features import load_numeric

    if args.method == "dtw":
        given = [o for o, v in (("-k", args.k), ("--radius", args.radius), ("--eps", args.eps)) if v is not None]
        if given:
            raise ParameterError(f"{', '.join(given)} shape the neighbourhood graph of --method lng; subsequence DTW "
                                 "(--method dtw) compares every frame: leave them out")
    _csv_folder(args.csv)
    with _engine(args) as engine:
        load_numeric(engine.db, args.numeric_set)  # a clear error naming `mocapviz features DB` when not stored
        example = _example(engine.db, args.example)
        lng = {} if args.method == "dtw" else {"k": args.k or ..., "radius": args.radius, "eps": args.eps or ...}
        table = engine.match(example, frames=args.frames, numeric_set=args.numeric_set, method=args.method,
                             n_matches=args.n_matches, exclude_document=isinstance(example, int), paths=args.paths,
                             min_length=args.min_length, **lng)  # fmt: skip
    k = table.attrs.get("k", "")
    what = "subsequence DTW" if args.method == "dtw" else f"lazy neighbourhood graph, k={k}" + (
        f", r={args.radius:g}" if args.radius else "")  # fmt: skip
    own = isinstance(example, int)
    print(f"{len(table)} matches of a {table.attrs['query_frames']}-frame query by {args.numeric_set} ({what}), each "
          f"at least {args.min_length:g} × the query long, in {table.attrs['ms']:.1f} ms"
          + (" (the query's own document excluded)" if own else ""))  # fmt: skip
    _print_ranked(table, args.n_matches, "the lazy neighbourhood graph needs a neighbour of every query frame along a "
                  "whole path: try a larger -k such as 1024, --method dtw, or `mocapviz search DB --stretches`"
                  if args.method == "lng" else "no document long enough outside the query's own")  # fmt: skip
    _print_paths(table, args.paths)
    _write_csv(table, args.csv)

def _print_paths(table: pd.DataFrame, paths: bool) -> None:
    """``--paths``: each hit's warping path as query frame:frame of its document."""
    if paths:
        for rank, doc, path in zip(table["rank"], table["doc_id"], table["path"]):
            if path is not None:
                print(f"path {rank} (query frame:frame of document {doc}): " + " ".join(f"{i}:{j}" for i, j in path))


def _print_ranked(table: pd.DataFrame, n_rows: int, empty: str) -> None:
    """A ranked result table without its path column, or one line saying there is none and what to try."""
    if table.empty:
        print(f"no matches ({empty})")
        return
    import pandas as pd

    with pd.option_context("display.width", 160, "display.max_rows", n_rows + 5):
        shown = table.drop(columns=["path"], errors="ignore").dropna(axis=1, how="all")  # label columns of others
        print(_printed(shown.round(3)))


def _search(args) -> None:
    if args.min_length is not None and not args.stretches:
        raise ParameterError("--min-length is the shortest stretch as a share of the query: it needs --stretches")
    _csv_folder(args.csv)
    with _engine(args) as engine:
        example = _example(engine.db, args.example)
        options = {"frames": args.frames, "n_matches": args.n_matches, "numeric_set": args.numeric_set,
                   "mode": args.mode, "exclude_document": args.exclude_document, "paths": args.paths}  # fmt: skip
        if args.stretches:
            table = engine.stretches(example, min_length=... if args.min_length is None else args.min_length, **options)
        else:
            table = engine.clips(example, **options)
    what = "stretches" if args.stretches else "clips"
    print(f"{len(table)} {what} like {args.example} ({table.attrs['query_frames']} frames) by DTW on {args.numeric_set}"
          f", {args.mode} mode, in {table.attrs['ms']:.1f} ms" + (" (its own document excluded)" if
                                                                 args.exclude_document else ""))  # fmt: skip
    _print_ranked(table, args.n_matches, "the query's own document is the only one long enough; try whole clips, a "
                  "shorter --frames span or a smaller --min-length" if args.stretches else "no other document to "
                  "compare")  # fmt: skip
    _print_paths(table, args.paths)
    _write_csv(table, args.csv)

def _template_learn(args) -> None:
    from .engine.parameters import default
    from .relational.templates import DONT_CARE, store_template
    from .validation import one_of, some_of

    if args.out and not Path(args.out).parent.is_dir():
        raise ParameterError(f"--out {args.out}: no folder {Path(args.out).parent} to write it in")
    engine = _engine(args)
    db = engine.db
    docs = db.documents
    try:
        one_of(args.label, "label", sorted(map(str, docs["label"].dropna().unique())))
    except ParameterError as exc:
        raise ParameterError(f"--label: {exc}") from None
    actors = None
    if args.actors is not None:
        if "actor" not in docs.columns:
            raise ParameterError(f"--actors: the documents of {db.path} have no actor column; leave --actors out")
        try:
            actors = some_of(args.actors.split(","), "actor", sorted(map(str, docs["actor"].dropna().unique())))
        except ParameterError as exc:
            raise ParameterError(f"--actors: {exc}") from None
    t0 = time.perf_counter()
    template = engine.learn_template(args.label, actors=actors, relational_set=args.relational_set,
                                     max_examples=args.max_examples)  # fmt: skip
    seconds = time.perf_counter() - t0
    stored = store_template(db, template)
    delta = default("search_template", "delta")
    dont_care = float((template.quantised(delta) == DONT_CARE).mean())
    n = template.n_examples
    print(f"template {template.label!r} of {db.path} ({', '.join(actors) if actors else 'every actor'}): "
          f"{n} example{'s' * (n != 1)}, {len(template.values)} frames x {len(template.features)} features of the "
          f"{args.relational_set} set, {dont_care:.0%} don't care (δ = {delta}), {template.iterations} iterations, "
          f"{seconds:.1f} s")  # fmt: skip
    meta = template.meta
    print(f"its examples' own best matches cost up to {meta['example_threshold']:.3f} per frame; its learned threshold "
          f"is {meta['threshold']:.3f} (`--max-cost {meta['threshold']:.3f}`: the cost that best separates them from "
          f"the {meta['negatives']} clips of other labels, the nearest of which costs "
          + ("-" if meta["nearest_negative"] is None else f"{meta['nearest_negative']:.3f}") + ")")
    print(f"stored in {stored} (search it: `mocapviz template search {db.path} {stored.stem}`)")
    if args.out:
        template.save(args.out)
        print(f"written to {args.out}")


@contextlib.contextmanager
def _terminate_as_exit():
    """In the block, SIGTERM raises SystemExit (status 143, as the signal's default) in the main thread, so that
    cleanup in ``finally`` clauses and context managers runs; the previous handler afterwards."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def leave(signum, frame):
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, leave)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _export(args) -> None:
    from .db.database import MotionDB
    from .export import export_hits, export_stretch

    if args.frames is not None and args.doc is None:
        raise ParameterError("--frames A:B cuts the document of --doc ID; the stretches of --hits are their rows' "
                             "start:end")  # fmt: skip
    db = MotionDB.open(args.db)
    with _terminate_as_exit():  # SIGTERM mid-export: the written files are removed before the process ends
        if args.doc is not None:
            doc = int(db.document(args.doc)["doc_id"])  # an unknown id: an error naming the valid ones
            a, b = frame_span(args.frames, int(db.document(doc)["n_frames"]), f"document {doc}", "--frames", least=1)
            paths = export_stretch(db, doc, args.out, a, b, args.format, args.rig, args.search)
        else:
            paths = export_hits(db, args.hits, args.out, args.format, args.rig, args.search)
    for path in paths:
        print(path)
    print(f"{len(paths)} file(s) written to {args.out}")


def _template_search(args) -> None:
    from .relational.templates import shortest_instance

    _csv_folder(args.csv)
    with _engine(args) as engine:
        template = engine.template(args.template)
        try:
            table = engine.search_template(template, n_matches=args.n_matches, delta=args.delta,
                                           max_cost=args.max_cost, prefilter=args.prefilter)  # fmt: skip
        except ParameterError as exc:
            raise ParameterError(f"{args.template}: {exc}") from None
    limit = "" if args.max_cost is None else f", normalised cost <= {args.max_cost:g}"
    n = template.n_examples
    aligned = f", keyframe pre-filter: {table.attrs['aligned']:.0%} of the frames aligned" if args.prefilter else ""
    print(f"{len(table)} matches of template {template.label!r} ({len(template.values)} frames, {n} "
          f"example{'s' * (n != 1)}, {table.attrs['relational_set']} set) in {engine.db.path}{limit}{aligned}, in "
          f"{table.attrs['ms']:.1f} ms")  # fmt: skip
    own = template.meta.get("threshold")
    if args.max_cost is not None:
        empty = "try a larger --max-cost" + ("" if own is None else f"; the template's learned threshold is {own:.3f}")
    else:
        empty = f"no document holds the template's shortest instance, {shortest_instance(template)} frames"
    _print_ranked(table, args.n_matches, empty)
    _write_csv(table, args.csv)

def _reproduce(args) -> None:
    from .reproduction import reproduce

    reproduce(args.names, args.out, full=args.full, progress=not args.quiet)


def _datasets(args) -> None:
    from .io import datasets

    if args.action == "list" and args.name:
        raise ParameterError(f"datasets list takes no NAME (got {args.name!r}); `mocapviz datasets fetch NAME` "
                             "fetches one")
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


class _Parser(argparse.ArgumentParser):
    """argparse with mocapviz's one-line errors: ``mocapviz: error: ...`` and where to read the usage, status 2."""

    def error(self, message: str):
        message = re.sub(r"^argument (\S+): \1(?=[ :])", r"\1", message)  # a check that names the option itself
        self.exit(2, f"mocapviz: error: {message} (see `{self.prog} --help`)\n")


def _option(parser: argparse.ArgumentParser, *flags: str, check, **kwargs) -> None:
    """``parser.add_argument(*flags, **kwargs)`` whose value is ``check(text, name)``: a check of
    :mod:`mocapviz.validation` (its range bound with functools.partial) called with the option's names
    ("-K/--matches/--top"); its ParameterError becomes the parser's one-line error (status 2)."""
    name = "/".join(flags)

    def parse(text: str):
        try:
            return check(text, name)
        except ParameterError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parser.add_argument(*flags, type=parse, **kwargs)


_count = functools.partial(functools.partial, parse_count)  # _count(least=1) -> check(text, name)
_number = functools.partial(functools.partial, parse_number)


def _cluster_options(p: argparse.ArgumentParser) -> None:
    _option(p, "--scheduler", check=_scheduler_address, metavar="ADDRESS", help="run the tasks on this "
            "dask.distributed scheduler "
                   "(e.g. tcp://host:8786; its workers must see the same paths); default: a local cluster, one "
                   "worker process per core")  # fmt: skip
    p.add_argument("--no-cluster", action="store_true", help="no Dask: work in this process (threads)")


def _search_scheduler(p: argparse.ArgumentParser) -> None:
    _option(p, "--scheduler", check=_scheduler_address, metavar="ADDRESS", help="search the database sharded over "
            "a Dask cluster: 'local' (a local cluster, one worker per core) or a scheduler's address such as "
            "tcp://host:8786 (its workers must see the database's path); the same answer as without (exact "
            "modes); default: this process")  # fmt: skip


def build_parser() -> argparse.ArgumentParser:
    from .engine.parameters import PARAMETERS as P
    from .engine.parameters import RULES, default

    p = _Parser(prog="mocapviz", description="Content-based retrieval in motion-capture databases.")
    sub = p.add_subparsers(dest="command", required=True)

    ing = sub.add_parser("ingest", help="read ASF/AMC and BVH files into a MotionDB (creates or appends)")
    ing.add_argument("paths", nargs="+", help="files, folders (searched recursively) or glob patterns")
    ing.add_argument("--out", required=True, help="MotionDB directory")
    _option(ing, "--fps", check=_number(low=FPS_RANGE[0], high=FPS_RANGE[1]),
            help=f"resample every clip to this frame rate ({FPS_RANGE[0]}..{FPS_RANGE[1]:,})")
    ing.add_argument("--labels", help="label table (TSV/CSV with a 'file' column); default: tables beside the data")
    ing.add_argument("--mapping", help="JSON file {canonical joint: joint name} for rigs the rules cannot map")
    ing.add_argument("--asf", help="ASF skeleton for all AMC files (default: found beside each)")
    ing.add_argument("--up", choices=["auto", "y", "z"], help="up axis of BVH files (default auto)")
    ing.add_argument("--skip-bad", action="store_true", help="skip unreadable files with a warning")
    _cluster_options(ing)
    _option(ing, "--jobs", check=_count(least=1, most=MAX_JOBS), help=f"(1..{MAX_JOBS}) worker processes of the "
            "local cluster (default: one per core), or "
                     "with --no-cluster reader threads (default: the cores, at most 8)")
    ing.add_argument("--quiet", action="store_true", help="no progress bar")
    ing.set_defaults(func=_ingest)

    info = sub.add_parser("info", help="summarise a MotionDB")
    info.add_argument("db")
    info.add_argument("--documents", action="store_true", help="also list every document")
    info.set_defaults(func=_info)

    chk = sub.add_parser("check", help="read every file of a MotionDB and its derived data back and verify its "
                                       "checksum; exit status 0 if all are ok, 1 if any is damaged, 3 if derived data "
                                       "is only stale (older than the documents: the commands that rebuild it are "
                                       "printed)")  # fmt: skip
    chk.add_argument("db")
    chk.set_defaults(func=_check)

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
    _option(q, "--frames", check=parse_span, help="frame span A:B of the example, B excluded (default: all of it)")
    q.add_argument("--features", help="comma-separated relational feature names (default: all of the set)")
    P["query_mode"].add_to(q, "--mode")
    q.add_argument("--mismatch", dest="mismatches", type=P["mismatches"].reader("--mismatch"),
                   help="answer in mismatch mode: " + P["mismatches"].help("none: the --mode given"))
    _option(q, "--mismatch-at", check=functools.partial(parse_integers, least=0), dest="allowed",
            help=P["allowed"].help() + "; with --mismatch, comma-separated 0-based segments")
    P["relational_set"].add_to(q, "--relational-set", "--feature-set")
    _option(q, "-K", "--matches", "--top", check=_count(least=1), dest="rows", default=20,
            help="hits to print (default 20; --top: its old name)")
    q.add_argument("--csv", help="also write the ranked hit table to this CSV file (columns and frames as docs/glossary.md, Results: start and end within the document, half-open)")
    _search_scheduler(q)
    q.set_defaults(func=_query)

    fd = sub.add_parser("find", help="the stretches a scene description describes (\"kick_right then punch_left "
                        "within 2 s\"; docs/descriptions.md), through the relational index",
                        description="Find what a scene description describes (Müller et al. 2005 §6.3): progressions "
                        "of the relational features' states (rknee: straight bent straight), joined by 'and' "
                        "(concurrent), 'then ... within T s' and '|'; shipped names (mocapviz find --list) and stored "
                        "templates (template:NAME). Needs the relational index (mocapviz index DB). Columns as every "
                        "result table: start and end within the document, half-open; score = the hit's length in "
                        "seconds (shortest first); parts = where each part matched.")  # fmt: skip
    fd.add_argument("db", nargs="?", help="the MotionDB")
    fd.add_argument("description", nargs="?", help="the description, in quotes")
    fd.add_argument("--file", help="read the description from this file instead")
    P["n_matches"].add_to(fd, default=default("find", "n_matches"))
    fd.add_argument("--relational-set", dest="relational_set", choices=P["relational_set"].choices,
                    help="the set whose words the description uses (default: the one its 'set' statement or its "
                    "templates name, else 2005)")  # fmt: skip
    P["template_cost"].add_to(fd)
    fd.add_argument("--explain", action="store_true", help="print the description as read, the hits of each part "
                    "and where each hit's parts matched")  # fmt: skip
    fd.add_argument("--list", action="store_true", help="list the shipped named descriptions and exit")
    fd.add_argument("--csv", help="also write the ranked hit table to this CSV file (columns and frames as "
                    "docs/glossary.md, Results: start and end within the document, half-open)")  # fmt: skip
    fd.add_argument("--template-file", action="append", dest="template_files", metavar="NAME=FILE",
                    help="read template:NAME from this template file (.npz, `mocapviz template learn --out`) instead "
                    "of the one stored as NAME with the database; repeatable. The description itself names stored "
                    "templates only, never a file")  # fmt: skip
    _search_scheduler(fd)
    fd.set_defaults(func=_find)

    feat = sub.add_parser("features", help="compute and store the numeric feature sets of a MotionDB (kNN search)")
    feat.add_argument("db")
    _option(feat, "--numeric-sets", "--sets", check=functools.partial(parse_names, what="numeric set",
            options=NUMERIC_SETS), dest="numeric_sets", help=f"comma-separated numeric sets (default "
                      f"all: {','.join(NUMERIC_SETS)}; --sets: its old name)")  # fmt: skip
    feat.add_argument("--pca", help="PCA reference for Fp8/16/25 (only with one of them): a saved model (.npz) or a "
                      "MotionDB to fit it on (default: fitted on DB itself)")
    _cluster_options(feat)
    feat.add_argument("--quiet", action="store_true", help="no progress bar")
    feat.set_defaults(func=_features)

    kn = sub.add_parser("knn", help="the k nearest frames of one frame of a MotionDB (kd-tree)")
    kn.add_argument("db")
    _option(kn, "--frame", check=_doc_frame, required=True, help="DOC:FRAME, a document id and a frame within it")
    P["numeric_set"].add_to(kn, "--numeric-set", "--features")
    P["k"].add_to(kn, "-k")
    P["radius"].add_to(kn)
    P["eps"].add_to(kn)
    P["exclude_document"].add_to(kn)
    P["per_document"].add_to(kn)
    kn.add_argument("--quiet", action="store_true", help="no progress bar")
    kn.add_argument("--csv", help="also write the ranked hit table to this CSV file (columns and frames as docs/glossary.md, Results: start and end within the document, half-open)")
    _search_scheduler(kn)
    kn.set_defaults(func=_knn)

    mt = sub.add_parser("match", help="stretches of the DB that move like an example, ranked (lazy neighbourhood "
                        "graph or subsequence DTW)")  # fmt: skip
    mt.add_argument("db")
    mt.add_argument("--example", required=True, help="a motion file, or a document id of the DB (then its own "
                    "document is excluded from the matches)")  # fmt: skip
    _option(mt, "--frames", check=parse_span, help="frame span A:B of the example, B excluded (default: all of it)")
    P["numeric_set"].add_to(mt, "--numeric-set", "--features")
    P["n_matches"].add_to(mt)
    for name in ("k", "radius", "eps"):  # of --method lng only: None when not given (refused with dtw)
        mt.add_argument(*P[name].cli_flags if name != "k" else ("-k",), dest=name, default=None,
                        type=P[name].reader("-k" if name == "k" else P[name].cli_flags[0]),
                        help="--method lng: " + P[name].help(RULES.get(("match", name), default("match", name))))
    P["method"].add_to(mt)
    P["min_length"].add_to(mt)
    P["paths"].add_to(mt)
    mt.add_argument("--csv", help="also write the ranked hit table to this CSV file (columns and frames as docs/glossary.md, Results: start and end within the document, half-open)")
    _search_scheduler(mt)
    mt.set_defaults(func=_match)

    se = sub.add_parser("search", help="the clips (or stretches of long takes) of the DB that move most like an "
                        "example, ranked by DTW on a numeric feature set (exact or fast)")  # fmt: skip
    se.add_argument("db")
    se.add_argument("--example", required=True, help="a motion file, or a document id of the DB")
    _option(se, "--frames", check=parse_span, help="frame span A:B of the example, B excluded (default: all of it)")
    P["numeric_set"].add_to(se, "--numeric-set", "--features")
    P["n_matches"].add_to(se)
    P["mode"].add_to(se)
    se.add_argument("--stretches", action="store_true", help="the K best non-overlapping stretches inside documents "
                    "(subsequence DTW) instead of whole clips")  # fmt: skip
    se.add_argument("--min-length", dest="min_length", type=P["min_length"].reader("--min-length"),
                    help="with --stretches: " + P["min_length"].help())
    P["exclude_document"].add_to(se)
    se.add_argument("--csv", help="also write the ranked hit table to this CSV file (columns and frames as docs/glossary.md, Results: start and end within the document, half-open)")
    P["paths"].add_to(se)
    _search_scheduler(se)
    se.set_defaults(func=_search)

    tp = sub.add_parser("template", help="motion templates (Müller & Röder 2006): learn a class from its labelled "
                        "documents, stored with the DB; find its instances")  # fmt: skip
    tsub = tp.add_subparsers(dest="action", required=True)
    tl = tsub.add_parser("learn", help="learn the template of the documents with a label (of some actors only); "
                         "stored in DB/templates/LABEL[-ACTOR...].npz, replacing one of that name")  # fmt: skip
    tl.add_argument("db")
    tl.add_argument("--label", required=True, help="the class: a value of the documents' label column")
    tl.add_argument("--actors", help="comma-separated actors: learn from their documents only (default all)")
    P["relational_set"].add_to(tl, default=default("learn_template", "relational_set"))
    P["max_examples"].add_to(tl)
    tl.add_argument("--out", help="also write the template to this file (.npz)")
    tl.set_defaults(func=_template_learn)
    ts = tsub.add_parser("search", help="the stretches of the DB that match a template, best first",
                         description="The K best non-overlapping stretches of the DB's documents that match a "
                         "template (subsequence DTW, its don't-care features left out). Columns: rank, doc_id, name, "
                         "start and end (the stretch's frames within its document, half-open: end is one past the last "
                         "frame, as every result table of mocapviz), frames, start_s, end_s, cost (DTW cost), normalised_cost (cost per template "
                         "frame: the mean disagreement, in [0, 1]) and the document's labels.")  # fmt: skip
    ts.add_argument("db")
    ts.add_argument("template", metavar="FILE_OR_NAME", help="a template file, or the name of one stored in "
                    "DB/templates/ (by `mocapviz template learn`)")  # fmt: skip
    P["n_matches"].add_to(ts, default=default("search_template", "n_matches"))
    P["delta"].add_to(ts)
    P["max_cost"].add_to(ts)
    ts.add_argument("--csv", help="also write the ranked hit table to this CSV file (columns and frames as docs/glossary.md, Results: start and end within the document, half-open)")
    P["prefilter"].add_to(ts)
    _search_scheduler(ts)
    ts.set_defaults(func=_template_search)

    ex = sub.add_parser("export", help="write the stretches a search found (--hits, its --csv file) or one stretch "
                        "of a document (--doc) as motion files: BVH, AMC or glTF binary, one per hit")  # fmt: skip
    ex.add_argument("db")
    what = ex.add_mutually_exclusive_group(required=True)
    what.add_argument("--hits", metavar="HITS.csv", help="the hit table a search wrote with --csv FILE (columns rank, "
                      "doc_id, start, end: frames within the document, half-open)")  # fmt: skip
    _option(what, "--doc", check=_count(least=0), metavar="ID", help="one document (a doc id)")
    _option(ex, "--frames", check=parse_span, metavar="A:B", help="with --doc: frames A:B of it (B excluded; "
            "default: all)")  # fmt: skip
    ex.add_argument("--format", required=True, choices=["bvh", "amc", "glb"], help="bvh (BVH), amc (AMC with its "
                    "ASF; ASF/AMC sources only) or glb (glTF binary)")  # fmt: skip
    ex.add_argument("--rig", choices=["source", "canonical"], help="source: the source file's frames on its own rig; "
                    "canonical: the 24 canonical joints posed to the database's frames (default: canonical for glb, "
                    "source otherwise)")  # fmt: skip
    ex.add_argument("--out", required=True, help="output folder (created if missing; an existing one keeps its other "
                    "files). Written all or nothing: on any failure, the folder as it was")  # fmt: skip
    ex.add_argument("--search", help="what found the hits, written into every file (default: the hits file's name)")
    ex.set_defaults(func=_export)

    rp = sub.add_parser("reproduce", help="re-run the papers' experiments on the shared data; write CSV tables and "
                        "PNG/HTML figures")  # fmt: skip
    rp.add_argument("names", nargs="+", metavar="NAME", help="experiment function name(s) (index_statistics, "
                    "query_statistics, relational_query, alignment, knn_timings, rank_correlations, "
                    "similarity_matrices, lng_accuracy, numerical_search, reconstruction, base_poses, "
                    "retrieval_quality, template_quality) or 'all'")
    rp.add_argument("--out", required=True, help="output folder; each experiment writes OUT/NAME/")
    rp.add_argument("--full", action="store_true", help="the papers' sizes (slow; every shared archive as the "
                    "large database)")  # fmt: skip
    rp.add_argument("--quiet", action="store_true", help="no progress bars")
    rp.set_defaults(func=_reproduce)

    sv = sub.add_parser("serve", help="the dashboard in the browser: browse, query by example, kNN, matching, "
                        "correlations, index statistics, reconstruction")
    sv.add_argument("db", nargs="?", help="MotionDB folder (default: the embedded sample, ingested once)")
    _option(sv, "--port", check=parse_port, default=5006, help="port (1..65535, default 5006)")
    sv.add_argument("--address", default="127.0.0.1",
                    help="interface to listen on (default 127.0.0.1: this machine only; anything else exposes the "
                    "database to the network, needs --allow-origin and prints a warning)")
    sv.add_argument("--allow-origin", action="append", metavar="HOST:PORT", help="an address browsers open the "
                    "dashboard at besides 127.0.0.1, localhost, [::1] and --address at --port, e.g. "
                    "myhost.example.org:5006 (repeatable; needed with an --address other than loopback; never '*'). "
                    "Any other Host header, or WebSocket Origin (a WebSocket needs one), gets a 403")
    sv.add_argument("--show", action="store_true", help="open the dashboard in a web browser")
    _search_scheduler(sv)
    sv.set_defaults(func=_serve)

    ds = sub.add_parser("datasets", help="list the registered motion-capture datasets (the shared archives and the "
                        "embedded sample) with sizes, licences and sources, or fetch one")
    ds.add_argument("action", choices=["list", "fetch"])
    ds.add_argument("name", nargs="?", help="for fetch: a shared archive (see list) or 'sample' (embedded)")
    ds.set_defaults(func=_datasets)
    return p


def _serve(args) -> None:
    from .app import serve, websocket_origins
    from .app.backend import sample_database
    from .db.database import MotionDB

    websocket_origins(args.address, args.port, args.allow_origin)  # refused before the sample is ingested
    db = args.db if args.db else sample_database()
    MotionDB.open(db)  # a bad path fails before the server starts
    print(f"mocapviz: serving {db}: warming up (the first clicks then answer at once) …", flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        serve(db, port=args.port, address=args.address, show=args.show, allow_origin=args.allow_origin,
              scheduler=args.scheduler, ready=lambda url: print(f"mocapviz: ready: {url} (Ctrl-C stops)", flush=True))


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"mocapviz: warning: {message}", file=sys.stderr)


def main(argv=None) -> int:
    """Run ``mocapviz ARGV``; return the exit status: 0, 1 (the command refused a value or failed on bad input), 2
    (the argument parser refused the command line; returned, not raised, like every other status) or 3 (``check``:
    derived data stale, nothing damaged)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help (0) or a refused command line (2), its one line already printed
        return int(exc.code or 0)
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            status = args.func(args)
    except (MocapvizError, OSError) as exc:  # bad input; anything else is a bug and shows its traceback
        print(f"mocapviz: error: {exc}", file=sys.stderr)
        return 1
    return status or 0


def run() -> None:
    """The ``mocapviz`` command (the console script, ``python -m mocapviz.cli``): :func:`main` on this process's
    command line, then exit with its status.

    ``mocapviz serve`` first restarts itself with Python's objects on glibc's heap
    (:func:`mocapviz.heap.restart_with_trimmable_heap`; not where the C library is another, nor when ``PYTHONMALLOC``
    is set): its pages' objects, freed when a browser session closes, then leave the server's memory.

    The exit leaves out the interpreter's teardown, which frees a thousand modules (pandas, numba, LLVM) one by one:
    0.1 to 0.25 s, a fifth of a search, that a finished command does not need. What a normal exit does for the
    command is done first: the output flushed, the atexit handlers run. With a thread still running, or output that
    cannot be flushed (a closed pipe), the exit is the normal one.
    """
    import atexit
    import os
    import threading

    if sys.argv[1:2] == ["serve"]:  # a long-running server: what its closed sessions free goes back to the system
        from .heap import restart_with_trimmable_heap

        restart_with_trimmable_heap()
    status = main()
    if threading.active_count() > 1:  # a thread's work would be cut short
        sys.exit(status)
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):  # let the normal exit report it
        sys.exit(status)
    atexit._run_exitfuncs()  # logging.shutdown, multiprocessing's children, weakref.finalize (temporary folders)
    with contextlib.suppress(OSError, ValueError):
        sys.stdout.flush()
        sys.stderr.flush()
    os._exit(status)


if __name__ == "__main__":
    run()
