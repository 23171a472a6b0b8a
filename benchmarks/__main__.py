"""``python -m benchmarks [--quick] [--only NAME ...]``: run the benchmarks, print markdown tables, write CSV results
and one report, ``benchmarks/REPORT.md`` (``benchmarks/results/REPORT-quick.md`` under --quick).

Each benchmark's printed markdown is also saved as ``benchmarks/results/<name>[-quick].md``; the report assembles
those (``benchmarks.report``), so a benchmark left out with --only keeps its previous section.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
NAMES = ("io", "dask", "relational", "knn", "match", "search", "templates", "scaling", "startup", "descriptions",
         "integrity", "dashboard", "engine", "audit")


class _Tee(io.TextIOBase):
    """Writes to the real stdout and keeps a copy."""

    def __init__(self, stream):
        self.stream, self.copy = stream, io.StringIO()

    def write(self, text):
        self.copy.write(text)
        return self.stream.write(text)

    def flush(self):
        self.stream.flush()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    parser.add_argument("--quick", action="store_true", help="small subsets, for a smoke run (a few minutes)")
    parser.add_argument("--repeats", type=int, default=3, help="runs per figure; the median is reported (default 3)")
    parser.add_argument("--no-ingest", action="store_true", help="skip the MotionDB.ingest benchmark of bench_io")
    parser.add_argument("--only", nargs="+", choices=NAMES, help="run only these benchmarks (default: all)")
    parser.add_argument(
        "--out",
        type=Path,
        default=Path(__file__).resolve().parent / "results",
        help="folder of the CSV and markdown results (default benchmarks/results)",
    )
    args = parser.parse_args(argv)
    # unpack the shared archives once, into the repository's cache (ignored by git)
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))

    from . import (
        bench_audit,
        bench_dashboard,
        bench_dask,
        bench_descriptions,
        bench_engine,
        bench_integrity,
        bench_io,
        bench_knn,
        bench_match,
        bench_relational,
        bench_scaling,
        bench_search,
        bench_startup,
        bench_templates,
        report,
    )

    runs = {
        "io": lambda: bench_io.main(quick=args.quick, repeats=args.repeats, ingest=not args.no_ingest,
                                    out_dir=args.out),
        **{name: (lambda mod=mod: mod.main(quick=args.quick, repeats=args.repeats, out_dir=args.out))
           for name, mod in (("dask", bench_dask), ("relational", bench_relational), ("knn", bench_knn),
                             ("match", bench_match), ("search", bench_search), ("templates", bench_templates),
                             ("scaling", bench_scaling), ("startup", bench_startup),
                             ("descriptions", bench_descriptions), ("integrity", bench_integrity),
                             ("dashboard", bench_dashboard), ("engine", bench_engine), ("audit", bench_audit))},
    }  # fmt: skip
    status = 0
    for name in args.only or NAMES:
        tee = _Tee(sys.stdout)
        with contextlib.redirect_stdout(tee):
            status = runs[name]() or status
        out = report.section_path(args.out, name, args.quick)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(tee.copy.getvalue())
    path = report.build(args.quick, args.out, command="python -m benchmarks " + " ".join(argv or sys.argv[1:]),
                        ran=args.only or NAMES)  # the others keep their sections of the report
    print(f"report: {path}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
