"""A seeded mutation fuzzer over real files of the shared data: every damaged file gives a typed mocapviz error that
names the file, or a Motion with finite positions and a sane frame rate, within time and memory bounds.

Mutations (one to three per case): bit flips, line deletions and duplications, numbers replaced by huge, tiny,
NaN, infinite, negative or malformed ones, keyword case changes, truncation, white-space changes and encoding
damage (byte-order marks, UTF-16, invalid UTF-8, NUL and Latin-1 bytes). ASF/AMC cases damage the AMC or its ASF.

The "garbage" class (one damage per case) makes ASF/AMC pairs that a lax reader loads as something wrong: a bone's
lines deleted from every AMC frame (the root or another), a frame emptied (or every one), every ASF direction
zeroed, NaN / inf / overflow in an ASF ``limits``, ``id`` or ``direction``, an AMC that is just ``0``, an AMC cut
inside its only frame. Each must be refused with a typed error, or (an AMC cut inside its last frame) load with a
MocapFormatWarning; one that loads silently counts as silent garbage.

The fast tier runs a few hundred cases per format, the slow tier (``-m slow``) thousands; each test prints its
counts. Outside pytest: ``python tests/test_fuzz.py --format bvh --cases 2000 --seed 1`` prints the same counts
(``--format amc`` the random ASF/AMC mutations, ``--format garbage`` the garbage class).
"""

from __future__ import annotations

import argparse
import re
import signal
import sys
import time
import traceback
import tracemalloc
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from mocapviz.errors import MocapFormatWarning, MocapvizError
from mocapviz.io import find_asf, load
from mocapviz.io.checks import DISTANCE_LIMIT_CM
from mocapviz.motion import FPS_RANGE

HANG_S = 60  # a case still running after this (wall clock) is stopped and counted as a hang
CPU_BUDGET_S = 10.0  # a case that needed more CPU than this (normal cases take milliseconds) counts as a hang
MEMORY_FIXED = 32 * 2**20  # per case: peak traced allocation at most this + 4 x the arrays returned + 16 x the input
FAST_CASES = 300
SLOW_CASES = 4000  # BVH; ASF/AMC cases cost about four times as much (two files each): half as many

_NUMBER = re.compile(rb"(?<![^\s])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![^\s])")
_WORD = re.compile(rb"(?m)^[ \t]*([A-Za-z:][A-Za-z_:\-]*)")
_SPACE = re.compile(rb"[ \t]+")
_ODD_NUMBERS = [b"1e308", b"-1e308", b"1e39", b"-1e39", b"3.5e38", b"1e-300", b"-1e-300", b"1e-45", b"nan", b"NaN",
                b"-nan", b"inf", b"-inf", b"Infinity", b"1e999", b"-1e400", b"-0", b"0", b"-1", b"-7.5", b"1e6",
                b"123456789012345678901234567890", b"2.5", b"0x1F", b"1_000", b"1e", b"--1", b"1.2.3", b"\xd9\xa3"]


# ------------------------------------------------------------------------------------------------------ mutations
def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


_BARE = re.compile(rb"(?m)^[ \t]*[-+\d.][^\n]*$")


def _body_start(data: bytes) -> int:
    """Byte offset of the first line after MOTION (if any) that starts with a number (a BVH frame line, an AMC frame
    number), or the length of ``data``."""
    m = _BARE.search(data, data.find(b"MOTION") + 1)
    return len(data) if m is None else m.start()


def _line_at(data: bytes, at: int) -> int:
    return data.count(b"\n", 0, at) + 1


def flip_bytes(data: bytes, rng) -> tuple[bytes, str]:
    if not data:
        return data, "nothing to flip"
    b = bytearray(data)
    at = sorted(int(i) for i in rng.integers(0, len(b), rng.integers(1, 5)))
    for i in at:
        b[i] ^= int(rng.integers(1, 256))
    return bytes(b), f"flip bytes at {at}"


def delete_lines(data: bytes, rng) -> tuple[bytes, str]:
    lines = _lines(data)
    k, n = int(rng.integers(0, len(lines))), int(rng.integers(1, 4))
    return b"\n".join(lines[:k] + lines[k + n :]), f"delete lines {k + 1}..{k + n}"


