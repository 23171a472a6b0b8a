"""The C3D reader (mocapviz.io.c3d) on the twelve real files of the ``c3d-markers`` archive: frames, rates, first
frames and gaps against the archive's MANIFEST.md (figures its author measured with ezc3d and the py c3d package),
markers, units and up axis against a human body, and damaged files refused by name: the round3 reproducers and
each check of mocapviz.io.c3d_layout against a real file with a field changed (naming the field and both values),
what is certain loaded as the original; ezc3d read in a helper process (mocapviz.io.isolated): a crash inside it
a typed error on any thread, in an ingest and on Dask workers, its positions those read in this process."""

from __future__ import annotations

import re
import shutil
import struct
import sys
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from test_fuzz_c3d import c3d_fields

from mocapviz import MotionDB
from mocapviz.errors import MocapFormatError, MocapFormatWarning, ParameterError
from mocapviz.io import c3d as c3d_module
from mocapviz.io import load
from mocapviz.io.c3d import read_c3d
from mocapviz.io.c3d_layout import Layout, check_layout
from mocapviz.io.isolated import read_isolated
from mocapviz.motion.markers import MARKER_SETS, marker_gaps


def _manifest(c3d_dir) -> dict[str, dict]:
    """The Summary table of the archive's MANIFEST.md: file -> set, markers, Hz, frames, first, gaps %."""
    rows = {}
    for line in (c3d_dir / "MANIFEST.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 10 and cells[0].endswith(".c3d"):
            rows[cells[0]] = {"set": cells[1], "markers": int(cells[2]), "hz": float(cells[3]),
                              "frames": int(cells[4]), "first": int(cells[5]), "gaps": float(cells[8])}  # fmt: skip
    return rows


@pytest.fixture(scope="module")
def manifest(c3d_dir):
    rows = _manifest(c3d_dir)
    assert len(rows) == 12, "the manifest's summary table lists the twelve files"
    return rows


@pytest.fixture(scope="module")
def motions(c3d_dir, manifest):
    return {name: load(c3d_dir / name) for name in manifest}


def test_every_file_loads_with_the_manifest_frames_rate_and_first_frame(motions, manifest):
    for name, row in manifest.items():
        m = motions[name]
        assert (m.n_frames, m.fps, m.labels["first_frame"]) == (row["frames"], row["hz"], row["first"]), name
        seen = m.positions[~np.isnan(m.positions)]
        assert np.isfinite(seen).all() and m.positions.dtype == np.float32, name


def test_cmu_and_hdm05_markers_prefix_cut_unlabelled_points_dropped(motions, manifest):
    """The manifest counts POINT:USED: the 41 (or 42, with an extra RBAC-1 / RWRB-1) markers; HDM05's three
    unlabelled points ``*0 *1 *2`` are dropped; cmu_16_07's 330 points are all labelled."""
    for name, row in manifest.items():
        if row["set"] not in ("CMU", "HDM05"):
            continue
        m = motions[name]
        assert m.n_joints == row["markers"] - (3 if row["set"] == "HDM05" else 0), name
        assert set(MARKER_SETS["cmu"]) <= set(m.joint_names), name
        assert not any(":" in n or n.startswith("*") for n in m.joint_names), name
        assert (m.parents == -1).all() and m.quaternions is None


def test_plug_in_gait_model_outputs_dropped(motions):
    """btk_PiG_Motion-FlatFoot-Full lists its angles, forces, moments and powers in POINT:ANGLES ...: they are no
    markers (an angle in degrees read as a position would be a point metres away)."""
    m = motions["btk_PiG_Motion-FlatFoot-Full.c3d"]
    assert "LASI" in m.joint_names and not any(n.endswith(("Angles", "Force", "Moment", "Power")) for n in m.joint_names)


def test_gap_share_as_in_the_manifest(motions, manifest):
    """cmu_01_01 (42 markers, all kept) and btk_Gait (33 points, no model outputs): the manifest's gaps % is the
    share of samples ezc3d reads as invalid."""
    for name in ("cmu_01_01.c3d", "btk_Gait.c3d"):
        share = 100 * marker_gaps(motions[name]).mean()
        assert share == pytest.approx(manifest[name]["gaps"], abs=0.1), name
    assert (marker_gaps(motions["cmu_135_02.c3d"]) == 0).all()


def test_centimetres_and_y_up(motions, manifest):
    """Every CMU/HDM05 take: head markers above the ankle markers by a human's 130 to 200 cm when standing, feet
    near the floor, whether the file states its axes (POINT:X_SCREEN/Y_SCREEN) or not (cmu_135_02, HDM05)."""
    for name, row in manifest.items():
        if row["set"] not in ("CMU", "HDM05"):
            continue
        m = motions[name]
        height = np.nanpercentile(m.joint("LFHD")[:, 1] - m.joint("LANK")[:, 1], 90)  # standing (85_12 breakdances)
        ankle = np.nanmedian(m.joint("LANK")[:, 1])
        assert 130 < height < 200 and -10 < ankle < 25, (name, height, ankle)
        across = np.nanmedian(m.joint("LSHO") - m.joint("RSHO"), axis=0)
        front = np.nanmedian(m.joint("STRN") - m.joint("T10"), axis=0)
        assert np.cross(front, across)[1] > 0, f"{name}: forward x left must point up (right-handed, not mirrored)"


def test_up_overrides(c3d_dir):
    z = read_c3d(c3d_dir / "cmu_07_01.c3d", up="z")
    auto = read_c3d(c3d_dir / "cmu_07_01.c3d")
    np.testing.assert_array_equal(z.positions, auto.positions)
    y = read_c3d(c3d_dir / "cmu_07_01.c3d", up="y")
    assert np.nanmedian(y.joint("LFHD")[:, 2] - y.joint("LANK")[:, 2]) > 130  # taken as y up: the file keeps z up
    with pytest.raises(ParameterError, match="up must be"):
        read_c3d(c3d_dir / "cmu_07_01.c3d", up="x")


@pytest.mark.parametrize("damage", ["text", "empty", "truncated", "key", "processor"])
def test_damaged_files_refused_naming_the_file(c3d_dir, tmp_path, damage):
    src = (c3d_dir / "cmu_07_12.c3d").read_bytes()
    data = {
        "text": b"HIERARCHY\nROOT Hips\n",
        "empty": b"",
        "truncated": src[: len(src) // 2],
        "key": src[:1] + b"\x00" + src[2:],
        "processor": src[:512 * (src[0] - 1) + 3] + b"\x07" + src[512 * (src[0] - 1) + 4:],
    }[damage]
    path = tmp_path / f"{damage}.c3d"
    path.write_bytes(data)
    with pytest.raises(MocapFormatError, match=re.escape(str(path))):
        load(path)


def test_missing_file(tmp_path):
    with pytest.raises(MocapFormatError, match="no such file"):
        load(tmp_path / "none.c3d")


def test_extension_case_and_file_name_do_not_matter(c3d_dir, tmp_path):
    """A copy under another name, ``.C3D``, reads the same (the reader keys nothing on the file name)."""
    copy = tmp_path / "renamed.C3D"
    shutil.copy(c3d_dir / "cmu_07_01.c3d", copy)
    m = load(copy)
    assert m.joint_names == load(c3d_dir / "cmu_07_01.c3d").joint_names and "LFIN" in m.joint_names


# ------------------------------------------------------------------------------------------------------ damaged layouts
# round3/c3d: a real c3d-markers file with one field changed each; ezc3d segfaulted on the first, loaded the others
# scrambled without a word (../shared/reliability/round3.tar.xz, README)
ROUND3 = {
    "analog_used_1_cmu_07_12.c3d": r"ANALOG:USED 1 channels × 5 samples per frame \(header word 10\) = 5, but the "
                                   r"header says 0 analog samples per frame \(word 3\)",
    "point_used_43.c3d": r"POINT:USED 43 but the header says 42 points",
    "point_used_1.c3d": r"POINT:USED 1 but the header says 42 points",
    "point_frames_1.c3d": r"POINT:FRAMES 1 but the header says 263 frames \(first frame 202, last 464\)",
    "analog_rate.c3d": r"ANALOG:RATE 10001 Hz is 83.3417 samples per frame at 120 fps but the header says 9 "
                       r"\(word 10\)",
    "data_block_early.c3d": r"the header's data block 15 but POINT:DATA_START 16",
    "header_scale_positive.c3d": r"the header's scale inf is no scale factor \(finite, not 0\); POINT:SCALE is -0.1",
    "point_scale_nan.c3d": r"POINT:SCALE nan is no scale factor \(finite, not 0\); the header's scale is -0.1",
    "first_after_last.c3d": r"the header's first frame 65535 is after its last frame 550",
}  # fmt: skip


def test_round3_reproducers_refused_naming_the_field_and_both_values(round3):
    folder = round3 / "c3d"
    assert sorted(p.name for p in folder.glob("*.c3d")) == sorted(ROUND3), "a reproducer without its expected error"
    for name, reason in ROUND3.items():
        with pytest.raises(MocapFormatError, match=f"^{re.escape(str(folder / name))}: {reason}$"):
            load(folder / name)


def _edited(source: Path, edits: dict) -> bytes:
    """The bytes of ``source`` with fields (labels of tests/test_fuzz_c3d.Field) set; a callable value gets the old."""
    data = source.read_bytes()
    data = data[: len(data) - edits.get("_cut", 0)]  # "_cut": bytes cut off the end
    for label, value in ((k, v) for k, v in edits.items() if k != "_cut"):
        (f,) = [f for f in c3d_fields(data) if f.label == label]
        data = f.write(data, value(f.read(data)) if callable(value) else value)
    return data


REFUSED = [
    ("cmu_07_12.c3d", {"POINT:USED": 41}, r"POINT:USED 41 but the header says 42 points"),
    ("cmu_07_12.c3d", {"header word 2 (points)": 43}, r"POINT:USED 42 but the header says 43 points"),
    ("cmu_07_12.c3d", {"POINT:USED": 0, "header word 2 (points)": 0}, r"POINT:USED 0 and the header says 0 points"),
    ("cmu_07_12.c3d", {"POINT:FRAMES": 262}, r"POINT:FRAMES 262 but the header says 263 frames \(first frame 202"),
    ("cmu_07_12.c3d", {"header word 5 (last frame)": 400}, r"POINT:FRAMES 263 but the header says 199 frames"),
    ("cmu_07_12.c3d", {"header word 4 (first frame)": 465}, r"the header's first frame 465 is after its last "
                                                            r"frame 464"),
    ("cmu_07_12.c3d", {"POINT:RATE": 60.0}, r"POINT:RATE 60 fps but the header says 120 fps"),
    ("cmu_07_12.c3d", {"POINT:RATE": np.nan}, r"POINT:RATE nan fps and the header's 120 fps: nan frames per second"),
    ("cmu_07_12.c3d", {"POINT:RATE": 0.0, "header word 11-12 (frame rate)": 1e6},
     r"POINT:RATE 0 fps and the header's 1e\+06 fps: 0 frames per second is outside"),
    ("cmu_07_12.c3d", {"POINT:SCALE": 0.0}, r"POINT:SCALE 0 is no scale factor \(finite, not 0\); the header's "
                                            r"scale is -0.1"),
    ("cmu_07_12.c3d", {"POINT:SCALE": -np.inf}, r"POINT:SCALE -inf is no scale factor"),
    ("cmu_07_12.c3d", {"header word 7-8 (scale)": 0.1},
     r"POINT:SCALE -0.1 but the header's scale is 0.1: one says float data, the other integers \(sign\)"),
    ("btk_Gait.c3d", {"POINT:SCALE": lambda v: 2 * v},
     r"POINT:SCALE 0.148815 but the header's scale is 0.0744075 \(integer data: it scales every coordinate\)"),
    ("cmu_07_12.c3d", {"ANALOG:USED": 2}, r"ANALOG:USED 2 channels × 5 samples per frame \(header word 10\) = 10, but "
                                          r"the header says 0 analog samples per frame"),
    ("cmu_07_12.c3d", {"header word 3 (analog samples per frame)": 5}, r"ANALOG:USED 0 channels × 5 .* = 0, but the "
                                                                       r"header says 5"),
    ("btk_FunctionalWalk.c3d", {"ANALOG:RATE": 1200.0},
     r"ANALOG:RATE 1200 Hz is 10 samples per frame at 120 fps but the header says 9"),
    ("btk_FunctionalWalk.c3d", {"ANALOG:RATE": 1079.9}, r"ANALOG:RATE 1079.9 Hz is 8.99917 samples per frame"),
    ("btk_FunctionalWalk.c3d", {"header word 10 (analog samples per channel)": 8},
     r"ANALOG:USED 36 channels × 8 samples per frame \(header word 10\) = 288, but the header says 324"),
    ("btk_FunctionalWalk.c3d", {"ANALOG:USED": 37, "header word 3 (analog samples per frame)": 333},
     r"ANALOG:USED 37 channels but 36 ANALOG:SCALE and 36 ANALOG:OFFSET values"),
    ("cmu_07_12.c3d", {"ANALOG:RATE": 1e9}, r"ANALOG:RATE 1e\+09 Hz is 8.33333e\+06 analog samples per frame at 120 "
                                            r"fps: more than the file holds"),
    ("cmu_07_12.c3d", {"ANALOG:RATE": -600.0}, r"ANALOG:RATE -600 Hz is -5 analog samples per frame"),
    ("cmu_07_12.c3d", {"POINT:DATA_START": 17}, r"the header's data block 16 but POINT:DATA_START 17"),
    ("cmu_07_12.c3d", {"POINT:DATA_START": 3, "header word 9 (data block)": 3},
     r"the header's data block 3 \(byte 1024\) starts inside the parameter section \(it ends at byte \d+\)"),
    ("cmu_07_12.c3d", {"POINT:FRAMES": 300, "header word 5 (last frame)": 501, "_cut": 100},
     r"truncated or damaged: 300 frames of 42 points from block 16 need 209280 bytes, the file has 184316"),
]  # fmt: skip


@pytest.mark.parametrize("source, edits, reason", REFUSED, ids=[", ".join(e) for _, e, _ in REFUSED])
def test_header_and_parameters_that_disagree_are_refused_naming_both(c3d_dir, tmp_path, source, edits, reason):
    path = tmp_path / f"edited_{source}"
    path.write_bytes(_edited(c3d_dir / source, edits))
    with pytest.raises(MocapFormatError, match=f"^{re.escape(str(path))}: {reason}"):
        load(path)


LOADED = [
    ("cmu_07_12.c3d", {"header word 11-12 (frame rate)": 0.0},
     "the header's frame rate 0 fps is no frame rate; read at POINT:RATE 120 fps"),
    ("btk_FunctionalWalk.c3d", {"POINT:RATE": 0.0}, "POINT:RATE 0 fps; read at the header's 120 fps"),
    ("cmu_07_12.c3d", {"POINT:FRAMES": 0}, None),  # 0: not stated (Kistler writes it so; ezc3d reads it so)
    ("btk_Gait.c3d", {"POINT:SCALE": lambda v: -v, "header word 7-8 (scale)": lambda v: -v}, None),  # DEC floats
    ("cmu_07_12.c3d", {"POINT:SCALE": -0.5}, None),  # float data: the scale's size scales nothing that is read
    ("btk_FunctionalWalk.c3d", {"header word 7-8 (scale)": -3.0}, None),
    ("cmu_07_12.c3d", {"ANALOG:RATE": 0.0}, None),  # no analog channels: their rate is not used
    ("btk_FunctionalWalk.c3d", {"ANALOG:GEN_SCALE": np.nan, "ANALOG:SCALE[0]": 0.0, "ANALOG:OFFSET[3]": 7}, None),
    ("cmu_07_12.c3d", {"header word 6 (interpolation gap)": 65535, "POINT:MOVIE_DELAY": np.inf}, None),
    ("cmu_07_12.c3d", {"POINT:FRAMES": 300, "header word 5 (last frame)": 501},  # stopped early, at a whole frame
     "the header says 300 frames but the file holds 263 (its data ends after frame 263, at byte 184416): read the "
     "263 frames it holds"),
    ("cmu_07_12.c3d", {"POINT:DATA_START": 0}, None),  # 0: not stated (ezc3d reads the header's data block)
]  # fmt: skip


@pytest.mark.parametrize("source, edits, note", LOADED, ids=[", ".join(e) for _, e, _ in LOADED])
def test_what_is_certain_loads_as_the_original_with_a_note(c3d_dir, motions, tmp_path, source, edits, note):
    """A frame rate of 0 in one copy (the other one used, with a MocapFormatWarning); values no marker is read by
    (POINT:FRAMES 0, a float file's scale size, the analog gains, offsets and rate of a marker file): the same
    Motion as the original, without a warning."""
    path = tmp_path / f"edited_{source}"
    path.write_bytes(_edited(c3d_dir / source, edits))
    if source == "btk_Gait.c3d":  # its points are integers: negated scales make them floats, and they read as such
        with pytest.raises(MocapFormatError, match=re.escape(str(path))):
            load(path)
        return
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        m = load(path)
    assert [str(w.message) for w in seen if w.category is MocapFormatWarning] == ([f"{path}: {note}"] if note else [])
    original = motions[source]
    np.testing.assert_array_equal(m.positions, original.positions)
    assert (m.fps, m.labels, m.joint_names) == (original.fps, original.labels, original.joint_names)


def _frames_entry(data: bytes, value: bytes, kind: int) -> bytes:
    """``data`` with POINT:FRAMES re-stored as ``value`` of data type ``kind`` (the parameter section keeps its size:
    the bytes gained or lost come from its zero padding before the data block)."""
    f = {f.label: f for f in c3d_fields(data)}["POINT:FRAMES"]
    at, link = f.offset, f.offset - 4  # int16 value; before it: the link (int16), the type, 0 dimensions
    assert data[at - 2 : at] == bytes([2, 0])
    grow = len(value) - 2
    end = (int.from_bytes(data[16:18], "little") - 1) * 512
    assert data[end - grow : end] == bytes(grow)
    step = int.from_bytes(data[link : link + 2], "little", signed=True) + grow
    entry = step.to_bytes(2, "little", signed=True) + bytes([kind, 0]) + value
    return data[:link] + entry + data[at + 2 : end - grow] + data[end:]


def test_frames_stored_as_a_float_or_absent_or_beyond_the_header(c3d_dir, motions, tmp_path):
    """Writers of files beyond 65,535 frames store the header's last frame as 65,535 and the count in POINT:FRAMES,
    some as a float: POINT:FRAMES above the header's count where its last frame is 65,535 is the count; a float
    that is no whole number is refused, a whole one passes the checks and ezc3d 1.7 refuses it (typed, naming the
    file: a limit of ezc3d, none of the c3d-markers files has one); a file without POINT:FRAMES reads by the
    header."""
    source = c3d_dir / "cmu_07_12.c3d"
    data = source.read_bytes()
    cases = {
        "float": _frames_entry(data, struct.pack("<f", 263.0), 4),
        "absent": data.replace(b"FRAMES", b"FRAMEZ", 1),
        "long": _edited(source, {"header word 4 (first frame)": 65300, "header word 5 (last frame)": 65535}),
        "fraction": _frames_entry(data, struct.pack("<f", 263.5), 4),
    }
    for name, edited in cases.items():
        path = tmp_path / f"{name}.c3d"
        path.write_bytes(edited)
        refused = {"fraction": r"POINT:FRAMES 263.5 is not a number of frames$",
                   "float": r"the C3D reader \(ezc3d\) raised ValueError: FRAMES parameter is not an INT$"}
        if name in refused:
            with pytest.raises(MocapFormatError, match=f"^{re.escape(str(path))}: {refused[name]}"):
                load(path)
            continue
        m = load(path)
        np.testing.assert_array_equal(m.positions, motions["cmu_07_12.c3d"].positions)
        assert m.labels["first_frame"] == (65300 if name == "long" else 202), name


def test_real_files_pass_the_checks_without_a_note(c3d_dir, manifest):
    for name in manifest:
        layout = check_layout(str(c3d_dir / name))
        assert layout == Layout((), manifest[name]["first"]), name


# ------------------------------------------------------------------------------------------------------ isolation
def test_reading_in_a_helper_changes_nothing(c3d_dir, manifest, motions, monkeypatch):
    """Every real file: the Motion read by ezc3d in its helper process equals the one read in this process."""
    monkeypatch.setattr(c3d_module, "read_isolated", lambda function, path, *args, **how: function(path, *args))
    for name in manifest:
        m = load(c3d_dir / name)
        np.testing.assert_array_equal(m.positions, motions[name].positions)
        assert (m.fps, m.labels, m.joint_names) == (motions[name].fps, motions[name].labels, motions[name].joint_names)


@pytest.fixture
def crashing(round3, monkeypatch) -> Path:
    """The reproducer ezc3d segfaults on, with the checks that refuse it switched off (in this process)."""
    monkeypatch.setattr(c3d_module, "check_layout", lambda path: Layout((), 1))
    return round3 / "c3d" / "analog_used_1_cmu_07_12.c3d"


def test_a_crash_inside_ezc3d_is_a_typed_error_and_reading_goes_on(crashing, c3d_dir, motions):
    """ANALOG:USED 1 where the header has no analog samples: ezc3d indexes an empty ANALOG:SCALE and segfaults in
    its helper; this process gets a MocapFormatError naming the file and the signal, on any thread, and reads on."""
    crashed = f"^{re.escape(str(crashing))}: the C3D reader \\(ezc3d\\) crashed on this file \\(signal 11, SIGSEGV\\)$"
    with pytest.raises(MocapFormatError, match=crashed):
        load(crashing)
    good = [c3d_dir / "cmu_07_01.c3d", c3d_dir / "btk_Gait.c3d"]
    with ThreadPoolExecutor(4) as pool:
        futures = [pool.submit(load, p) for p in (crashing, good[0], crashing, good[1])]
    for f in futures[::2]:
        with pytest.raises(MocapFormatError, match=crashed):
            f.result()
    for f, p in zip(futures[1::2], good):
        np.testing.assert_array_equal(f.result().positions, motions[p.name].positions)


def test_a_reader_over_its_time_or_memory_is_refused_and_reading_goes_on(c3d_dir, motions):
    path = str(c3d_dir / "cmu_135_02.c3d")
    how = {"reader": "the C3D reader (ezc3d)", "preload": ("ezc3d",)}
    with pytest.raises(MocapFormatError, match=r"the C3D reader \(ezc3d\) did not finish within 0.001 s$"):
        read_isolated(c3d_module._ezc3d_points, path, memory=2**30, timeout=1e-3, **how)
    with pytest.raises(MocapFormatError, match=r"the C3D reader \(ezc3d\) needed more than its 1 MiB \(RuntimeError: "
                                               r"std::bad_alloc\)$"):  # fmt: skip
        read_isolated(c3d_module._ezc3d_points, path, memory=2**20, timeout=60.0, **how)
    np.testing.assert_array_equal(load(path).positions, motions["cmu_135_02.c3d"].positions)


def test_ingest_skips_a_file_that_crashes_ezc3d(crashing, c3d_dir, tmp_path):
    """``ingest --skip-bad --no-cluster`` (reader threads in this process) skips the file that crashes ezc3d with a
    warning naming it and stores the others; without ``--skip-bad`` the ingest stops with the typed error."""
    folder = tmp_path / "in"
    folder.mkdir()
    for p in (crashing, c3d_dir / "cmu_07_01.c3d", c3d_dir / "cmu_85_02.c3d"):
        shutil.copy(p, folder / p.name)
    with pytest.warns(UserWarning, match=r"skipped .*analog_used_1_cmu_07_12.c3d: the C3D reader \(ezc3d\) crashed"):
        db = MotionDB.ingest(folder, tmp_path / "db", skip_bad=True, threads=2, progress=False)
    assert len(db) == 2
    with pytest.raises(MocapFormatError, match=r"analog_used_1_cmu_07_12.c3d: the C3D reader \(ezc3d\) crashed"):
        MotionDB.ingest(folder, tmp_path / "db2", threads=2, progress=False)


def _without_checks() -> bool:
    """On a Dask worker: switch the C3D checks off there (what the ``crashing`` fixture does in this process)."""
    c3d_module.check_layout = lambda path: Layout((), 1)
    return True


def test_ingest_on_a_cluster_reports_a_crash_as_a_typed_error(crashing, c3d_dir, tmp_path):
    """On Dask workers (daemonic processes) ezc3d's crash is the same typed error, not a KilledWorker."""
    import cloudpickle
    from distributed import Client, LocalCluster

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    folder = tmp_path / "in"
    folder.mkdir()
    for p in (crashing, c3d_dir / "cmu_07_01.c3d", c3d_dir / "cmu_85_02.c3d"):
        shutil.copy(p, folder / p.name)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            Client(cluster) as client:  # fmt: skip
        assert all(client.run(_without_checks).values())
        with pytest.warns(UserWarning, match=r"skipped .*analog_used_1_cmu_07_12.c3d: the C3D reader \(ezc3d\) crash"):
            db = MotionDB.ingest(folder, tmp_path / "db", skip_bad=True, scheduler=client, progress=False)
        assert len(db) == 2
        with pytest.raises(MocapFormatError, match=r"analog_used_1_cmu_07_12.c3d: the C3D reader \(ezc3d\) crashed"):
            MotionDB.ingest(folder, tmp_path / "db2", scheduler=client, progress=False)
