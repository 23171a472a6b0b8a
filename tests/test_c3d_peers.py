"""C3D files other systems wrote (the ``peer-readers`` archive: pyomeca/ezc3d-testFiles, GPL test data, read here
only): each one loads, with the frames, rate, first frame and values its MANIFEST.md and ezc3d's own tests state,
or is refused saying what it holds instead of markers; marker mapping files (``marker_mapping``): their format, a
random relabelling of a real Plug-in Gait file read back through the inverse mapping file gives the same joints
(hypothesis), a lab's Davis-protocol labels mapped onto lower-body Plug-in Gait; ``mocapviz c3d markers`` and
``mocapviz ingest --marker-mapping``."""

from __future__ import annotations

import csv
import re
import shutil
import struct
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import MotionDB
from mocapviz.cli import main
from mocapviz.errors import MocapFormatError, MocapFormatWarning, ParameterError
from mocapviz.io import load, read_marker_mapping, relabel

# Davis protocol labels (BTS SMART, FP_Type1.c3d) -> Plug-in Gait: the wands are the 'bar' markers (10 cm lateral of
# thigh and shank, between the joints), 'knee 1' the lateral epicondyle, 'mall' the lateral malleolus, 'met' the
# fifth metatarsal head (positions of FP_Type1's frame medians)
DAVIS = {"sacrum": "SACR", "r asis": "RASI", "l asis": "LASI", "r bar 1": "RTHI", "l bar 1": "LTHI",
         "r knee 1": "RKNE", "l knee 1": "LKNE", "r bar 2": "RTIB", "l bar 2": "LTIB", "r mall": "RANK",
         "l mall": "LANK", "r met": "RTOE", "l met": "LTOE", "r heel": "RHEE", "l heel": "LHEE", "c7": "C7",
         "r should": "RSHO", "l should": "LSHO"}  # fmt: skip


def _quiet_load(path, **options):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        motion = load(path, **options)
    return motion, [str(w.message) for w in seen if w.category is MocapFormatWarning]


def _parameters(data: bytes) -> dict:
    """{(GROUP, NAME): byte offset of its data type} of an Intel C3D file's parameter section (walked here, not by
    the reader under test)."""
    at, groups, entries = (data[0] - 1) * 512 + 4, {}, {}
    while data[at]:
        chars, group = struct.unpack_from("bb", data, at)
        name = data[at + 2 : at + 2 + abs(chars)].decode("latin-1").upper()
        link = at + 2 + abs(chars)
        step = struct.unpack_from("<h", data, link)[0]
        if group < 0:
            groups[-group] = name
        else:
            entries[(group, name)] = link + 2
        if step == 0:
            break
        at = link + step
    return {(groups[g], name): offset for (g, name), offset in entries.items()}


def _dec_float(raw: bytes) -> float:
    """A DEC F-floating number: the IEEE single of the 16-bit halves swapped, divided by 4."""
    return struct.unpack("<f", raw[2:4] + raw[0:2])[0] / 4


# --------------------------------------------------------------------------------------------------- each peer file
LOADS = {  # file: (markers, frames, fps, first frame) as MANIFEST.md states them
    "BTS.c3d": (22, 675, 100.0, 1),
    "FP_Type1.c3d": (22, 634, 100.0, 1),
    "FP_Type3.c3d": (34, 2, 250.0, 1166),
    "Optotrak.c3d": (54, 29, 30.0, 1),
    "Vicon.c3d": (51, 580, 100.0, 1),
    "read_NOTworking2.c3d": (23, 670, 25.0, 0),
}


@pytest.mark.parametrize("name", sorted(LOADS))
def test_each_peer_file_loads_with_its_manifest_frames_rate_and_first_frame(peer_readers_dir, name):
    m, notes = _quiet_load(peer_readers_dir / "c3d" / name)
    assert (m.n_joints, m.n_frames, m.fps, m.labels["first_frame"]) == LOADS[name]
    seen = m.positions[~np.isnan(m.positions)]
    assert len(seen) and np.abs(seen).max() < 1e4, "centimetres within a lab"
    if name == "Optotrak.c3d":  # header and POINT:FRAMES 1,149; the data section holds 29 frames (25,056 bytes)
        assert notes == [(f"{peer_readers_dir / 'c3d' / name}: the header says 1149 frames but the file holds 29 "
                          "(its data ends after frame 29, at byte 28640): read the 29 frames it holds")]  # fmt: skip
    else:
        assert notes == []


