"""The C3D tier of the mutation fuzzer (tests/test_fuzz.py): real C3D files of the ``c3d-markers`` archive damaged
where a binary file breaks, each case loaded (and mapped to the canonical joints) in a worker process.

Mutations (one to three per case): truncation and byte flips anywhere (test_fuzz's), byte flips in the header, in
the parameter section and in the point data, NaN / infinite / huge values written into point coordinates, the
frame rate zeroed (header and every RATE parameter). Each case must load with finite positions (NaN only in gaps,
within ±1e7 cm, a sane frame rate) or raise a mocapviz error naming the file; then ``canonical()`` must give finite
joints or a mocapviz error. ezc3d is native code, so a case runs in a worker process: a crash (segfault) or a hang
(no answer within HANG_S seconds) of the worker is counted against the case it was reading, and a new worker takes
the remaining cases.

The fast tier runs 200 cases over the six smallest files, the slow tier (``-m slow``) 3,000 over all twelve; each
test prints its counts.
"""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest
from test_fuzz import HANG_S, flip_bytes, mutate, truncate

FAST_CASES = 200
SLOW_CASES = 3000
_ODD_FLOATS = [np.nan, np.inf, -np.inf, 1e30, -3.4e38, 1e7, 0.0]


# ------------------------------------------------------------------------------------------------------ mutations
def _sections(data: bytes) -> tuple[int, int]:
    """Byte offsets of the parameter section and of the data (as the header states them, clamped to the file)."""
    if len(data) < 18:
        return 0, len(data)
    params = min(len(data), max(0, data[0] - 1) * 512)
    block = int.from_bytes(data[16:18], "little")
    return params, min(len(data), max(params, (block - 1) * 512))


def _flip_in(data: bytes, rng, lo: int, hi: int, where: str) -> tuple[bytes, str]:
    if hi <= lo:
        return data, f"no {where}"
    b = bytearray(data)
    at = sorted(int(i) for i in rng.integers(lo, hi, rng.integers(1, 5)))
    for i in at:
        b[i] ^= int(rng.integers(1, 256))
    return bytes(b), f"flip {where} bytes at {at}"


def flip_header(data: bytes, rng) -> tuple[bytes, str]:
    return _flip_in(data, rng, 0, min(512, len(data)), "header")


def flip_parameters(data: bytes, rng) -> tuple[bytes, str]:
    return _flip_in(data, rng, *_sections(data), "parameter")


def flip_data(data: bytes, rng) -> tuple[bytes, str]:
    return _flip_in(data, rng, _sections(data)[1], len(data), "data")


def odd_point_values(data: bytes, rng) -> tuple[bytes, str]:
    """1-4 aligned 4-byte words of the data section set to NaN, infinity or huge floats."""
    start = _sections(data)[1]
    words = (len(data) - start) // 4
    if words <= 0:
        return data, "no data"
    b = bytearray(data)
    done = []
    for _ in range(int(rng.integers(1, 5))):
        at = start + 4 * int(rng.integers(0, words))
        value = _ODD_FLOATS[int(rng.integers(0, len(_ODD_FLOATS)))]
        b[at : at + 4] = struct.pack("<f", value)
        done.append(f"{value:g}@{at}")
    return bytes(b), f"point values {', '.join(done)}"


def zero_rate(data: bytes, rng) -> tuple[bytes, str]:
    """The header's frame rate and the value of every parameter named RATE set to 0."""
    b = bytearray(data)
    if len(b) >= 24:
        b[20:24] = bytes(4)
    lo, hi = _sections(data)
    at = data.find(b"RATE", lo, hi)
    while at >= 0:
        if at >= 2 and abs(struct.unpack_from("b", data, at - 2)[0]) == 4 and at + 8 <= len(b):
            dims = b[at + 7]
            value = at + 8 + dims
            b[value : value + 4] = bytes(max(0, min(4, len(b) - value)))
        at = data.find(b"RATE", at + 4, hi)
    return bytes(b), "rates zeroed"


C3D_MUTATIONS = (truncate, flip_bytes, flip_header, flip_parameters, flip_data, odd_point_values, zero_rate)


# ------------------------------------------------------------------------------------------------------ worker
def _outcome(path: Path) -> dict:
    """Load one case and say what happened (run in the worker)."""
    from mocapviz.errors import MocapvizError
    from mocapviz.io import load
    from mocapviz.io.checks import DISTANCE_LIMIT_CM
    from mocapviz.motion import FPS_RANGE

    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        try:
            m = load(path)
            p = m.positions[~np.isnan(m.positions)]
            if not (np.isfinite(p).all() and np.abs(p).max(initial=0) <= DISTANCE_LIMIT_CM):
                return {"kind": "bad", "what": "non-finite or absurd positions"}
            if not FPS_RANGE[0] <= m.fps <= FPS_RANGE[1]:
                return {"kind": "bad", "what": f"fps {m.fps:g}"}
            try:
                c = m.canonical()
                if not np.isfinite(c.positions).all():
                    return {"kind": "bad", "what": "non-finite canonical joints"}
            except MocapvizError:
                pass
            kind, what = "loaded", ""
        except MocapvizError as exc:
            kind, what = ("typed" if path.name in str(exc) else "unnamed"), f"{type(exc).__name__}: {exc}"
        except Exception as exc:  # noqa: BLE001 - an untyped error is what the fuzzer looks for
            return {"kind": "crash", "what": f"{type(exc).__name__}: {exc}"}
    runtime = [str(w.message) for w in seen if issubclass(w.category, RuntimeWarning)]
    return {"kind": "warning", "what": runtime[0]} if runtime else {"kind": kind, "what": what}