def duplicate_lines(data: bytes, rng) -> tuple[bytes, str]:
    lines = _lines(data)
    k, n = int(rng.integers(0, len(lines))), int(rng.integers(1, 3))
    return b"\n".join(lines[: k + n] + lines[k : k + n] + lines[k + n :]), f"duplicate lines {k + 1}..{k + n}"


def replace_number(data: bytes, rng) -> tuple[bytes, str]:
    # half of the time a number of the header (BVH hierarchy and Frames/Frame Time, ASF, AMC frame numbers)
    head = _body_start(data) if rng.random() < 0.5 else len(data)
    found = [m for m in _NUMBER.finditer(data, 0, max(head, 1))] or list(_NUMBER.finditer(data))
    if not found:
        return data, "no number"
    m = found[int(rng.integers(0, len(found)))]
    new = _ODD_NUMBERS[int(rng.integers(0, len(_ODD_NUMBERS)))] if rng.random() < 0.8 else b"-" + m.group()
    return data[: m.start()] + new + data[m.end() :], f"number {m.group()!r} -> {new!r} at line {_line_at(data, m.start())}"


def change_case(data: bytes, rng) -> tuple[bytes, str]:
    found = list(_WORD.finditer(data))
    if not found:
        return data, "no word"
    m = found[int(rng.integers(0, len(found)))]
    ways = [how for how in ("lower", "upper", "title", "swapcase") if getattr(m.group(1), how)() != m.group(1)]
    how = ways[int(rng.integers(0, len(ways)))] if ways else "swapcase"
    word = getattr(m.group(1), how)()
    return data[: m.start(1)] + word + data[m.end(1) :], f"{how} {m.group(1)!r} at line {_line_at(data, m.start())}"


def truncate(data: bytes, rng) -> tuple[bytes, str]:
    at = int(rng.integers(0, len(data) + 1)) if rng.random() < 0.7 else len(data) - int(rng.integers(1, 200))
    at = max(0, at)
    return data[:at], f"truncate at byte {at} of {len(data)}"


def change_space(data: bytes, rng) -> tuple[bytes, str]:
    how = int(rng.integers(0, 6))
    if how == 0:
        return data.replace(b"\r\n", b"\n").replace(b"\n", b"\r\n"), "CR LF line ends"
    if how == 1:
        return data.replace(b"\r\n", b"\n").replace(b"\n", b"\r"), "CR line ends"
    found = list(_SPACE.finditer(data))
    if not found:
        return data, "no space"
    m = found[int(rng.integers(0, len(found)))]
    new = [b"\t", b"\v", b"\f", b"   ", b"", b"\xa0"][int(rng.integers(0, 6))] if how < 5 else b"\v\f "
    where = _line_at(data, m.start())
    if how == 4:  # white space before a line
        k = data.rfind(b"\n", 0, m.start()) + 1
        return data[:k] + new + data[k:], f"{new!r} before line {where}"
    return data[: m.start()] + new + data[m.end() :], f"space -> {new!r} at line {where}"


def damage_encoding(data: bytes, rng) -> tuple[bytes, str]:
    how = int(rng.integers(0, 8))
    if how == 0:
        return b"\xef\xbb\xbf" + data, "UTF-8 BOM"
    if how == 1:
        return b"\xef\xbb\xbf\xff\xfe" + data, "BOM then invalid UTF-8"
    if how == 2:
        return data.decode("latin-1").encode("utf-16"), "UTF-16"
    at = int(rng.integers(0, len(data) + 1))
    new = [b"\xff\xfe", b"\xc3\x28", b"\x00", "é".encode(), b"\xe9"][how - 3]
    return data[:at] + new + data[at:], f"insert {new!r} at line {_line_at(data, at)}"


MUTATIONS = (flip_bytes, delete_lines, duplicate_lines, replace_number, change_case, truncate, change_space,
             damage_encoding)


# ------------------------------------------------------------------------------- garbage: ASF/AMC that must not load
_FRAME = re.compile(rb"(?m)^[ \t]*\d+[ \t\r]*$")
_BONE = re.compile(rb"(?m)^[ \t]*([A-Za-z][^ \t\r\n]*)[^\n]*(?:\n|$)")
_PLAIN_NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
_NON_FINITE = [b"nan", b"NaN", b"-nan", b"inf", b"-inf", b"Infinity", b"1e400", b"-1e400", b"1e999"]


