"""The ``mocapviz`` command.

    mocapviz ingest PATH... --out DB [--fps N] [--labels FILE] [--skip-bad] [--jobs N]
    mocapviz info DB [--documents]
    mocapviz datasets list
    mocapviz datasets fetch NAME        (NAME: a shared archive, or ``sample`` for the embedded sample)

Errors print one line (``mocapviz: error: ...``) and exit with status 1.
"""
from __future__ import annotations

import argparse
import json
import sys

import pandas as pd

from . import datasets
from .database import MotionDB
from .errors import MocapFormatError, MotionDBError, SkeletonMappingError


def _ingest(args) -> None:
    mapping = None
    if args.mapping:
        with open(args.mapping) as fh:
            mapping = json.load(fh)
    options = {k: v for k, v in (("asf", args.asf), ("up", args.up)) if v is not None}
    db = MotionDB.ingest(args.paths, args.out, fps=args.fps, labels=args.labels, mapping=mapping,
                         skip_bad=args.skip_bad, n_jobs=args.jobs, progress=not args.quiet, **options)
    print(db)


def _info(args) -> None:
    db = MotionDB.open(args.db)
    print(db)
    with pd.option_context("display.max_rows", 200, "display.width", 160):
        print(db.summary().round(2).to_string())
        if args.documents:
            cols = [c for c in db.documents.columns if c not in ("path", "sha256")]
            print(db.documents[cols].to_string(index=False))


def _datasets(args) -> None:
    if args.action == "list":
        with pd.option_context("display.width", 160, "display.max_colwidth", 40):
            print(datasets.info().drop(columns=["sha256"]).to_string(index=False))
    else:
        if not args.name:
            raise ValueError("datasets fetch needs a NAME (see 'mocapviz datasets list', or 'sample')")
        print(datasets.sample() if args.name == "sample" else datasets.fetch(args.name, progress=True))


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
    ing.add_argument("--jobs", type=int, default=1, help="reader processes (default 1)")
    ing.add_argument("--quiet", action="store_true", help="no progress bar")
    ing.set_defaults(func=_ingest)

    info = sub.add_parser("info", help="summarise a MotionDB")
    info.add_argument("db")
    info.add_argument("--documents", action="store_true", help="also list every document")
    info.set_defaults(func=_info)

    ds = sub.add_parser("datasets", help="list or fetch the registered motion-capture archives")
    ds.add_argument("action", choices=["list", "fetch"])
    ds.add_argument("name", nargs="?")
    ds.set_defaults(func=_datasets)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except (MocapFormatError, SkeletonMappingError, MotionDBError, datasets.DatasetError, FileNotFoundError,
            ValueError, KeyError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"mocapviz: error: {msg}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
