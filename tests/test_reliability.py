"""Regression tests: each malformed or pathological file of ``../shared/reliability`` (and of its ``big.tar.xz``) gives
its expected outcome — a typed error naming the file, the line and the value, or a correct load — in bounded time and
memory; ``ingest --skip-bad`` skips every unreadable one. Also the readers' guards that need no file (resample of an
absurd frame rate, the ASF bone order)."""

from __future__ import annotations

import json
import subprocess
import sys
import tarfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapviz.errors import MocapFormatError, ParameterError
from mocapviz.io import load
from mocapviz.motion import Motion

REPO = Path(__file__).resolve().parent.parent
RELIABILITY = REPO.parent / "shared" / "reliability"


@pytest.fixture(scope="module")
def reliability() -> Path:
    if not (RELIABILITY / "README.md").is_file():
        pytest.skip(f"needs the regression files of {RELIABILITY} (../shared/reliability beside the checkout)")
    return RELIABILITY


@pytest.fixture(scope="module")
def big(reliability, tmp_path_factory) -> Path:
    """The members of big.tar.xz, unpacked (the tarfile ``data`` filter refuses links and paths out of the folder)."""
    out = tmp_path_factory.mktemp("big")
    with tarfile.open(reliability / "big.tar.xz") as tar:
        tar.extractall(out, filter="data")
    return out


def _line_of(path: Path, needle: bytes) -> int:
    """1-based number of the only line of ``path`` holding ``needle``."""
    lines = [i for i, s in enumerate(path.read_bytes().split(b"\n"), start=1) if needle in s]
    assert len(lines) == 1, (path.name, needle, lines)
    return lines[0]


def _error(path: Path, **kw) -> MocapFormatError:
    with pytest.raises(MocapFormatError) as info:
        load(path, **kw)
    err = info.value
    assert err.path == str(path) and path.name in str(err)
    return err


# -------------------------------------------------------------------------------- the small files, one by one
def _uppercase_motion(data: bytes) -> bytes:
    return data.replace(b"\nMotion\n", b"\nMOTION\n")


def _no_vertical_tab(data: bytes) -> bytes:
    return data.replace(b"\n\vMOTION", b"\nMOTION")


def _no_bom_no_bad_byte(data: bytes) -> bytes:
    return data.removeprefix(b"\xef\xbb\xbf").replace(b"Hips\xff", b"Hips")


@pytest.mark.parametrize("name, repair, root", [
    ("C1_lowercase_motion.bvh", _uppercase_motion, "Hips"),
    ("C1b_vtab_motion.bvh", _no_vertical_tab, "Hips"),
    ("C2_bom_invalid_utf8.bvh", _no_bom_no_bad_byte, "Hips\xff"),  # not UTF-8: read as Latin-1
])  # fmt: skip
def test_keyword_case_white_space_and_encoding_load_as_the_repaired_file(reliability, tmp_path, name, repair, root):
    """``motion``, a vertical tab before MOTION and a BOM before invalid UTF-8 load as their repaired files do."""
    raw = (reliability / name).read_bytes()
    fixed = tmp_path / "fixed.bvh"
    fixed.write_bytes(repair(raw))
    assert fixed.read_bytes() != raw
    m, ref = load(reliability / name), load(fixed)
    assert m.joint_names == (root, "Spine", "Spine_end") and ref.joint_names[1:] == m.joint_names[1:]
    for a, b in ((m.positions, ref.positions), (m.quaternions, ref.quaternions), (m.euler, ref.euler)):
        np.testing.assert_array_equal(a, b)
    assert m.fps == ref.fps == 30.0
    # by hand: the root at (0, 90, 0) (its channels), no rotation, offsets of 10 cm up
    np.testing.assert_array_equal(m.positions, np.tile([[0.0, 90.0, 0.0], [0.0, 100.0, 0.0], [0.0, 110.0, 0.0]], (2, 1, 1)))


@pytest.mark.parametrize("name, shown", [("C3_bandai_frametime_1e308.bvh", "1e+308"),
                                         ("C3b_bandai_frametime_1e-300.bvh", "1e-300")])
def test_absurd_frame_time_is_refused_at_its_line(reliability, name, shown):
    path = reliability / name
    err = _error(path)
    assert err.line == _line_of(path, b"Frame Time")
    assert f"Frame Time {shown} s" in err.reason and "outside 1 to 10,000 frames per second" in err.reason


def test_channel_beyond_float32_is_refused_at_its_line(reliability):
    path = reliability / "C4_bandai_channel_1e39.bvh"
    err = _error(path)
    assert err.line == _line_of(path, b"1e39")
    assert "1e+39" in err.reason and "joint_Root Xposition" in err.reason


def test_amc_root_translation_beyond_limits_is_refused_at_its_line(reliability):
    path = reliability / "C5_root_tx_1e39.amc"
    err = _error(path)  # its ASF found beside it
    assert err.line == _line_of(path, b"1e39")
    assert "1e+39" in err.reason and "root" in err.reason