def test_vicon_frame_0_point_0_as_ezc3d_asserts(peer_readers_dir):
    """ezc3d's test_ezc3d.cpp (readViconC3D): frame 0, point 0, x = 44.16278839111328 mm; the file's X_SCREEN is +X,
    so it stays x, in cm; the subject prefix is cut."""
    m, _ = _quiet_load(peer_readers_dir / "c3d" / "Vicon.c3d")
    assert m.positions[0, 0, 0] == pytest.approx(4.416278839111328, rel=1e-6)
    assert m.joint_names[:2] == ("gauche_ext", "gauche_int") and "ASISr" in m.joint_names


def test_units_in_metres_read_as_centimetres(peer_readers_dir):
    """FP_Type1's POINT:UNITS is m: frame 0 of 'sacrum' is its float32 coordinates in the data block, × 100 (X_SCREEN
    +X, Y_SCREEN +Y: no turn); the body stands about 1.5 m tall."""
    path = peer_readers_dir / "c3d" / "FP_Type1.c3d"
    data = path.read_bytes()
    block = struct.unpack_from("<H", data, 16)[0]
    raw = np.array(struct.unpack_from("<3f", data, (block - 1) * 512))
    m, _ = _quiet_load(path)
    np.testing.assert_allclose(m.positions[0, m.joint_names.index("sacrum")], raw * 100, rtol=1e-6)
    height = np.nanmedian(np.nanmax(m.positions[:, :, 1], axis=1) - np.nanmin(m.positions[:, :, 1], axis=1))
    assert 130 < height < 160


def test_dec_integer_file_frame_0(peer_readers_dir):
    """read_NOTworking2 (DEC processor, integer data, first frame 0): frame 0 of LFHD is its 16-bit integers times
    POINT:SCALE (a DEC float, decoded here), mm -> cm, turned from z up (Y_SCREEN +Z) to y up: (x, z, -y)."""
    path = peer_readers_dir / "c3d" / "read_NOTworking2.c3d"
    data = path.read_bytes()
    assert data[(data[0] - 1) * 512 + 3] == 85, "a DEC file"
    at = _parameters(data)[("POINT", "SCALE")]
    scale = _dec_float(data[at + 2 : at + 6])  # type 4, 0 dimensions, the value
    block = struct.unpack_from("<H", data, 16)[0]
    x, y, z = np.array(struct.unpack_from("<3h", data, (block - 1) * 512)) * scale / 10
    m, _ = _quiet_load(path)
    assert m.joint_names[0] == "LFHD"
    np.testing.assert_allclose(m.positions[0, 0], [x, z, -y], rtol=1e-5)


@pytest.mark.parametrize("name, reason", [
    ("Kistler.c3d", (r"analog data only: no marker trajectories \(0 points, no POINT group; ANALOG:USED 16 "
                     r"channels at 600 Hz")),
    ("C3DRotationExample.c3d", (r"rotations only: no marker trajectories \(0 points, POINT:USED 0; ROTATION:USED "
                                r"21 segment rotations at 85 Hz")),
])  # fmt: skip
def test_files_without_markers_are_refused_saying_what_they_hold(peer_readers_dir, name, reason):
    path = peer_readers_dir / "c3d" / name
    with pytest.raises(MocapFormatError, match=f"^{re.escape(str(path))}: {reason}"):
        load(path)


def test_the_marker_sets_of_the_peer_files(peer_readers_dir, capsys):
    """What `mocapviz c3d markers` says of each: none is a set without a mapping (Davis-protocol labels, CAST
    clusters, an upper-limb model, numbered markers, a Plug-in Gait upper body without legs)."""
    lacks = {"BTS.c3d": "cmu", "FP_Type1.c3d": "cmu", "FP_Type3.c3d": "cmu", "Optotrak.c3d": "cmu",
             "Vicon.c3d": "cmu", "read_NOTworking2.c3d": "plug-in gait"}  # fmt: skip
    for name, closest in lacks.items():
        assert main(["c3d", "markers", str(peer_readers_dir / "c3d" / name)]) == 0
        out = capsys.readouterr().out
        assert out.splitlines()[-1].startswith(f"set: none: closest {closest}, which lacks "), name
    assert "LTHI, LKNE, LANK" in out  # read_NOTworking2: markers of the upper body only


