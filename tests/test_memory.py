"""Memory of the read path of ingest, ``load`` → ``canonical`` → ``resample``, on generated large files: measured in
a fresh process (peak RSS, as ``python -m benchmarks.bench_io --large`` measures it) or, for a file the reader may
refuse, with tracemalloc as the fuzzer bounds each case (``tests/test_fuzz.py``)."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from benchmarks.bench_io import measure_pipeline, pipeline_memory, sample_clip, tiled_amc, warm_files
from mocapviz.errors import MocapFormatError
from mocapviz.io import load
from mocapviz.motion import motion as motion_module
from mocapviz.motion import rotations

ALLOWANCE = 64e6  # bytes: a process's fixed part (one block of temporaries, the allocator's free lists)


def test_ingest_read_path_of_200000_frames_needs_at_most_twice_the_largest_arrays(tmp_path):
    """A real clip tiled to 200,000 frames (160 MB of AMC text) read as ingest reads it, resampled down (30 fps) and
    up (240 fps): the peak RSS of load, canonical and resample, above the process's RSS before the load, is at most 2x
    the largest arrays one of the steps returns (the loaded clip's, or the clip resampled up), plus a fixed allowance.
    Before: the load peaked at 3.1x the arrays (the scanner's table of every line's start, for a few numbers such as
    3.1e-018 that it converts with float(); the file's bytes kept to the end; 4-byte line indices), resample took the
    slerp of the whole clip in float64 (2.3 GB at 240 fps)."""
    path = tiled_amc(*sample_clip(), tmp_path / "big", 200_000)
    r = measure_pipeline(path, (30.0, 240.0), warm_files(tmp_path))
    steps = {s["step"]: s for s in r["steps"]}
    assert [s["frames"] for s in r["steps"]] == [200_000, 200_000, 50_000, 399_999]
    assert steps["load"]["joints"] == 31 and steps["canonical"]["joints"] == 24
    for rate in (30.0, 240.0):
        m = pipeline_memory(r, rate)
        shown = ", ".join(f"{s['step']} {(s['peak'] - r['base']) / 1e6:.0f} MB" for s in m["steps"])
        print(f"{rate:g} fps: {shown}; largest arrays {m['largest'] / 1e6:.0f} MB")
        assert m["peak"] <= 2 * m["largest"] + ALLOWANCE, shown


def test_a_million_frame_numbers_without_bone_lines_are_refused_within_a_bound(tmp_path):
    """An AMC of 1M frame numbers and no bone line (7 MB, as ``big.tar.xz``'s M2) on a real skeleton is refused at its
    first frame; the memory traced until then (tracemalloc, as the fuzzer measures a case) is at most the fuzzer's
    bound for a refused file (32 MB + 16x the input) plus 4 bytes per frame and joint: the line table (1 byte a cell)
    and the completeness check's three boolean tables. No Python object per frame. (4-byte line indices and the file's
    bytes kept to the end: 288 MB, over the bound.)"""
    amc, asf = sample_clip()
    path = tmp_path / "bare.amc"
    path.write_text(":FULLY-SPECIFIED\n:DEGREES\n" + "".join(f"{k}\n" for k in range(1, 1_000_001)))
    (tmp_path / "bare.asf").write_bytes(asf.read_bytes())
    load(amc)  # compiled kernels loaded, skeleton parsed: not part of the bound
    tracing = tracemalloc.is_tracing()
    if not tracing:
        tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        with pytest.raises(MocapFormatError, match="frame 1 has no bone lines"):
            load(path)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        if not tracing:
            tracemalloc.stop()
    size = path.stat().st_size + asf.stat().st_size
    bound = 32 * 2**20 + 16 * size + 4 * 1_000_000 * 31
    print(f"peak traced {peak / 1e6:.0f} MB until refused, bound {bound / 1e6:.0f} MB")
    assert peak <= bound


@pytest.mark.parametrize("rate", [30.0, 97.3, 240.0])
def test_resample_by_blocks_gives_what_the_whole_clip_gives(rate):
    """Resampling a block of output frames at a time: the same float32 values as interpolating every frame at once
    (positions linearly, quaternions by slerp in float64, Euler angles the shorter way round), at every block edge."""
    m = load(sample_clip()[0]).canonical()
    m = m[np.arange(m.n_frames * 200) % m.n_frames]  # more than two blocks at any of the rates
    r = m.resample(rate)
    x = np.arange(r.n_frames) * (m.fps / rate)
    i0 = np.minimum(np.floor(x + 1e-9).astype(np.int64), m.n_frames - 1)
    i1 = np.minimum(i0 + 1, m.n_frames - 1)
    w = np.clip(x - i0, 0.0, 1.0)
    pos = m.positions[i0] + (m.positions[i1] - m.positions[i0]) * w[:, None, None].astype(np.float32)
    quat = rotations.slerp(m.quaternions[i0], m.quaternions[i1], w[:, None]).astype(np.float32)
    turn = np.remainder(m.euler[i1] - m.euler[i0] + 180.0, 360.0) - 180.0
    euler = m.euler[i0] + turn * w[:, None].astype(np.float32)
    assert r.n_frames > 2 * motion_module._RESAMPLE_BLOCK // m.n_joints
    np.testing.assert_array_equal(r.positions, pos)
    np.testing.assert_array_equal(r.quaternions, quat)
    np.testing.assert_array_equal(r.euler, euler)