def test_every_small_file_has_an_expected_outcome(reliability):
    """A new file in the folder needs a test here."""
    covered = {"C1_lowercase_motion.bvh", "C1b_vtab_motion.bvh", "C2_bom_invalid_utf8.bvh",
               "C3_bandai_frametime_1e308.bvh", "C3b_bandai_frametime_1e-300.bvh", "C4_bandai_channel_1e39.bvh",
               "C5_root_tx_1e39.amc", "C5_root_tx_1e39.asf", "README.md", "big.tar.xz",
               "round3.tar.xz"}  # fmt: skip  (round3: the `round3` fixture of conftest.py, tests of each reader)
    assert {p.name for p in reliability.iterdir()} == covered


def test_ingest_skip_bad_skips_every_unreadable_file(reliability, bandai1_files, tmp_path):
    """``ingest --skip-bad --fps 30``: each file of the folder is skipped with a warning naming it (C1, C1b and C2
    load but their toy rig has no humanoid mapping); a good file beside them is stored, finite."""
    from mocapviz import MotionDB

    bad = sorted(p for p in reliability.iterdir() if p.suffix in (".bvh", ".amc"))
    good = bandai1_files[0]
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        db = MotionDB.ingest(bad + [good], tmp_path / "db", fps=30, skip_bad=True, threads=1, progress=False)
    skipped = [str(w.message) for w in seen if str(w.message).startswith("skipped")]
    assert len(skipped) == len(bad)
    for p in bad:
        assert sum(p.name in s for s in skipped) == 1, (p.name, skipped)
    assert len(db) == 1 and db.fps == 30.0
    assert np.isfinite(db.motion(0).positions).all()


# -------------------------------------------------------------------------------- guards that need no file
@pytest.mark.parametrize("clip_fps, target", [(1e-308, 30.0), (30.0, 1e308), (30.0, 0.5), (1e6, 30.0)])
def test_resample_refuses_absurd_frame_rates(clip_fps, target):
    """The OverflowError of ``resample(30)`` on a 1e-308 fps clip is a ParameterError naming the range."""
    m = Motion(positions=np.zeros((3, 1, 3)), fps=clip_fps, joint_names=("a",), parents=[-1], source="clip.bvh")
    with pytest.raises(ParameterError, match="outside 1 to 10,000 frames per second"):
        m.resample(target)


def _repeated_passes(names: list[str], parent: dict[str, str]) -> list[int]:
    """The ASF reader's bone order as it was first written: passes over the bones in file order, each placing those
    whose parent is placed (quadratic; the reference)."""
    order, placed, pending = [], {"root"}, list(range(len(names)))
    while pending:
        waiting = []
        for i in pending:
            if parent[names[i]] in placed:
                placed.add(names[i])
                order.append(i)
            else:
                waiting.append(i)
        pending = waiting
    return order


def test_asf_bone_order_is_the_repeated_pass_order():
    """The linear bone order equals the repeated-pass one on random trees listed in random order."""
    from mocapviz.io.asfamc import _topological_order

    rng = np.random.default_rng(18)
    for n in (1, 2, 5, 30, 200):
        for _ in range(20):
            parent_of = [-1] + [int(rng.integers(-1, k)) for k in range(1, n)]  # bone k's parent: root or an earlier
            names = [f"b{k}" for k in range(n)]
            shuffle = rng.permutation(n)  # file order
            listed = [names[k] for k in shuffle]
            parent = {names[k]: "root" if parent_of[k] < 0 else names[parent_of[k]] for k in range(n)}
            order, parents = _topological_order(listed, parent, "x.asf", {})
            assert order == _repeated_passes(listed, parent)
            placed = [listed[i] for i in order]
            assert [parent[b] for b in placed] == ["root" if p < 0 else placed[p] for p in parents]


# -------------------------------------------------------------------------------- big.tar.xz (slow)
def _tolerance(parents: np.ndarray, reach: float) -> np.ndarray:
    """Per joint, cm: 1e-3 plus what the forward kinematics' float32 sines and cosines (about 1e-7 rad per joint,
    :func:`mocapviz.motion.rotations.forward_kinematics`) may add up to along a chain of d joints: 1e-7 d^2 reach / 2,
    ``reach`` the longest bone. Negligible for a body (d < 10); centimetres at d = 10,000."""
    depth = np.zeros(len(parents))
    for j, p in enumerate(parents):
        depth[j] = 0 if p < 0 else depth[p] + 1
    return 1e-3 + 1e-7 * depth**2 * reach / 2


def _measure(path: Path, *args: str) -> dict:
    """Load ``path`` in a fresh process: wall and CPU seconds, the arrays returned (bytes), the process's peak RSS
    before (imports and kernels loaded on a small file) and after the load (bytes)."""
    code = f"""
import json, resource, sys, time
from mocapviz.io import load
load({str(RELIABILITY / 'C1_lowercase_motion.bvh')!r})
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
t, c = time.perf_counter(), time.process_time()
m = load(sys.argv[1])
out = dict(wall=time.perf_counter() - t, cpu=time.process_time() - c, frames=m.n_frames, joints=m.n_joints,
           returned=sum(a.nbytes for a in (m.positions, m.quaternions, m.euler) if a is not None),
           base=base, peak=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
print(json.dumps(out))
"""
    done = subprocess.run([sys.executable, "-c", code, str(path), *args], capture_output=True, text=True,
                          timeout=600, cwd=REPO, check=False)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def m2_without_dofs(big, tmp_path_factory) -> Path:
    """M2 on its skeleton without DOFs, where its frames of frame numbers only are complete (``without_dofs``)."""
    from benchmarks.bench_io import without_dofs

    return without_dofs(big / "M2_amc_1M_markers_7MB.amc", tmp_path_factory.mktemp("m2"))