# ------------------------------------------------------------------------------------------------------ mapping files
@pytest.fixture
def davis_file(tmp_path):
    path = tmp_path / "davis.csv"
    with open(path, "w", newline="") as fh:
        fh.write("# Davis protocol (BTS SMART) -> Plug-in Gait\nlabel,marker\n")
        csv.writer(fh).writerows(DAVIS.items())
    return path


def test_a_davis_protocol_file_maps_onto_lower_body_plug_in_gait(peer_readers_dir, davis_file):
    """FP_Type1 through the mapping file: lower-body Plug-in Gait (C7 and the shoulders seen, no arm marker), every
    frame on the canonical joints; thighs and shanks of a body about 1.5 m tall."""
    m, _ = _quiet_load(peer_readers_dir / "c3d" / "FP_Type1.c3d", marker_mapping=davis_file)
    assert m.joint_names[:3] == ("SACR", "RASI", "r thigh")
    with pytest.warns(MocapFormatWarning, match=r"no arm marker seen \(a lower-body Plug-in Gait clip; C7, LSHO, "
                                                r"RSHO not used\)"):  # fmt: skip
        c = m.canonical()
    assert c.n_frames == 634 and np.isfinite(c.positions).all()
    j = {n: c.positions[:, k] for k, n in enumerate(c.joint_names)}
    for side in "lr":
        thigh = np.median(np.linalg.norm(j[side + "hip"] - j[side + "knee"], axis=1))
        shank = np.median(np.linalg.norm(j[side + "knee"] - j[side + "ankle"], axis=1))
        assert 33 < thigh < 45 and 33 < shank < 45, (side, thigh, shank)
    assert m.joint_names == load(peer_readers_dir / "c3d" / "FP_Type1.c3d", marker_mapping=DAVIS).joint_names


@pytest.mark.parametrize("text, reason, line", [
    ("r asis,RASI\nsacrum\n", r"expected 'label,marker' \(two non-empty cells\), got 'sacrum'", 2),
    ("r asis,RASI\nr asis,LASI\n", r"label 'r asis' listed twice \('RASI' and 'LASI'\)", 2),
    ("# c\n\nr asis,RASI\nl asis,RASI\n", r"labels 'r asis' and 'l asis' both mapped onto 'RASI'", 4),
    ("r asis,RASI,x\n", r"expected 'label,marker'", 1),
])  # fmt: skip
def test_a_bad_mapping_file_is_refused_naming_its_line(tmp_path, text, reason, line):
    path = tmp_path / "m.csv"
    path.write_text(text)
    with pytest.raises(MocapFormatError, match=reason) as err:
        read_marker_mapping(path)
    assert err.value.line == line and err.value.path == str(path)


def test_the_header_line_is_skipped_once(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("Label , Marker\nlabel,marker\n")
    assert read_marker_mapping(path) == {"label": "marker"}


def test_a_mapping_that_names_two_markers_alike_is_refused():
    with pytest.raises(ParameterError, match=r"names two markers of x.c3d 'LASI': 'l asis' and 'LASI'"):
        relabel(("l asis", "LASI"), {"l asis": "LASI"}, "x.c3d")


PIG = "btk_PiG_Motion-FlatFoot-Full.c3d"
_LETTERS = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 _-,."


@pytest.fixture(scope="module")
def pig(c3d_dir):
    """A real full-body Plug-in Gait file: its bytes, where its labels are, its markers and their joints."""
    data = (c3d_dir / PIG).read_bytes()
    at = _parameters(data)[("POINT", "LABELS")]
    assert struct.unpack_from("bB", data, at) == (-1, 2)  # characters, 2 dimensions
    width, count = data[at + 2], data[at + 3]
    labels = [data[at + 4 + k * width : at + 4 + (k + 1) * width].decode("latin-1").strip() for k in range(count)]
    motion, _ = _quiet_load(c3d_dir / PIG)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MocapFormatWarning)
        joints = motion.canonical()
    return data, at + 4, width, labels, motion, joints


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_a_relabelled_file_read_through_the_inverse_mapping_gives_the_same_joints(pig, tmp_path_factory, data):
    """The markers of a real Plug-in Gait file given random labels in the file itself (POINT:LABELS rewritten), read
    back with the mapping file of new label -> old name: the same marker names, positions and canonical joints."""
    raw, at, width, labels, motion, joints = pig
    markers = [k for k, label in enumerate(labels) if label in motion.joint_names]
    taken = {label.upper() for label in labels}
    new = data.draw(st.lists(st.text(_LETTERS, min_size=1, max_size=width).filter(
        lambda s: s == s.strip() and s.upper() not in taken), min_size=len(markers), max_size=len(markers),
        unique_by=str.upper))  # fmt: skip
    edited = bytearray(raw)
    for k, label in zip(markers, new):
        edited[at + k * width : at + (k + 1) * width] = label.ljust(width).encode("latin-1")
    folder = tmp_path_factory.mktemp("relabelled")
    (folder / PIG).write_bytes(bytes(edited))
    with open(folder / "inverse.csv", "w", newline="") as fh:
        csv.writer(fh).writerows((label, labels[k]) for k, label in zip(markers, new))
    plain, _ = _quiet_load(folder / PIG)
    assert set(new) <= set(plain.joint_names)
    m, _ = _quiet_load(folder / PIG, marker_mapping=folder / "inverse.csv")
    assert m.joint_names == motion.joint_names
    np.testing.assert_array_equal(m.positions, motion.positions)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MocapFormatWarning)
        np.testing.assert_array_equal(m.canonical().positions, joints.positions)


