"""Start-up (issue 24 item 6): the wall time of a command from a fresh process, beside the floor every command pays.

Measured, each in a new process (``subprocess``), ``RUNS`` times in turn (one run of every command per round, so
that a busy moment slows them alike), after one warm-up run of each that fills the caches (the numba kernels'
on-disk cache, Python's bytecode cache); the median and the range are reported:

- ``python -c "import mocapviz"``;
- ``mocapviz --help`` (target <= 0.5 s);
- ``mocapviz search SAMPLE --example 7 -K 5 --exclude-document`` on the embedded sample (24 clips; its MotionDB and
  numeric features built once under ``.cache/bench/startup``; target <= 1.0 s);
- the floors, in the same rounds: ``python -c "import numpy, pandas"`` (what any command that reads a MotionDB
  pays), the same ending in ``os._exit(0)`` and, for the search, that plus ``import numba`` and one call of a cached
  numba kernel (numba's own start-up: its compiler's registries, which import ``scipy.linalg``). ``mocapviz`` exits
  without the interpreter's teardown (:func:`mocapviz.cli.run`); the floors ending in ``os._exit`` do the same.

The processes write and read Python's bytecode cache (``PYTHONDONTWRITEBYTECODE`` unset, ``PYTHONPYCACHEPREFIX``
under ``.cache/bench/startup``), as an installed package does; without it every mocapviz module would be compiled
from source on every run. Beside each command: the heavy packages its process had imported when it ended (one
extra run, not timed).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from .common import REPO, CpuMonitor, header, log, machine_info, markdown, write_results_csv
from .common import fmt as _f

RUNS = 7  # timed runs per command (3 with --quick)
HELP_TARGET_S = 0.5
SEARCH_TARGET_S = 1.0
HEAVY = ("numpy", "pandas", "pyarrow", "numba", "scipy", "scipy.spatial", "tqdm", "dask", "distributed", "panel")
WORK = REPO / ".cache" / "bench" / "startup"
FLOOR_KERNEL = '''import os

import numba
import numpy as np
import pandas as pd


@numba.njit(cache=True)
def total(x):
    return x.sum()


total(np.zeros(3))
os._exit(0)  # no interpreter teardown, as the mocapviz command
'''


def _env() -> dict:
    env = dict(os.environ, MOCAPVIZ_HOME=os.environ.get("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz")),
               PYTHONPYCACHEPREFIX=str(WORK / "pycache"))  # fmt: skip
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _mocapviz() -> list[str]:
    """The ``mocapviz`` console script beside this Python (as a user runs it), else ``python -m mocapviz.cli``."""
    script = Path(sys.executable).with_name("mocapviz")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "mocapviz.cli"]


def sample_db() -> Path:
    """The embedded sample ingested, with its numeric feature sets stored (built once, rebuilt when stale)."""
    from mocapviz.db.database import MotionDB
    from mocapviz.db.layout import manifest_file
    from mocapviz.errors import MocapvizError
    from mocapviz.features import load_numeric
    from mocapviz.io import datasets

    path = WORK / "sample.mdb"
    env, cli = _env(), _mocapviz()
    try:
        load_numeric(MotionDB.open(path), "F15E")
        return path
    except MocapvizError:
        pass
    log(f"building {path} (the embedded sample and its numeric features)")
    if not manifest_file(path).is_file():
        subprocess.run([*cli, "ingest", str(datasets.fetch("sample")), "--out", str(path), "--no-cluster", "--quiet"],
                       check=True, env=env, capture_output=True)  # fmt: skip
    subprocess.run([*cli, "features", str(path), "--no-cluster", "--quiet"], check=True, env=env, capture_output=True)
    return path


def commands(db: Path) -> list[dict]:
    """The timed commands: what, the command line shown, the argv run, the target (s) and which floor it is."""
    py, cli = sys.executable, _mocapviz()
    search = ["search", str(db), "--example", "7", "-K", "5", "--exclude-document"]
    kernel = WORK / "floor_kernel.py"
    return [
        {"what": "floor: numpy + pandas", "shown": 'python -c "import numpy, pandas"',
         "argv": [py, "-c", "import numpy, pandas"], "target": None, "floor": True},
        {"what": "floor: numpy + pandas, no teardown", "shown": 'python -c "import numpy, pandas, os; os._exit(0)"',
         "argv": [py, "-c", "import numpy, pandas, os; os._exit(0)"], "target": None, "floor": True},
        {"what": "floor: + numba, one cached kernel, no teardown", "shown": "python floor_kernel.py (numpy, pandas, "
         "numba; one call of a cached @njit; os._exit)", "argv": [py, str(kernel)], "target": None, "floor": True},
        {"what": "import mocapviz", "shown": 'python -c "import mocapviz"', "argv": [py, "-c", "import mocapviz"],
         "target": None, "floor": False},
        {"what": "mocapviz --help", "shown": "mocapviz --help", "argv": [*cli, "--help"], "target": HELP_TARGET_S,
         "floor": False},
        {"what": "one search", "shown": "mocapviz " + " ".join(search).replace(str(REPO) + "/", ""),
         "argv": [*cli, *search], "target": SEARCH_TARGET_S, "floor": False},
    ]  # fmt: skip


def _run(argv: list[str], env: dict) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run(argv, env=env, capture_output=True, cwd=WORK, check=False)
    seconds = time.perf_counter() - t0
    if proc.returncode:
        raise RuntimeError(f"{' '.join(argv)} exited with {proc.returncode}: {proc.stderr.decode()[-2000:]}")
    return seconds


def loaded_packages(argv: list[str], env: dict) -> list[str]:
    """The HEAVY packages in sys.modules when the command's process ends (the same command, run through a wrapper
    that reports them at exit)."""
    report = ("import atexit, os, sys\n"
              f"def _loaded(): print('LOADED', *[m for m in {HEAVY!r} if m in sys.modules], file=sys.stderr,"
              " flush=True)\n"
              "atexit.register(_loaded)\n"
              "_exit = os._exit\n"
              "os._exit = lambda status: (atexit.unregister(_loaded), _loaded(), _exit(status))\n")  # fmt: skip
    if argv[0] != sys.executable or argv[1] == "-m":  # mocapviz: the console script, or python -m mocapviz.cli
        rest = argv[1:] if argv[0] != sys.executable else argv[3:]
        wrapped = [sys.executable, "-c", report + f"from mocapviz.cli import main; sys.exit(main({rest!r}))"]
    elif argv[1] == "-c":
        wrapped = [sys.executable, "-c", report + argv[2]]
    else:  # a script
        wrapped = [sys.executable, "-c", report + f"import runpy; runpy.run_path({argv[1]!r}, run_name='__main__')"]
    proc = subprocess.run(wrapped, env=env, capture_output=True, text=True, cwd=WORK, check=False)
    line = next((ln for ln in proc.stderr.splitlines() if ln.startswith("LOADED")), "LOADED")
    return line.split()[1:]


def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info()
    WORK.mkdir(parents=True, exist_ok=True)
    (WORK / "floor_kernel.py").write_text(FLOOR_KERNEL)
    db = sample_db()
    env = _env()
    cmds = commands(db)
    runs = 3 if quick else max(RUNS, repeats)
    t0 = time.perf_counter()
    for c in cmds:  # warm-up: numba's disk cache and the bytecode cache filled, the files in the page cache
        _run(c["argv"], env)
    warm = time.perf_counter() - t0
    times = {c["what"]: [] for c in cmds}
    for r in range(runs):
        log(f"round {r + 1} of {runs}")
        for c in cmds:
            times[c["what"]].append(_run(c["argv"], env))
    floor = statistics.median(times["floor: numpy + pandas"])
    numba_floor = statistics.median(times["floor: + numba, one cached kernel, no teardown"])
    rows = []
    for c in cmds:
        t = times[c["what"]]
        median = statistics.median(t)
        rows.append({"what": c["what"], "command": c["shown"], "median_s": median, "min_s": min(t), "max_s": max(t),
                     "runs": len(t), "over_floor_s": median - floor,
                     "over_numba_floor_s": median - numba_floor if c["what"] == "one search" else None,
                     "target_s": c["target"],
                     "meets_target": None if c["target"] is None else bool(median <= c["target"]),
                     "loaded": " ".join(loaded_packages(c["argv"], env))})  # fmt: skip
    info["others"] = monitor.report()
    notes = [f"{runs} timed runs of each command, in turn (median; range min–max), after one warm-up run of each "
             f"({warm:.1f} s, not timed); every run a new process",
             "bytecode cache on (PYTHONPYCACHEPREFIX under .cache/bench/startup), numba kernels from their disk cache",
             (f"the sample MotionDB: the embedded sample (24 clips, 5,543 frames at 120 Hz), ingested and its numeric "
              f"sets stored once under .cache/bench/startup; targets: --help <= {HELP_TARGET_S} s, one search <= "
              f"{SEARCH_TARGET_S} s (issue 24 item 6)")]  # fmt: skip
    title = "### Start-up: import, --help and one search from a fresh process" + (" (quick)" if quick else "")
    print(header(title, info, ("numpy", "numba", "scipy"), notes))
    print()
    print(markdown(
        "| what | command | median s | range s | above the numpy + pandas floor s | above the numba floor s | "
        "target s | heavy packages loaded |", "|---|---|---:|---:|---:|---:|---:|---|",
        [[r["what"], f"`{r['command']}`", _f(r["median_s"]), f"{_f(r['min_s'])}–{_f(r['max_s'])}",
          "—" if r is rows[0] else f"{r['over_floor_s']:+.2f}",
          "—" if r["over_numba_floor_s"] is None else f"{r['over_numba_floor_s']:+.2f}",
          "—" if r["target_s"] is None else f"{r['target_s']:.1f} ({'met' if r['meets_target'] else 'NOT met'})",
          r["loaded"] or "—"] for r in rows]))  # fmt: skip
    print()
    print("The floors are the baseline: a command that reads a MotionDB pays the numpy + pandas import, and one "
          "that runs a numba kernel pays numba's start-up too (its import, and on the first call its compiler's "
          "registries, which import scipy.linalg), however little it imports of mocapviz. `mocapviz` exits without "
          "the interpreter's teardown (`mocapviz.cli.run`: output flushed and atexit handlers run, then `os._exit`); "
          "the floors marked \"no teardown\" do the same, the first one tears down as a plain `python -c` does.")
    out = Path(out_dir) if out_dir else REPO / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    name = f"startup{'-quick' if quick else ''}.csv"
    write_results_csv(out / name, {"startup": pd.DataFrame(rows)}, info)
    print()
    print(f"CSV: benchmarks/results/{name}; total benchmark time {time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(quick="--quick" in sys.argv))