@pytest.mark.slow
def test_a_million_frames_without_bone_lines_are_refused_at_the_first(big):
    """M2's 1M frames are frame numbers only: on its skeleton (bones with DOFs) that is no motion, refused at the
    first frame (it loaded as 1M rest poses)."""
    path = big / "M2_amc_1M_markers_7MB.amc"
    err = _error(path)
    assert err.line == 3 and err.reason == "frame 1 has no bone lines"


@pytest.mark.slow
@pytest.mark.parametrize("name, frames, joints", [("M1_bvh_1M_frames_2MB.bvh", 1_000_000, 27),
                                                  ("M2_amc_1M_markers_7MB.amc", 1_000_000, 31)])
def test_million_frame_files_load_within_four_times_their_arrays(big, m2_without_dofs, name, frames, joints):
    """Peak memory of the load (above the process's own) at most 4x the arrays it returns (was 3.3 and 3.9 GB)."""
    r = _measure(m2_without_dofs if name.startswith("M2_") else big / name)
    print(f"{name}: {r['wall']:.1f} s, {r['cpu']:.1f} CPU-s, returned {r['returned'] / 1e6:.0f} MB, peak RSS "
          f"{r['peak'] / 1e6:.0f} MB (process before: {r['base'] / 1e6:.0f} MB)")
    assert (r["frames"], r["joints"]) == (frames, joints)
    assert r["peak"] - r["base"] <= 4 * r["returned"]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["H1_wide20000.bvh", "H1b_deep20000.bvh"])
def test_20000_joint_rigs_load_as_a_reference_computes(big, name):
    """Every joint's position equals a plain scipy forward kinematics (R = Rz Rx Ry per joint, channels 1.5)."""
    from test_io import _bvh_reference_fk, _parse_bvh

    m = load(big / name)
    joints, values = _parse_bvh(big / name)
    assert m.n_joints == len(joints) > 20_000 and m.n_frames == len(values) == 2
    ref = _bvh_reference_fk(joints, values[1])
    expected = np.array([ref[n] for n in m.joint_names])
    error = np.abs(m.positions[1] - expected).max(axis=1)
    assert (error <= _tolerance(m.parents, 1.0)).all(), error.max()


@pytest.mark.slow
def test_10000_bone_chain_listed_backwards_loads_as_a_reference_computes(big):
    """Each bone b_k (k = 0..9999, parent b_(k-1)) turns by the same M = Rz(30) Ry(20) Rx(10) (XYZ, x first), so
    its tip is the previous tip plus M^(k+1) (0, L, 0), L = 1 / 0.45 inch."""
    m = load(big / "H2_chain10000_rev.amc")
    assert m.n_joints == 10_001 and m.n_frames == 3
    step = Rotation.from_euler("xyz", [10, 20, 30], degrees=True)
    g, tip = Rotation.identity(), np.zeros(3)
    bone = np.array([0.0, 1.0 / 0.45 * 2.54, 0.0])
    expected = {"root": tip}
    for k in range(10_000):
        g = g * step
        tip = tip + g.apply(bone)
        expected[f"b{k}"] = tip
    ref = np.array([expected[n] for n in m.joint_names])
    error = np.abs(m.positions[2] - ref).max(axis=1)
    assert (error <= _tolerance(m.parents, bone[1])).all(), error.max()
    assert error[: 100].max() < 1e-3  # the first hundred bones: exactly as the reference


@pytest.mark.slow
@pytest.mark.parametrize("rate, frames", [(30.0, 1_000_000), (120.0, 3_999_997)])
def test_million_frame_bvh_is_ingested_within_twice_its_largest_arrays(big, tmp_path, rate, frames):
    """M1 read as ingest reads it at ``rate`` (load, canonical, resample: the clip is at 30 fps) in a fresh process:
    peak RSS at most 2x the largest arrays one of the steps returns plus 64 MB (at 120 fps it was 20.8 GB, 7.6x: the
    slerp of 4M frames in float64; at 30 fps 2.0x: canonical copied the quaternions twice)."""
    from benchmarks.bench_io import measure_pipeline, pipeline_memory, warm_files

    r = measure_pipeline(big / "M1_bvh_1M_frames_2MB.bvh", (rate,), warm_files(tmp_path))
    m = pipeline_memory(r, rate)
    print(", ".join(f"{s['step']} {(s['peak'] - r['base']) / 1e6:.0f} MB" for s in m["steps"]))
    assert [s["frames"] for s in m["steps"]] == [1_000_000, 1_000_000, frames]
    assert m["peak"] <= 2 * m["largest"] + 64e6