def _frames(amc: bytes) -> list[int]:
    """Byte offsets of the frame-number lines of an AMC (after its header)."""
    return [m.start() for m in _FRAME.finditer(amc)]


def drop_bone(amc: bytes, asf: bytes, rng) -> tuple[bytes, bytes, str]:
    names = sorted({m.group(1) for m in _BONE.finditer(amc, _frames(amc)[0])} - {b"root"})
    name = b"root" if rng.random() < 0.25 else names[int(rng.integers(0, len(names)))]
    kept = _BONE.sub(lambda m: b"" if m.group(1) == name else m.group(), amc)
    return kept, asf, f"AMC: bone {name.decode()} deleted from every frame"


def empty_frames(amc: bytes, asf: bytes, rng) -> tuple[bytes, bytes, str]:
    starts = _frames(amc) + [len(amc)]
    if rng.random() < 0.2:
        return amc[: starts[0]] + _BONE.sub(b"", amc[starts[0] :]), asf, "AMC: every bone line deleted"
    k = int(rng.integers(0, len(starts) - 1))
    number_end = amc.index(b"\n", starts[k]) + 1 if b"\n" in amc[starts[k] : starts[k + 1]] else starts[k + 1]
    return (amc[:number_end] + amc[starts[k + 1] :], asf,
            f"AMC: frame {k + 1} of {len(starts) - 1} emptied")  # fmt: skip


def zero_directions(amc: bytes, asf: bytes, rng) -> tuple[bytes, bytes, str]:
    return amc, re.sub(rb"(?m)^([ \t]*direction)[^\n]*", rb"\1 0 0 0", asf), "ASF: every direction 0 0 0"


def non_finite_asf(amc: bytes, asf: bytes, rng) -> tuple[bytes, bytes, str]:
    key = [b"limits", b"id", b"direction"][int(rng.integers(0, 3))]
    lines = list(re.finditer(rb"(?m)^[ \t]*(?:limits\b|\()[^\n]*" if key == b"limits" else
                             rb"(?m)^[ \t]*" + key + rb"\b[^\n]*", asf))  # (limits: a pair a line)
    line = lines[int(rng.integers(0, len(lines)))]
    numbers = list(_PLAIN_NUMBER.finditer(asf, line.start(), line.end()))
    m = numbers[int(rng.integers(0, len(numbers)))]
    odd = [v for v in _NON_FINITE if key != b"limits" or v not in (b"inf", b"-inf")]  # (the ASF's "no limit")
    new = odd[int(rng.integers(0, len(odd)))]
    return amc, asf[: m.start()] + new + asf[m.end() :], (f"ASF: {key.decode()} {m.group()!r} -> {new!r} at line "
                                                          f"{_line_at(asf, m.start())}")


def just_zero(amc: bytes, asf: bytes, rng) -> tuple[bytes, bytes, str]:
    new = [b"0", b"0\n", b"1\r\n", b"1\n\n"][int(rng.integers(0, 4))]
    return new, asf, f"AMC: the file is {new!r}"


def cut_only_frame(amc: bytes, asf: bytes, rng) -> tuple[bytes, bytes, str]:
    starts = _frames(amc) + [len(amc)]
    frame = amc[: starts[1]]  # the header and the first frame
    last_line = frame.rstrip(b"\r\n").rfind(b"\n") + 1
    at = int(rng.integers(frame.index(b"\n", starts[0]) + 1, last_line + 1))
    return amc[:at], asf, f"AMC: only frame 1 kept, cut at byte {at} (its last bone line at {last_line})"


GARBAGE = (drop_bone, empty_frames, zero_directions, non_finite_asf, just_zero, cut_only_frame)


def mutate(data: bytes, rng, mutations=MUTATIONS) -> tuple[bytes, list[str]]:
    """``data`` damaged by one to three random ``mutations`` (one in two cases one), and what was done."""
    done = []
    for _ in range(1 if rng.random() < 0.5 else int(rng.integers(2, 4))):
        fn = mutations[int(rng.integers(0, len(mutations)))]
        data, what = fn(data, rng)
        done.append(f"{fn.__name__}: {what}")
    return data, done


