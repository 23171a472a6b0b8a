"""``mocapviz audit``: the near-copies of a collection (or between two), clusters of copies, the leakage of a
test split into the training split, and the documents a clean training set keeps (docs/audit.md)."""
from __future__ import annotations

import time
from pathlib import Path

import pandas as pd

from ..engine import Engine, MotionDB
from ..engine.parameters import arguments
from ..errors import ParameterError
from ..store import atomic_write
from ..validation import plural
from .inputs import engine_of
from .output import csv_folder, printed

SHOWN = 20
"""Pairs printed (every pair goes to --csv)."""


def run_audit(args) -> None:
    for flag in ("csv", "leakage_csv", "keep_one"):
        csv_folder(getattr(args, flag))
    if args.split and args.against:
        raise ParameterError("--split names the train and test documents of one collection: leave out --against")
    if args.split and not Path(args.split).is_file():
        raise ParameterError(f"--split {args.split}: no such file")
    with engine_of(args) as engine:
        other = MotionDB.open(args.against) if args.against else None
        t0 = time.perf_counter()
        pairs = engine.audit(other, progress=not args.quiet, **arguments(args, "audit"))
        seconds = time.perf_counter() - t0
        _report(engine, other, pairs, seconds)
        _write(pairs, args.csv, "pairs")
        if args.split:
            leaks = engine.leakage(pairs, args.split)
            test = sorted(set(leaks["doc_a"]))
            print(f"\nleakage: {plural(len(test), 'test document')} with a near-copy in train "
                  f"({plural(len(leaks), 'pair')}){':' if len(leaks) else ''}")  # fmt: skip
            if len(leaks):
                print(printed(leaks.head(SHOWN)[["doc_a", "name_a", "start_a", "end_a", "doc_b", "name_b", "start_b",
                                                 "end_b", "cost", "mirrored"]].round(2)))  # fmt: skip
            _write(leaks, args.leakage_csv, "leakage report")
        if args.keep_one:
            kept = engine.keep_one(pairs)
            _write(kept[["doc_id", "name"]], args.keep_one, f"documents kept ({len(kept)} of {len(engine.db)})")


def _report(engine: Engine, other, pairs: pd.DataFrame, seconds: float) -> None:
    where = f"{engine.db.path} against {other.path}" if other is not None else str(engine.db.path)
    a = pairs.attrs
    print(f"audit of {where}: {plural(len(pairs), 'pair')} of near-copies in "
          f"{plural(pairs['cluster'].nunique() if len(pairs) else 0, 'cluster')}, {int(pairs['mirrored'].sum())} "
          f"mirrored ({seconds:.1f} s)")  # fmt: skip
    print(f"stretches of at least {a['min_length']:g} s compared at {a['rate']:g} Hz; threshold {a['threshold']:.2f} cm "
          f"({a['threshold_how']})")  # fmt: skip
    if len(pairs):
        shown = pairs.head(SHOWN).round({"seconds": 2, "cost": 2, "scale": 3})
        print(printed(shown))
        if len(pairs) > SHOWN:
            print(f"... {len(pairs) - SHOWN} more (--csv FILE writes every pair)")


def _write(table: pd.DataFrame, path: str | None, what: str) -> None:
    if path:
        atomic_write(path, table.to_csv(index=False).encode())
        print(f"{what} written to {path}")