def _worker(paths: list[str]) -> None:
    for p in paths:
        print(json.dumps({"start": p}), flush=True)
        print(json.dumps({"case": p, **_outcome(Path(p))}), flush=True)


def _run_workers(paths: list[Path]) -> dict[str, dict]:
    """Outcome per case file, running workers until every case has one (a dead or stuck worker's case: crash/hang)."""
    results, todo = {}, [str(p) for p in paths]
    while todo:
        proc = subprocess.Popen([sys.executable, __file__, "--worker", *todo], stdout=subprocess.PIPE, text=True,
                                cwd=Path(__file__).parent)  # fmt: skip
        hung = threading.Event()
        timer = None
        started = None
        for line in proc.stdout:
            if timer:
                timer.cancel()
            msg = json.loads(line)
            if "start" in msg:
                started = msg["start"]
                timer = threading.Timer(HANG_S, lambda p=proc, h=hung: (h.set(), p.kill()))
                timer.start()
            else:
                results[msg.pop("case")], started = msg, None
        if timer:
            timer.cancel()
        proc.wait()
        if started is not None:
            results[started] = {"kind": "hang" if hung.is_set() else "crash", "what": f"worker exit {proc.returncode}"}
        todo = [p for p in todo if p not in results]
    return results


# ------------------------------------------------------------------------------------------------------ the fuzzer
def fuzz_c3d(sources: list[Path], n_cases: int, seed: int, tmp: Path) -> tuple[dict, list]:
    """Run ``n_cases`` damaged copies of ``sources``; return (counts per outcome, failing cases with what was done)."""
    done = {}
    for case in range(n_cases):
        rng = np.random.default_rng([seed, case])
        src = sources[int(rng.integers(0, len(sources)))]
        data, what = mutate(src.read_bytes(), rng, C3D_MUTATIONS)
        path = tmp / f"case{case}.c3d"
        path.write_bytes(data)
        done[str(path)] = f"case {case} (seed {seed}) of {src.name}: {'; '.join(what)}"
    results = _run_workers([Path(p) for p in done])
    counts: dict[str, int] = {}
    failures = []
    for p, r in results.items():
        counts[r["kind"]] = counts.get(r["kind"], 0) + 1
        if r["kind"] not in ("typed", "loaded"):
            failures.append(f"{done[p]}: {r['kind']}: {r['what']}")
    return counts, failures


def c3d_sources(c3d_dir: Path, n: int = 6) -> list[Path]:
    """The ``n`` smallest C3D files (a case costs about its size): float and int16 (DEC) files among them."""
    return sorted(c3d_dir.glob("*.c3d"), key=lambda p: (p.stat().st_size, p.name))[:n]


def _report(counts: dict, failures: list, n_cases: int) -> None:
    print(f"fuzz c3d: {n_cases} cases: {counts}")
    for f in failures[:20]:
        print("  FAIL", f)
    assert not failures, f"{len(failures)} failing cases, e.g. {failures[:3]}"
    assert counts.get("typed", 0) > n_cases // 4 and counts.get("loaded", 0) > n_cases // 20, counts


# ------------------------------------------------------------------------------------------------------ tests
def test_c3d_mutations_damage_and_are_reproducible(c3d_dir):
    data = (c3d_dir / "cmu_07_12.c3d").read_bytes()
    for fn in C3D_MUTATIONS:
        changed = [fn(data, np.random.default_rng([7, i]))[0] != data for i in range(20)]
        assert sum(changed) >= 15, fn.__name__
        assert fn(data, np.random.default_rng(3)) == fn(data, np.random.default_rng(3))


def test_fuzz_c3d(c3d_dir, tmp_path):
    counts, failures = fuzz_c3d(c3d_sources(c3d_dir), FAST_CASES, 20261127, tmp_path)
    _report(counts, failures, FAST_CASES)


@pytest.mark.slow
def test_fuzz_c3d_slow(c3d_dir, tmp_path):
    counts, failures = fuzz_c3d(c3d_sources(c3d_dir, 12), SLOW_CASES, 1, tmp_path)
    _report(counts, failures, SLOW_CASES)


if __name__ == "__main__":  # a worker of _run_workers
    _worker(sys.argv[2:])