# ------------------------------------------------------------------------------------------------------ the fuzzer
@dataclass
class Counts:
    """What the fuzzer saw. ``crashes``, ``unnamed``, ``non_finite``, ``hangs``, ``over_memory``, ``numpy_warnings``
    and ``silent`` (a garbage case loaded without a MocapFormatWarning) list the failing cases (case id, mutations,
    what happened)."""

    fmt: str
    cases: int = 0
    typed: int = 0
    typed_with_line: int = 0
    loaded: int = 0
    warned: int = 0
    silent: list = field(default_factory=list)
    crashes: list = field(default_factory=list)
    unnamed: list = field(default_factory=list)
    non_finite: list = field(default_factory=list)
    hangs: list = field(default_factory=list)
    over_memory: list = field(default_factory=list)
    numpy_warnings: list = field(default_factory=list)
    max_cpu_s: float = 0.0
    max_peak_mb: float = 0.0

    @property
    def failures(self) -> list:
        return (self.crashes + self.unnamed + self.non_finite + self.hangs + self.over_memory + self.numpy_warnings
                + self.silent)

    def summary(self) -> str:
        return (f"fuzz {self.fmt}: {self.cases} cases: {self.typed} typed errors ({self.typed_with_line} naming a "
                f"line), {self.loaded} finite loads ({self.warned} with a MocapFormatWarning); crashes "
                f"{len(self.crashes)}, errors not naming the file {len(self.unnamed)}, non-finite or absurd accepted "
                f"{len(self.non_finite)}, silent garbage {len(self.silent)}, hangs {len(self.hangs)}, over the memory "
                f"bound {len(self.over_memory)}, numpy warnings {len(self.numpy_warnings)}; slowest case "
                f"{self.max_cpu_s:.2f} CPU-s, largest peak {self.max_peak_mb:.1f} MB")


class _Hang(BaseException):
    """Raised by the alarm in a case that runs too long (a BaseException: no reader's ``except`` catches it)."""


def _on_alarm(signum, frame):
    raise _Hang()


def _check_motion(m) -> str | None:
    """What is wrong with a loaded Motion, or None."""
    arrays = {"positions": m.positions, "quaternions": m.quaternions, "euler": m.euler}
    for name, a in arrays.items():
        if a is not None and not np.isfinite(a).all():
            return f"non-finite {name}"
    if np.abs(m.positions).max(initial=0) > DISTANCE_LIMIT_CM:
        return f"position {np.abs(m.positions).max():g} cm"
    if not FPS_RANGE[0] <= m.fps <= FPS_RANGE[1]:
        return f"fps {m.fps:g}"
    r = m.resample(30)
    if not np.isfinite(r.positions).all() or r.n_frames < 1:
        return "resample(30) gave non-finite positions"
    return None


