"""The database commands: ``mocapviz ingest`` (files into a MotionDB, its stored indexes and feature sets then
brought up to date), ``mocapviz info`` (its summary) and ``mocapviz check`` (every file of it read back and
verified)."""
from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

import pandas as pd

from .. import io as readers  # lazy: the ASF reader (and numba) load only for --asf
from ..engine import CANONICAL_JOINTS, MotionDB, expand_paths, stored_sets, update_derived
from ..errors import MocapvizError, MotionDBError, ParameterError
from ..integrity import check, rebuild_commands
from ..parallel import LOCAL, dask_client
from ..validation import plural
from .options import scheduler_of
from .output import printed


def run_ingest(args) -> None:
    mapping = _mapping(args.mapping) if args.mapping else None
    if args.labels and not Path(args.labels).is_file():
        raise ParameterError(f"--labels {args.labels}: no such file (a TSV/CSV label table with a 'file' column)")
    if args.asf:  # read once here: a bad skeleton is one error, not every AMC file failing (or skipped) with it
        try:
            readers.read_asf(args.asf)
        except (MocapvizError, OSError) as exc:
            raise ParameterError(f"--asf: {exc}") from None
    options = {k: v for k, v in (("asf", args.asf), ("up", args.up), ("take", args.take)) if v is not None}
    if args.marker_mapping:  # read once here: a bad mapping file is one error, not every C3D file failing with it
        try:
            options["marker_mapping"] = readers.read_marker_mapping(args.marker_mapping)
        except MocapvizError as exc:
            raise ParameterError(f"--marker-mapping: {exc}") from None
    scheduler = scheduler_of(args)
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
                             scheduler=scheduler, markers_only=args.markers_only, **options)
    print(db)
    if len(db.marker_documents):
        print(f"and {plural(len(db.marker_documents), 'marker-only document')} (no canonical joints)")
    _update_derived(db, progress=not args.quiet)


def _update_derived(db: MotionDB, progress: bool) -> None:
    """The derived data stored with ``db`` (indexes, numeric sets) brought up to date after an ingest, the new
    documents' frames alone computed (:func:`mocapviz.engine.update_derived`); one line per set."""
    if not any(stored_sets(db).values()):
        return
    for row in update_derived(db, progress=progress).to_dict("records"):
        done = f" ({plural(row['documents'], 'document')}, {plural(row['frames'], 'frame')}, {row['seconds']:.1f} s)" \
            if row["how"] in ("extended", "rebuilt") else ""
        print(f"{row['kind']} {row['set']}: {row['how']}{done}")


def _mapping(path: str) -> dict[str, str]:
    """``--mapping FILE``: a JSON object {canonical joint: joint name}, its keys checked against the canonical joints
    (the joint names are the skeleton's, checked per file)."""
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


def _check_out_folder(out: Path) -> None:
    """A NotADirectoryError unless ``out`` is a folder or can become one (no file in the way)."""
    for folder in (out, *out.parents):
        if folder.exists():
            if not folder.is_dir():
                raise NotADirectoryError(f"--out {out}: {folder} is a file, not a folder")
            return


def run_info(args) -> None:
    db = MotionDB.open(args.db)
    print(db)
    with pd.option_context("display.max_rows", 200, "display.width", 160):
        print(db.summary().round(2).to_string())
        if args.documents:
            cols = [c for c in db.documents.columns if c not in ("path", "sha256")]
            print(printed(db.documents[cols]))
        only = db.marker_documents.documents
        if len(only):
            print(f"{plural(len(only), 'marker-only document')} (no canonical joints; `mocapviz markers` searches "
                  "them)")  # fmt: skip
            if args.documents:
                print(printed(only[["doc_id", "name", "n_frames", "fps", "label"]].assign(
                    markers=only["markers"].map(len))))  # fmt: skip


def run_check(args) -> int:
    """Print the report of ``mocapviz.integrity.check``; exit status 1 when a file is damaged, 3 when derived data
    is only stale (with the commands that compute it again), else 0."""
    report = check(args.db)
    shown = report.assign(status=report["status"].replace({"damaged": "DAMAGED"}))[["file", "what", "status", "detail"]]
    with pd.option_context("display.max_rows", 500, "display.width", 200, "display.max_colwidth", 160):
        print(shown.to_string(index=False))
    damaged, stale = (int((report["status"] == s).sum()) for s in ("damaged", "stale"))
    rebuild = "".join(f"\n  {command}" for command in rebuild_commands(report))
    also = f"; {stale} stale" if stale else ""
    if damaged:
        raise MotionDBError(f"{args.db}: {plural(damaged, 'file')} of {len(report)} "
                            f"{plural(damaged, 'is', 'are', number=False)} damaged{also} (see above)" +
                            (f"; derived data is computed again by:{rebuild}" if rebuild else ""))  # fmt: skip
    if stale:
        print(f"mocapviz: {args.db}: {plural(stale, 'file')} of {len(report)} {plural(stale, 'is', 'are', number=False)}"
              f" stale derived data (intact, computed before the database last changed; nothing is damaged); compute "
              f"{plural(stale, 'it', 'them', number=False)} again with:{rebuild}", file=sys.stderr)
        return 3
    return 0
