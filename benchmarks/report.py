"""``python -m benchmarks.report [--quick]``: assemble the benchmarks' markdown outputs into one report.

Every benchmark run by ``python -m benchmarks`` has its printed markdown saved as ``benchmarks/results/<name>.md``
(``<name>-quick.md`` under --quick). This module puts them together, in ``SECTIONS`` order, under a header with
the date, the commit and the machine description: ``benchmarks/REPORT.md`` (a --quick run writes
``benchmarks/results/REPORT-quick.md`` instead, so that a smoke run never replaces the full report).

A benchmark left out of a run (``python -m benchmarks --only NAME``) keeps its section of the existing report as it
is (the saved outputs are not committed, so the report is where the figures of earlier runs live); a section comes
from a saved output when its benchmark ran, or when the report has no figures for it yet. Only a benchmark with
neither gets a line saying it was not run.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
# (file stem, title)
SECTIONS = (
    ("io", "Parse + forward kinematics and MotionDB.ingest (bench_io)"),
    ("dask", "Dask scale-out: ingest and features, serial vs local cluster (bench_dask)"),
    ("relational", "Relational features, index build and queries vs Müller et al. 2005 Tables 2–3 (bench_relational)"),
    ("knn", "k nearest neighbours vs Krüger et al. 2010 Table 1 and brute force (bench_knn)"),
    ("match", "LNG global matching vs subsequence DTW (bench_match)"),
    ("search", "Similarity search: exact / fast DTW search vs brute force and dtaidistance (bench_search)"),
    ("templates", "Motion templates: keyframe pre-filter vs the full DTW pass (bench_templates)"),
    ("scaling", "Cost growth at 1M / 4M / 10M frames: every query path, one process and sharded (bench_scaling)"),
    ("startup", "Start-up: import, --help and one search from a fresh process (bench_startup)"),
    ("descriptions", "Scene descriptions: index vs frame-wise scan (bench_descriptions)"),
    ("integrity", "Checked reads: xxh3 of every block on first read vs sha256 (bench_integrity)"),
    ("dashboard", "The dashboard's answers on every shared archive at 30 Hz (bench_dashboard)"),
    ("engine", "Engine overhead: every use case through Engine(db) vs the library function it wraps (bench_engine)"),
    ("audit", "Audit of a collection: index self-join vs brute-force subsequence DTW and STUMPY (bench_audit)"),
)
NOT_RUN = "not run: "  # how the line of a section with no figures begins


def report_path(quick: bool) -> Path:
    return RESULTS / "REPORT-quick.md" if quick else HERE / "REPORT.md"


def section_path(out_dir: Path, name: str, quick: bool) -> Path:
    return Path(out_dir) / f"{name}{'-quick' if quick else ''}.md"


def _demote(text: str) -> str:
    """Headings moved down so that a benchmark's top heading is level 3, below the report's section headings (the
    title is the only level-1 heading; no level skipped, which the documentation site's build refuses)."""
    levels = [len(m.group(1)) for m in re.finditer(r"^(#+) ", text, flags=re.MULTILINE)]
    shift = 3 - min(levels, default=3)
    return re.sub(r"^(#+) ", lambda m: "#" * (len(m.group(1)) + shift) + " ", text, flags=re.MULTILINE)


def existing_sections(text: str) -> dict[str, str]:
    """The sections of a report (its text) that hold figures: {benchmark name: the section's body as written}.
    A section is found by its heading's title, or by the ``(bench_NAME)`` that ends it (a renamed title); a
    "not run" section holds none."""
    names = {title: name for name, title in SECTIONS}
    found, name, body = {}, None, []
    for line in [*text.splitlines(), "## end"]:
        heading = re.match(r"^## (?:\d+\. )?(.*)$", line)
        if heading:
            if name and "\n".join(body).strip() and not "\n".join(body).strip().startswith(NOT_RUN):
                found[name] = "\n".join(body).strip()
            title = heading.group(1).strip()
            suffix = re.search(r"\(bench_(\w+)\)$", title)
            name = names.get(title) or (suffix.group(1) if suffix and suffix.group(1) in dict(SECTIONS) else None)
            body = []
        elif name:
            body.append(line)
    return found


def build(quick: bool = False, out_dir: Path = RESULTS, command: str | None = None, ran=None) -> Path:
    """Write the report and return its path.

    Parameters
    ----------
    quick : bool
        Assemble the --quick outputs into ``results/REPORT-quick.md``.
    out_dir : Path
        The folder of the saved outputs.
    command : str, optional
        The command line, for the report's header.
    ran : iterable of str, optional
        The benchmarks of this run: their sections come from their saved outputs; every other section is kept
        from the existing report when it has figures there. Default (reassembling): every saved output is used.
    """
    from .common import machine_info

    out = report_path(quick)
    kept = existing_sections(out.read_text()) if out.is_file() else {}
    ran = None if ran is None else set(ran)
    info = machine_info()
    lines = [
        f"# mocapviz benchmark report{' (QUICK smoke run: small subsets, not the papers’ scale)' if quick else ''}",
        "",
        ("Generated by `python -m benchmarks` (`make bench`); do not edit by hand. Each benchmark section below "
        "was written by its own run (its date and total time are at its end); every figure stands beside its "
        "baseline (another library, a numpy scan or brute force, or the paper's published figure) and their ratio."),
        "",
        f"- generated: {time.strftime('%Y-%m-%d %H:%M:%S %Z')}" + (f"; command: `{command}`" if command else ""),
        f"- commit: {info['commit']}",
        (f"- machine: {info['cpu']}; {info['cores']} cores ({info['usable_cores']} usable); "
        f"{info['ram_gib']} GiB RAM; {info['os']}"),
        f"- software: Python {info['python']}; " + ", ".join(
            f"{k} {info[k]}" for k in ("numpy", "numba", "scipy", "bvh", "pykdtree", "mocapviz")),
        f"- multiprocessing start method: {info['start_method']}; load average at report time: {info['load_start']}",
        "",
        "Contents: " + "; ".join(f"{i + 1}. {title}" for i, (_, title) in enumerate(SECTIONS)),
        "",
    ]  # fmt: skip
    for i, (name, title) in enumerate(SECTIONS):
        lines += [f"## {i + 1}. {title}", ""]
        path = section_path(out_dir, name, quick)
        fresh = path.is_file() and (name in ran if ran is not None else True)
        if fresh or (path.is_file() and name not in kept):
            stamp = time.strftime("%Y-%m-%d %H:%M", time.localtime(path.stat().st_mtime))
            lines += [f"*(output of {path.name}, written {stamp})*", "", _demote(path.read_text().strip()), ""]
        elif name in kept:  # left out of this run: its figures stay as the report had them
            lines += [kept[name], ""]
        else:
            lines += [(f"{NOT_RUN}no `{path.relative_to(HERE.parent) if path.is_relative_to(HERE.parent) else path}`"
                      " — run `python -m benchmarks` (or this benchmark alone) first"), ""]  # fmt: skip
    text = "\n".join(lines).replace(str(HERE.parent) + "/", "")  # paths relative to the repository, not this machine
    out.write_text(text.rstrip() + "\n")
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.report", description=__doc__)
    parser.add_argument("--quick", action="store_true", help="assemble the --quick outputs")
    parser.add_argument("--out", type=Path, default=RESULTS, help="folder of the saved outputs")
    args = parser.parse_args(argv)
    print(build(args.quick, args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