def run_case(case: int, fmt: str, sources: list, seed: int, tmp: Path, counts: Counts) -> None:
    """Damage one source (an ``.bvh`` path or an ``(.amc, .asf)`` pair; ``fmt`` "garbage": with one of
    :data:`GARBAGE`) and load it; record the outcome."""
    rng = np.random.default_rng([seed, case])
    src = sources[int(rng.integers(0, len(sources)))]
    if fmt == "bvh":
        data, done = mutate(src.read_bytes(), rng)
        path = tmp / f"case{case}.bvh"
        path.write_bytes(data)
        named, kwargs = (path,), {}
    else:
        amc, asf = src
        amc_data, asf_data = amc.read_bytes(), asf.read_bytes()
        if fmt == "garbage":
            amc_data, asf_data, what = GARBAGE[int(rng.integers(0, len(GARBAGE)))](amc_data, asf_data, rng)
            done = [what]
        elif rng.random() < 0.5:
            amc_data, done = mutate(amc_data, rng)
            done = ["AMC " + d for d in done]
        else:
            asf_data, done = mutate(asf_data, rng)
            done = ["ASF " + d for d in done]
        path, asf_path = tmp / f"case{case}.amc", tmp / f"case{case}.asf"
        path.write_bytes(amc_data)
        asf_path.write_bytes(asf_data)
        named, kwargs = (path, asf_path), {"asf": asf_path}
        data = amc_data + asf_data
    what = f"case {case} (seed {seed}) of {src if fmt == 'bvh' else src[0]}: {'; '.join(done)}"
    counts.cases += 1
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    c0 = time.process_time()
    returned = 0
    old = signal.signal(signal.SIGALRM, _on_alarm)
    signal.alarm(HANG_S)
    try:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            try:
                m = load(path, **kwargs)
            except MocapvizError as exc:
                counts.typed += 1
                counts.typed_with_line += getattr(exc, "line", None) is not None
                if not any(p.name in str(exc) for p in named):
                    counts.unnamed.append(f"{what}: {type(exc).__name__}: {exc}")
            except _Hang:
                counts.hangs.append(f"{what}: still running after {HANG_S} s")
            except Exception as exc:  # noqa: BLE001 - an untyped error is what the fuzzer looks for
                tb = traceback.extract_tb(exc.__traceback__)[-1]
                counts.crashes.append(f"{what}: {type(exc).__name__}: {exc} at {tb.filename}:{tb.lineno}")
            else:
                returned = sum(a.nbytes for a in (m.positions, m.quaternions, m.euler) if a is not None)
                problem = _check_motion(m)
                warned = any(issubclass(w.category, MocapFormatWarning) for w in seen)
                if problem:
                    counts.non_finite.append(f"{what}: loaded with {problem}")
                elif fmt == "garbage" and not warned:
                    counts.silent.append(f"{what}: loaded {m.n_frames} frames without a MocapFormatWarning")
                else:
                    counts.loaded += 1
                    counts.warned += warned
                del m
        numpy_warnings = [w for w in seen if issubclass(w.category, RuntimeWarning)]
        if numpy_warnings:
            counts.numpy_warnings.append(f"{what}: {numpy_warnings[0].message}")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    cpu = time.process_time() - c0
    peak = tracemalloc.get_traced_memory()[1] - base
    counts.max_cpu_s = max(counts.max_cpu_s, cpu)
    counts.max_peak_mb = max(counts.max_peak_mb, peak / 2**20)
    if cpu > CPU_BUDGET_S:
        counts.hangs.append(f"{what}: {cpu:.1f} CPU-s")
    if peak > MEMORY_FIXED + 4 * returned + 16 * len(data):
        counts.over_memory.append(f"{what}: peak {peak / 2**20:.1f} MB for {returned / 2**20:.1f} MB returned")
    for p in named:
        p.unlink()


def fuzz(fmt: str, sources: list, n_cases: int, seed: int, tmp: Path) -> Counts:
    """Run ``n_cases`` cases over ``sources`` (BVH paths, or (AMC, ASF) pairs); return the counts."""
    counts = Counts(fmt)
    tracing = tracemalloc.is_tracing()
    if not tracing:
        tracemalloc.start()
    try:
        for case in range(n_cases):
            run_case(case, fmt, sources, seed, tmp, counts)
    finally:
        if not tracing:
            tracemalloc.stop()
    return counts


# ------------------------------------------------------------------------------------------------------ sources
def bvh_sources(files: list[Path], n: int = 6) -> list[Path]:
    """The ``n`` smallest BVH files (a case costs about its size)."""
    return sorted(files, key=lambda p: (p.stat().st_size, p.name))[:n]


def amc_sources(hdm05: Path, cmu: Path, n: int = 4) -> list[tuple[Path, Path]]:
    """The ``n`` smallest AMC clips of HDM05 and of CMU, each with its ASF."""
    out = []
    for amcs in (list((hdm05 / "amc").glob("*.amc")), list((cmu / "amc").rglob("*.amc"))):
        for amc in sorted(amcs, key=lambda p: (p.stat().st_size, p.name))[:n]:
            out.append((amc, find_asf(amc)))
    return out


def _report(counts: Counts) -> None:
    print(counts.summary())
    for f in counts.failures[:20]:
        print("  FAIL", f)
    assert not counts.failures, f"{len(counts.failures)} failing cases, e.g. {counts.failures[:3]}"
    if counts.fmt == "garbage":  # refused naming the line, or (an AMC cut inside its last frame) loaded with a warning
        assert counts.typed + counts.warned == counts.cases and counts.typed > counts.cases * 3 // 4, counts.summary()
        assert counts.typed_with_line == counts.typed, counts.summary()
    else:
        assert counts.typed > counts.cases // 4 and counts.loaded > counts.cases // 20, counts.summary()


