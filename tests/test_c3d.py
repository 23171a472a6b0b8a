"""The C3D reader (mocapviz.io.c3d) on the twelve real files of the ``c3d-markers`` archive: frames, rates, first
frames and gaps against the archive's MANIFEST.md (figures its author measured with ezc3d and the py c3d package),
markers, units and up axis against a human body, and damaged files refused by name."""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest

from mocapviz.errors import MocapFormatError, ParameterError
from mocapviz.io import load
from mocapviz.io.c3d import read_c3d
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
