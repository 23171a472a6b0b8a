"""``python -m benchmarks [--quick]``: run the benchmarks, print markdown tables, write CSV results."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    parser.add_argument("--quick", action="store_true", help="small subsets, for a smoke run (< 1 min)")
    parser.add_argument("--repeats", type=int, default=3, help="runs per figure; the median is reported (default 3)")
    parser.add_argument("--no-ingest", action="store_true", help="skip the MotionDB.ingest benchmark")
    parser.add_argument(
        "--out",
        type=Path,
        default=Path(__file__).resolve().parent / "results",
        help="folder of the CSV results (default benchmarks/results)",
    )
    args = parser.parse_args(argv)
    # unpack the shared archives once, into the repository's cache (ignored by git)
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))

    from . import bench_io, bench_knn, bench_match, bench_relational

    status = bench_io.main(quick=args.quick, repeats=args.repeats, ingest=not args.no_ingest, out_dir=args.out)
    for bench in (bench_relational, bench_knn, bench_match):
        status = status or bench.main(quick=args.quick, repeats=args.repeats, out_dir=args.out)
    return status


if __name__ == "__main__":
    sys.exit(main())