# ------------------------------------------------------------------------------------------------------ tests
def test_mutations_damage_and_are_reproducible():
    """Each mutation changes a real-looking text, and a seed gives the same damage again."""
    text = b"HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n}\nMOTION\nFrames: 2\nFrame Time: 0.033\n1 2 3\n4 5 6\n"
    for fn in MUTATIONS:
        changed = [fn(text, np.random.default_rng([7, i]))[0] != text for i in range(20)]
        assert sum(changed) >= 15, fn.__name__
        assert fn(text, np.random.default_rng(3)) == fn(text, np.random.default_rng(3))


def test_fuzz_bvh(bandai1_files, tmp_path):
    _report(fuzz("bvh", bvh_sources(bandai1_files), FAST_CASES, 20261125, tmp_path))


def test_fuzz_asf_amc(hdm05_dir, cmu_dir, tmp_path):
    _report(fuzz("asf/amc", amc_sources(hdm05_dir, cmu_dir), FAST_CASES, 20261125, tmp_path))


def test_garbage_mutations_damage_and_are_reproducible(hdm05_dir, cmu_dir):
    """Each garbage mutation changes a real ASF/AMC pair, and a seed gives the same damage again."""
    for amc, asf in amc_sources(hdm05_dir, cmu_dir, 1):
        pair = amc.read_bytes(), asf.read_bytes()
        for fn in GARBAGE:
            for i in range(5):
                assert fn(*pair, np.random.default_rng([7, i]))[:2] != pair, fn.__name__
                assert fn(*pair, np.random.default_rng(i)) == fn(*pair, np.random.default_rng(i)), fn.__name__


def test_fuzz_garbage(hdm05_dir, cmu_dir, tmp_path):
    _report(fuzz("garbage", amc_sources(hdm05_dir, cmu_dir), FAST_CASES, 20261125, tmp_path))


@pytest.mark.slow
def test_fuzz_bvh_slow(bandai1_files, tmp_path):
    _report(fuzz("bvh", bvh_sources(bandai1_files, 12), SLOW_CASES, 1, tmp_path))


@pytest.mark.slow
def test_fuzz_asf_amc_slow(hdm05_dir, cmu_dir, tmp_path):
    _report(fuzz("asf/amc", amc_sources(hdm05_dir, cmu_dir, 8), SLOW_CASES // 2, 1, tmp_path))


@pytest.mark.slow
def test_fuzz_garbage_slow(hdm05_dir, cmu_dir, tmp_path):
    _report(fuzz("garbage", amc_sources(hdm05_dir, cmu_dir, 8), SLOW_CASES // 2, 1, tmp_path))


if __name__ == "__main__":
    import os
    import tempfile

    parser = argparse.ArgumentParser(description="Fuzz the readers; print the counts.")
    parser.add_argument("--format", choices=("bvh", "amc", "garbage"), required=True)
    parser.add_argument("--cases", type=int, default=FAST_CASES)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--files", type=int, default=6, help="source files (the smallest ones)")
    args = parser.parse_args()
    os.environ.setdefault("MOCAPVIZ_HOME", str(Path(__file__).resolve().parent.parent / ".cache" / "mocapviz"))
    from mocapviz.io import datasets

    with tempfile.TemporaryDirectory() as tmp:
        if args.format == "bvh":
            files = sorted((Path(datasets.fetch("bandai-namco-1")) / "data").glob("*.bvh"))
            result = fuzz("bvh", bvh_sources(files, args.files), args.cases, args.seed, Path(tmp))
        else:
            srcs = amc_sources(Path(datasets.fetch("hdm05-cut")), Path(datasets.fetch("cmu-asfamc")), args.files)
            result = fuzz("asf/amc" if args.format == "amc" else "garbage", srcs, args.cases, args.seed, Path(tmp))
    print(result.summary())
    for f in result.failures:
        print("  FAIL", f)
    sys.exit(1 if result.failures else 0)