# ------------------------------------------------------------------------------------------------------------- fronts
def test_c3d_markers_prints_labels_gaps_and_the_set(peer_readers_dir, c3d_dir, davis_file, capsys):
    path = peer_readers_dir / "c3d" / "FP_Type1.c3d"
    assert main(["c3d", "markers", str(path), "--mapping", str(davis_file)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"{path}: 22 markers, 634 frames at 100 fps, first frame 1"
    assert lines[1].split() == ["label", "marker", "gaps", "%"]
    assert lines[3].split() == ["r", "asis", "RASI", "0.0"] and lines[4].split() == ["r", "thigh", "r", "thigh", "0.0"]
    assert lines[-1] == "set: plug-in gait, lower body, no head markers"
    assert main(["c3d", "markers", str(c3d_dir / "cmu_07_12.c3d")]) == 0
    out = capsys.readouterr().out
    gaps = {row.split()[0]: float(row.split()[1]) for row in out.splitlines()[2:-1]}
    assert out.splitlines()[-1] == "set: cmu, full body, with head markers" and 0 < gaps["RBHD"] < 100
    assert main(["c3d", "markers", str(c3d_dir / "btk_Gait.c3d")]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "set: plug-in gait, full body, no head markers"


def test_c3d_markers_refuses_a_file_without_markers(peer_readers_dir, capsys):
    assert main(["c3d", "markers", str(peer_readers_dir / "c3d" / "Kistler.c3d")]) == 1
    assert "analog data only: no marker trajectories" in capsys.readouterr().err


def test_ingest_with_a_marker_mapping(peer_readers_dir, davis_file, tmp_path, capsys):
    """`mocapviz ingest --marker-mapping`: FP_Type1 stored on the canonical joints, all 634 frames; without the
    mapping it is skipped as no known set; a bad mapping file is one error before any file is read."""
    folder = tmp_path / "in"
    folder.mkdir()
    shutil.copy(peer_readers_dir / "c3d" / "FP_Type1.c3d", folder)
    assert main(["ingest", str(folder), "--out", str(tmp_path / "db"), "--marker-mapping", str(davis_file),
                 "--no-cluster", "--quiet"]) == 0  # fmt: skip
    db = MotionDB.open(tmp_path / "db")
    assert len(db) == 1 and db.documents["n_frames"].tolist() == [634]
    assert main(["ingest", str(folder), "--out", str(tmp_path / "db2"), "--no-cluster", "--quiet"]) == 1
    assert "the cmu marker set lacks" in capsys.readouterr().err
    (tmp_path / "bad.csv").write_text("r asis\n")
    assert main(["ingest", str(folder), "--out", str(tmp_path / "db3"), "--marker-mapping", str(tmp_path / "bad.csv"),
                 "--no-cluster", "--quiet"]) == 1  # fmt: skip
    assert re.search(r"--marker-mapping: .*bad.csv, line 1: expected 'label,marker'", capsys.readouterr().err)
