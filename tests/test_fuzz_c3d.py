"""The C3D tier of the mutation fuzzer (tests/test_fuzz.py): real C3D files of the ``c3d-markers`` archive damaged
two ways, each case built and loaded in a worker process.

Byte mutations (one to three per case): truncation and byte flips anywhere (test_fuzz's), byte flips in the header,
in the parameter section and in the point data, NaN / infinite / huge values written into point coordinates, the
frame rate zeroed (header and every RATE parameter). Each case must load with finite positions (NaN only in gaps,
within ±1e7 cm, a sane frame rate) or raise a mocapviz error naming the file; then ``canonical()`` must give finite
joints or a mocapviz error.

Field mutations (one per case): one numeric field of the file set to an odd value. The field is a header word
(points, analog samples per frame, first and last frame, interpolation gap, scale, data block, analog samples per
frame of a channel, frame rate: set alone, each disagrees with its copy in the parameters) or one value of any
numeric POINT or ANALOG parameter (POINT USED, SCALE, RATE, FRAMES, DATA_START, MOVIE_DELAY, LAB_ROT; ANALOG USED,
RATE, SCALE, OFFSET, GEN_SCALE, GAIN, BITS, BOARDS, PCHAN, ... as the file has them); the value is 0, 1, -0, the old
one ± 1, doubled, halved or negated (a scale's sign), the type's extremes, NaN, ±inf, ±1e30, 1e-30 or a random one.
A case that loads must equal the original file's load (positions, frames, frame rate, first frame, marker names:
the fields that set these are stated twice, in the header and in a parameter, so one changed alone is a
disagreement to refuse) or carry a MocapFormatWarning naming what it changed; every other case must raise a
mocapviz error naming the file. A case that loads otherwise is *wrong*.

ezc3d is native code, so a case runs in a worker process (and ezc3d, since mocapviz.io.isolated, in a helper of the
worker): a crash (segfault) or a hang (no answer within HANG_S seconds) of the worker is counted against the case it
was reading, and a new worker takes the remaining cases. Two workers run side by side.

Fast tier: 150 byte cases over the six smallest files and 150 field cases over all twelve (about 14 s); slow tier
(``-m slow``): 2,000 byte cases (3,000 before the field tier, cut to stay well within 3 minutes) and 2,400 field
cases over all twelve (about 2 minutes on 2 busy cores). Each test prints its counts: typed (refused, naming the
file), loaded / equal (the field tier: equal to the original), warned (loaded with a MocapFormatWarning; "changed,
warned" where it differs from the original and the warning names the field). Outside pytest:
``python tests/test_fuzz_c3d.py --tier fields --cases 2400 --seed 1``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import struct
import subprocess
import sys
import tempfile
import threading
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from test_fuzz import HANG_S, flip_bytes, mutate, truncate

FAST_BYTE_CASES, FAST_FIELD_CASES = 150, 150
SLOW_BYTE_CASES, SLOW_FIELD_CASES = 2000, 2400  # bytes: 3,000 until the field tier came (3,000 + 2,400: 148 s)
WORKERS = 2
_ODD_FLOATS = [np.nan, np.inf, -np.inf, 1e30, -3.4e38, 1e7, 0.0]


# ------------------------------------------------------------------------------------------------------ byte mutations
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


# ------------------------------------------------------------------------------------------------------ the fields
@dataclass(frozen=True)
class Field:
    """One numeric value of a C3D file: where it is and how it is stored.

    ``label`` is how a message names it (``POINT:RATE``, ``ANALOG:SCALE[3]``, ``header word 11-12 (frame rate)``);
    ``kind`` one of ``u2`` (a header word), ``i1``, ``i2`` (parameter integers), ``f4`` (a float); ``order`` the
    byte order; ``dec`` whether floats are DEC F-floating (processor type 85)."""

    label: str
    offset: int
    kind: str
    order: str
    dec: bool

    def read(self, data: bytes) -> float:
        raw = data[self.offset : self.offset + int(self.kind[1])]
        if self.kind == "f4":
            if self.dec:  # DEC: 16-bit halves swapped, exponent 2 above IEEE's
                raw = bytes([raw[2], raw[3], raw[0], raw[1] - 1 if raw[1] else 0])
            return float(np.frombuffer(raw, "<f4" if self.dec else self.order + "f4")[0])
        return float(np.frombuffer(raw, self.order + self.kind)[0])

    def write(self, data: bytes, value: float) -> bytes:
        if self.kind == "f4":
            with np.errstate(over="ignore"):
                raw = np.array([value], ("<" if self.dec else self.order) + "f4").tobytes()
            if self.dec:
                raw = bytes([raw[2], (raw[3] + 1) % 256 if any(raw) else 0, raw[0], raw[1]])
        else:
            bits = 8 * int(self.kind[1])
            raw = (int(value) % 2**bits).to_bytes(bits // 8, "little" if self.order == "<" else "big")
        return data[: self.offset] + raw + data[self.offset + len(raw) :]

    def odd_values(self, old: float, rng) -> list[float]:
        """The values to try, in random order: the type's edges, the old value moved, and one at random."""
        if self.kind == "f4":
            values = [0.0, -0.0, 1.0, np.nan, np.inf, -np.inf, 1e30, -1e30, 1e-30, old + 1, 2 * old, old / 2, -old,
                      float(rng.normal() * 1000)]  # fmt: skip
        else:
            low, high = {"u2": (0, 65535), "i2": (-32768, 32767), "i1": (-128, 127)}[self.kind]
            values = [0, 1, -1, old + 1, old - 1, 2 * old, old // 2, -old, low, high, int(rng.integers(low, high + 1))]
        return [values[i] for i in rng.permutation(len(values))]


_HEADER = [(2, "u2", "header word 2 (points)"), (4, "u2", "header word 3 (analog samples per frame)"),
           (6, "u2", "header word 4 (first frame)"), (8, "u2", "header word 5 (last frame)"),
           (10, "u2", "header word 6 (interpolation gap)"), (12, "f4", "header word 7-8 (scale)"),
           (16, "u2", "header word 9 (data block)"), (18, "u2", "header word 10 (analog samples per channel)"),
           (20, "f4", "header word 11-12 (frame rate)")]  # fmt: skip
_PROCESSORS = {84: "<", 85: "<", 86: ">"}
_PARAMETER_KINDS = {1: "i1", 2: "i2", 4: "f4"}


def c3d_fields(data: bytes) -> list[Field]:
    """Every numeric field of an intact C3D file: the header words that state its layout, and each value of every
    numeric POINT and ANALOG parameter (walked here, apart from mocapviz's own walk)."""
    start = (data[0] - 1) * 512
    order, dec = _PROCESSORS[data[start + 3]], data[start + 3] == 85
    fields = [Field(label, at, kind, order, dec) for at, kind, label in _HEADER]
    at, groups, entries = start + 4, {}, []
    while True:
        chars, group = struct.unpack_from("bb", data, at)
        if chars == 0:
            break
        name = data[at + 2 : at + 2 + abs(chars)].decode("latin-1").upper()
        link = at + 2 + abs(chars)
        step = struct.unpack_from(order + "h", data, link)[0]
        if group < 0:
            groups[-group] = name
        else:
            kind, dims = struct.unpack_from("bB", data, link + 2)
            entries.append((group, name, kind, int(np.prod(tuple(data[link + 4 : link + 4 + dims]))), link + 4 + dims))
        if step == 0:
            break
        at = link + step
    for group, name, kind, n, offset in entries:
        if groups[group] in ("POINT", "ANALOG") and kind in _PARAMETER_KINDS:
            fields += [Field(f"{groups[group]}:{name}" + (f"[{i}]" if n > 1 else ""), offset + i * kind,
                             _PARAMETER_KINDS[kind], order, dec) for i in range(n)]  # fmt: skip
    return fields


def set_field(data: bytes, label: str, value: float) -> bytes:
    """``data`` with the field named ``label`` (:class:`Field`) set to ``value``."""
    (f,) = [f for f in c3d_fields(data) if f.label == label]
    return f.write(data, value)


def field_mutation(data: bytes, rng) -> tuple[bytes, str, str]:
    """One field, chosen among the header words and the parameters with equal chances (then uniformly), set to one
    of its odd values that changes the file: (data, what was done, the field's label)."""
    fields = c3d_fields(data)
    header = [f for f in fields if f.label.startswith("header")]
    parameters = {f.label.split("[")[0]: f for f in fields if not f.label.startswith("header")}
    if rng.random() < 0.3:
        f = header[int(rng.integers(0, len(header)))]
    else:
        name = sorted(parameters)[int(rng.integers(0, len(parameters)))]
        same = [f for f in fields if f.label.split("[")[0] == name]
        f = same[int(rng.integers(0, len(same)))]
    old = f.read(data)
    for value in f.odd_values(old, rng):
        changed = f.write(data, value)
        if changed != data:
            return changed, f"{f.label} {old:g} -> {f.read(changed):g}", f.label
    return data, f"{f.label} {old:g} unchanged", f.label


# ------------------------------------------------------------------------------------------------------ worker
def motion_digest(m) -> str:
    """What must not change: positions (gaps as gaps), frames, frame rate, first frame, marker names."""
    h = hashlib.sha1(np.where(np.isnan(m.positions), np.float32(-1e9), m.positions).tobytes())
    h.update(repr((m.n_frames, m.fps, m.labels.get("first_frame"), m.joint_names)).encode())
    return h.hexdigest()


def _outcome(path: Path, canonical: bool) -> dict:
    """Load one case and say what happened (run in the worker)."""
    from mocapviz.errors import MocapFormatWarning, MocapvizError
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
            if canonical:
                try:
                    if not np.isfinite(m.canonical().positions).all():
                        return {"kind": "bad", "what": "non-finite canonical joints"}
                except MocapvizError:
                    pass
            out = {"kind": "loaded", "what": "", "digest": motion_digest(m)}
        except MocapvizError as exc:
            out = {"kind": "typed" if path.name in str(exc) else "unnamed", "what": f"{type(exc).__name__}: {exc}"}
        except Exception as exc:  # noqa: BLE001 - an untyped error is what the fuzzer looks for
            return {"kind": "crash", "what": f"{type(exc).__name__}: {exc}"}
    runtime = [str(w.message) for w in seen if issubclass(w.category, RuntimeWarning)]
    if runtime:
        return {"kind": "warning", "what": runtime[0]}
    notes = [str(w.message) for w in seen if issubclass(w.category, MocapFormatWarning)]
    if notes and out["kind"] == "loaded":
        out.update(kind="warned", what=notes[0])
    return out


def build_case(spec: dict) -> tuple[bytes, str, str | None]:
    """The damaged file of a case (data, what was done, the field changed or None), from its spec alone."""
    rng = np.random.default_rng([spec["seed"], spec["case"], 1])
    data = Path(spec["source"]).read_bytes()
    if spec["tier"] == "bytes":
        data, what = mutate(data, rng, C3D_MUTATIONS)
        return data, "; ".join(what), None
    return field_mutation(data, rng)


def _worker(specs: list[dict]) -> None:
    """Build, load and remove each case; print what happened (a line before each case, for a crash or hang)."""
    for spec in specs:
        print(json.dumps({"start": spec["case"]}), flush=True)
        data, what, label = build_case(spec)
        path = Path(spec["dir"]) / f"case{spec['case']}.c3d"
        path.write_bytes(data)
        try:
            result = _outcome(path, canonical=spec["tier"] == "bytes")
        finally:
            path.unlink()
        print(json.dumps({"case": spec["case"], "done": what, "field": label, **result}), flush=True)


def _run_worker(specs: list[dict]) -> dict[int, dict]:
    """Outcome per case, running workers until every case has one (a dead or stuck worker's case: crash/hang)."""
    results, todo = {}, list(specs)
    while todo:
        with subprocess.Popen([sys.executable, __file__, "--worker"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              text=True, cwd=Path(__file__).parent) as proc:  # fmt: skip
            proc.stdin.write(json.dumps(todo))
            proc.stdin.close()
            hung, timer, started = threading.Event(), None, None
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
        if started is not None:
            results[started] = {"kind": "hang" if hung.is_set() else "crash", "what": f"worker exit {proc.returncode}"}
        todo = [s for s in todo if s["case"] not in results]
    return results


# ------------------------------------------------------------------------------------------------------ the fuzzer
def fuzz_c3d(sources: list[Path], n_cases: int, seed: int, tier: str,
             reference: dict | None = None) -> tuple[dict, list]:
    """Run ``n_cases`` damaged copies of ``sources`` (``tier`` "bytes" or "fields") on WORKERS workers; return
    (counts per outcome, failing cases with what was done). ``reference``: the digest of each source's load, for
    the field tier (a field case that loads must equal it, or warn naming the field)."""
    with tempfile.TemporaryDirectory() as tmp:
        specs = []
        for case in range(n_cases):
            pick = np.random.default_rng([seed, case, 0]).integers(0, len(sources))
            specs.append({"case": case, "source": str(sources[int(pick)]), "seed": seed, "tier": tier, "dir": tmp})
        with ThreadPoolExecutor(WORKERS) as pool:
            results = {k: v for part in pool.map(_run_worker, [specs[i::WORKERS] for i in range(WORKERS)])
                       for k, v in part.items()}  # fmt: skip
    counts: dict[str, int] = {}
    failures = []
    for spec in specs:
        r = results[spec["case"]]
        kind = r["kind"]
        if tier == "fields" and kind in ("loaded", "warned"):
            if r["digest"] == reference[spec["source"]]:
                kind = "equal" if kind == "loaded" else "warned"
            else:
                kind = "changed, warned" if kind == "warned" and _mention(r["field"]) in r["what"] else "wrong"
        counts[kind] = counts.get(kind, 0) + 1
        if kind not in ("typed", "loaded", "warned", "equal", "changed, warned"):
            failures.append(f"case {spec['case']} (seed {seed}) of {Path(spec['source']).name}: "
                            f"{build_case(spec)[1]}: {kind}: {r['what']}")  # fmt: skip
    return counts, failures


def _mention(label: str) -> str:
    """How a warning names a field: ``POINT:RATE`` for a parameter's value, ``header`` for a header word."""
    return "header" if label.startswith("header") else label.split("[")[0]


def c3d_sources(c3d_dir: Path, n: int = 6) -> list[Path]:
    """The ``n`` smallest C3D files (a case costs about its size): float and int16 (DEC) files among them."""
    return sorted(c3d_dir.glob("*.c3d"), key=lambda p: (p.stat().st_size, p.name))[:n]


def reference_digests(sources: list[Path]) -> dict[str, str]:
    from mocapviz.io import load

    return {str(p): motion_digest(load(p)) for p in sources}


def _report(counts: dict, failures: list, n_cases: int, tier: str) -> None:
    print(f"fuzz c3d {tier}: {n_cases} cases: {counts}")
    for f in failures[:20]:
        print("  FAIL", f)
    assert not failures, f"{len(failures)} failing cases, e.g. {failures[:3]}"
    if tier == "bytes":
        assert counts.get("typed", 0) > n_cases // 4 and counts.get("loaded", 0) > n_cases // 20, counts
    else:  # most single fields are stated twice: refused; some are unused by a marker file: loaded, equal
        assert counts.get("typed", 0) > n_cases // 3 and counts.get("equal", 0) > n_cases // 10, counts


# ------------------------------------------------------------------------------------------------------ tests
def test_c3d_mutations_damage_and_are_reproducible(c3d_dir):
    data = (c3d_dir / "cmu_07_12.c3d").read_bytes()
    for fn in C3D_MUTATIONS:
        changed = [fn(data, np.random.default_rng([7, i]))[0] != data for i in range(20)]
        assert sum(changed) >= 15, fn.__name__
        assert fn(data, np.random.default_rng(3)) == fn(data, np.random.default_rng(3))
    spec = {"seed": 3, "case": 5, "source": str(c3d_dir / "btk_Gait.c3d"), "tier": "fields"}
    assert build_case(spec) == build_case(spec) and build_case(spec)[0] != (c3d_dir / "btk_Gait.c3d").read_bytes()


def test_fields_read_as_ezc3d_reads_them(c3d_dir):
    """The field editor reads what ezc3d reads (Intel and DEC floats, header and parameters), and writes what it
    reads back: the fuzzer changes the values it says it changes."""
    import ezc3d

    for name in ("cmu_07_12.c3d", "btk_Gait.c3d", "btk_FunctionalWalk.c3d"):
        data = (c3d_dir / name).read_bytes()
        fields = {f.label: f for f in c3d_fields(data)}
        c3d = ezc3d.c3d(str(c3d_dir / name))
        for group, key in (("POINT", "RATE"), ("POINT", "SCALE"), ("POINT", "USED"), ("ANALOG", "USED")):
            assert fields[f"{group}:{key}"].read(data) == pytest.approx(c3d["parameters"][group][key]["value"][0])
        assert fields["header word 4 (first frame)"].read(data) == c3d["header"]["points"]["first_frame"] + 1
        for f in fields.values():
            for value in (0.0, 3.0, -2.5 if f.kind == "f4" else 7):
                assert f.read(f.write(data, value)) == value, (name, f.label, value)


def test_fuzz_c3d(c3d_dir):
    counts, failures = fuzz_c3d(c3d_sources(c3d_dir), FAST_BYTE_CASES, 20261127, "bytes")
    _report(counts, failures, FAST_BYTE_CASES, "bytes")


def test_fuzz_c3d_fields(c3d_dir):
    sources = c3d_sources(c3d_dir, 12)
    counts, failures = fuzz_c3d(sources, FAST_FIELD_CASES, 20261207, "fields", reference_digests(sources))
    _report(counts, failures, FAST_FIELD_CASES, "fields")


@pytest.mark.slow
def test_fuzz_c3d_slow(c3d_dir):
    counts, failures = fuzz_c3d(c3d_sources(c3d_dir, 12), SLOW_BYTE_CASES, 1, "bytes")
    _report(counts, failures, SLOW_BYTE_CASES, "bytes")


@pytest.mark.slow
def test_fuzz_c3d_fields_slow(c3d_dir):
    sources = c3d_sources(c3d_dir, 12)
    counts, failures = fuzz_c3d(sources, SLOW_FIELD_CASES, 1, "fields", reference_digests(sources))
    _report(counts, failures, SLOW_FIELD_CASES, "fields")


if __name__ == "__main__":
    if sys.argv[1:] == ["--worker"]:  # a worker of _run_worker: the case specs on stdin
        _worker(json.load(sys.stdin))
    else:
        parser = argparse.ArgumentParser(description="the C3D fuzzer outside pytest")
        parser.add_argument("--tier", choices=("bytes", "fields"), default="fields")
        parser.add_argument("--cases", type=int, default=SLOW_FIELD_CASES)
        parser.add_argument("--seed", type=int, default=1)
        args = parser.parse_args()
        from mocapviz.io import datasets

        found = c3d_sources(Path(datasets.fetch("c3d-markers")), 12)
        ref = reference_digests(found) if args.tier == "fields" else None
        _report(*fuzz_c3d(found, args.cases, args.seed, args.tier, ref), args.cases, args.tier)
