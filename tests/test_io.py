"""Readers (mocapviz.io) on the real archives: frame counts, forward kinematics checked against an independent
implementation, units, encodings, malformed input reported at the right line, up axis and resampling."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapviz.errors import MocapFormatError, MocapFormatWarning
from mocapviz.io import find_asf, load, read_asf
from mocapviz.io.bvh import FRAMES_SLACK, read_bvh
from mocapviz.io.text import scan

CM_PER_INCH = 2.54

# ---------------------------------------------------------------------------------------------- helpers


def _lines(path: Path) -> list[str]:
    """The file's lines split on '\\n' only (a '\\r' stays at the end of its line, as in the HDM05 files)."""
    return path.read_bytes().decode("latin-1").split("\n")


def _write(path: Path, lines: list[str]) -> Path:
    path.write_bytes("\n".join(lines).encode("latin-1"))
    return path


def _is_frame_number(line: str) -> bool:
    return re.fullmatch(r"\s*\d+\s*", line) is not None


def _amc_frames(path: Path) -> list[tuple[int, dict[str, list[float]]]]:
    """AMC frames read by plain Python: [(1-based line of the frame number, {bone: values})]."""
    frames = []
    for i, line in enumerate(_lines(path), start=1):
        tok = line.split()
        if not tok or tok[0].startswith(("#", ":")):
            continue
        if _is_frame_number(line):
            frames.append((i, {}))
        else:
            frames[-1][1][tok[0]] = [float(t) for t in tok[1:]]
    return frames


def _bvh_header_frames(path: Path) -> int:
    with open(path, encoding="latin-1") as fh:
        for line in fh:
            if line.startswith("Frames:"):
                return int(line.split()[1])
    raise AssertionError(f"{path}: no 'Frames:' line")


def _bone_lengths_constant(positions: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Per non-root joint, the standard deviation over time of its distance to its parent, cm."""
    p = positions.astype(np.float64)
    child = np.flatnonzero(parents >= 0)
    return np.linalg.norm(p[:, child] - p[:, parents[child]], axis=-1).std(axis=0)


def _hdm05_clip(labels, actor: str, cls: str, k: int = 0) -> str:
    rows = labels[(labels.actor == actor) & (labels["class"] == cls)].sort_values("file")
    return rows.file.iloc[k]


# ------------------------------------------------------------------------------------- frame counts


def test_hdm05_every_clip_loads_with_labelled_frame_count(hdm05_dir, hdm05_labels):
    assert len(hdm05_labels) == 287
    for row in hdm05_labels.itertuples():
        motion = load(hdm05_dir / row.file)
        assert motion.n_frames == row.frames, row.file
        assert motion.fps == 120.0 == row.fps
        assert motion.n_joints == 31
        assert motion.quaternions.shape == (row.frames, 31, 4)
        assert np.isfinite(motion.positions).all(), row.file


def test_hdm05_asf_found_by_actor(hdm05_dir, hdm05_labels):
    for row in hdm05_labels.drop_duplicates("actor").itertuples():
        assert find_asf(hdm05_dir / row.file) == (hdm05_dir / "asf" / f"HDM_{row.actor}.asf").resolve()


def test_bandai1_every_file_matches_its_frames_header(bandai1_files):
    assert len(bandai1_files) == 174
    for path in bandai1_files:
        motion = load(path)
        assert motion.n_frames == _bvh_header_frames(path), path.name
        assert motion.fps == 30.0
        assert np.isfinite(motion.positions).all(), path.name


@pytest.mark.slow
def test_bandai2_every_file_matches_its_frames_header(bandai2_dir):
    files = sorted((bandai2_dir / "data").glob("*.bvh"))
    assert len(files) == 2902
    for path in files:
        motion = load(path)
        assert motion.n_frames == _bvh_header_frames(path), path.name
        assert motion.fps == 30.0
        # in cm whatever the distance of the figure from joint_Root at the origin (up to 8 m here)
        hips = motion.joint("Hips")[0, 1]
        assert 60 < hips < 120, (path.name, hips)


def test_cmu_every_trial_loads(cmu_dir):
    import pandas as pd

    labels = pd.read_csv(cmu_dir / "labels.tsv", sep="\t", dtype=str)
    assert len(labels) == 32
    for row in labels.itertuples():
        path = cmu_dir / row.file
        assert find_asf(path) == (cmu_dir / row.asf).resolve()
        frames = _amc_frames(path)
        bones = set().union(*(f[1] for f in frames))
        complete = [f for f in frames if set(f[1]) == bones]
        if len(complete) < len(frames):
            # golf_01.amc ends inside its last frame: that frame is dropped with a warning
            assert len(complete) == len(frames) - 1 and set(frames[-1][1]) < bones, row.file
            with pytest.warns(MocapFormatWarning, match=rf"{row.file.split('/')[-1]}, line \d+: last frame \d+ is "
                                                        "incomplete"):
                motion = load(path)
        else:
            motion = load(path)
        assert motion.n_frames == len(complete), row.file
        assert motion.fps == 120.0
        assert np.isfinite(motion.positions).all(), row.file


def test_cmu_131_01_frame_count(cmu_dir):
    path = cmu_dir / "amc" / "mjackson" / "131_01.amc"
    numbers = [int(s) for s in _lines(path) if _is_frame_number(s)]
    assert numbers == list(range(1, len(numbers) + 1))
    motion = load(path)
    assert motion.n_frames == len(numbers) == 994
    assert motion.joint_names[0] == "root" and "lfemur" in motion.joint_names


def test_cmu_asf_with_namespace_line(cmu_dir):
    path = cmu_dir / "asf" / "mjackson.asf"
    assert any(s.startswith(":namespace") for s in _lines(path))
    skeleton = read_asf(path)
    assert len(skeleton.bone_names) == 30
    # the :units section after :namespace was still read
    assert skeleton.cm_per_unit == pytest.approx(CM_PER_INCH / 0.45)
    assert skeleton.degrees


def test_hdm05_latin1_header(hdm05_dir, hdm05_labels, tmp_path):
    def header(p):
        raw = p.read_bytes()
        return raw[: raw.index(b"\n1")]

    path = next(hdm05_dir / f for f in hdm05_labels.file if b"\xfc" in header(hdm05_dir / f))
    raw = path.read_bytes()
    motion = load(path)
    ascii_copy = tmp_path / path.name
    ascii_copy.write_bytes(raw.replace(b"\xfc", b"u"))
    plain = load(ascii_copy, asf=find_asf(path))
    assert motion.n_frames == plain.n_frames
    np.testing.assert_array_equal(motion.positions, plain.positions)


# ----------------------------------------------------------------------------------- FK sanity


def test_asf_bone_lengths_constant_and_as_in_skeleton(hdm05_dir, hdm05_labels, cmu_dir):
    paths = [hdm05_dir / _hdm05_clip(hdm05_labels, a, c) for a, c in
             [("bd", "kickLFront1Reps"), ("bk", "lieDownFloor"), ("dg", "rotateArmsBothBackward1Reps"),
              ("mm", "hopBothLegs1hops"), ("tr", "throwBasketball")]]  # fmt: skip
    paths.append(cmu_dir / "amc" / "mjackson" / "131_01.amc")
    for path in paths:
        motion = load(path)
        bones, _, _, length_unit = _parse_asf(find_asf(path))
        assert length_unit == 0.45
        assert np.all(_bone_lengths_constant(motion.positions, motion.parents) < 1e-3), path.name
        lengths = np.linalg.norm(motion.positions[:, 1:] - motion.positions[:, motion.parents[1:]], axis=-1)
        expected = [bones[name]["length"] * CM_PER_INCH / length_unit for name in motion.joint_names[1:]]
        np.testing.assert_allclose(lengths.mean(0), expected, atol=1e-3, err_msg=path.name)


def test_bvh_bone_lengths_constant(bandai1_files):
    for path in bandai1_files[::12]:
        motion = load(path)
        _, data = _parse_bvh(path)
        # every joint here has 6 channels, positions first; they replace the OFFSET. Hips carries the
        # body's translation (in some files joint_Root moves too); the others hold constant lengths.
        translation = data.reshape(len(data), -1, 6)[:, :, :3]
        fixed = np.ptp(translation, axis=0).max(axis=1) < 1e-4
        assert not fixed[1] and fixed[2:].all()
        lengths = np.linalg.norm(translation[0], axis=1)
        p = motion.positions.astype(np.float64)
        channel_joints = [j for j, n in enumerate(motion.joint_names) if not n.endswith("_end")]
        checked = 0
        for k, j in enumerate(channel_joints):
            if motion.parents[j] < 0 or not fixed[k]:
                continue
            d = np.linalg.norm(p[:, j] - p[:, motion.parents[j]], axis=-1)
            assert d.std() < 1e-3 and abs(d.mean() - lengths[k]) < 1e-3, (path.name, motion.joint_names[j])
            checked += 1
        assert checked == len(channel_joints) - 2
        hips = motion.joint_names.index("Hips")
        # the one moving "bone": its length follows the Hips position channels frame by frame
        d = np.linalg.norm(p[:, hips] - p[:, 0], axis=-1)
        np.testing.assert_allclose(d, np.linalg.norm(translation[:, 1], axis=1), atol=1e-3)


def test_trunk_upright_while_walking(hdm05_dir, hdm05_labels, cmu_dir, bandai1_dir):
    """A wrong rotation order or convention for the root tilts the trunk (by 50-180 degrees in these clips):
    check it stays within 50 degrees of vertical in every frame of walking, jogging and sneaking clips
    (the correct reader: at most 44 here), and that the feet reach the floor."""
    paths = [
        hdm05_dir / _hdm05_clip(hdm05_labels, a, "jogLeftCircle4StepsRstart") for a in ("bd", "bk", "dg", "mm", "tr")
    ]
    paths += [hdm05_dir / _hdm05_clip(hdm05_labels, a, "sneak2StepsLStart") for a in ("bd", "bk", "mm")]
    paths += [cmu_dir / "amc" / g for g in ("mjackson/131_01.amc", "walk/walk_03.amc", "moderndance/md_walk.amc")]
    paths += [bandai1_dir / "data" / f"dataset-1_walk_{s}_001.bvh" for s in ("active", "normal", "old")]
    for path in paths:
        c = load(path).canonical()
        trunk = c.joint("neck") - c.joint("root")
        tilt = np.degrees(np.arccos(trunk[:, 1] / np.linalg.norm(trunk, axis=1)))
        assert tilt.max() < 50, (path.name, tilt.max())
        feet = c.positions[:, [3, 4, 7, 8], 1]  # ankles and toes
        assert -10 < feet.min() < 10, (path.name, feet.min())


# ------------------------------------------------------------------ FK against an independent implementation


def _parse_asf(path: Path):
    bones, parent, section, bone, length_unit = {}, {}, None, None, None
    root = {}
    for line in _lines(path):
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        if tok[0].startswith(":"):
            section = tok[0][1:]
            continue
        if section == "units" and tok[0] == "length":
            length_unit = float(tok[1])
        elif section == "root":
            root[tok[0]] = tok[1:]
        elif section == "bonedata":
            if tok[0] == "begin":
                bone = {"dof": []}
            elif tok[0] == "end":
                bones[bone["name"]] = bone
            elif tok[0] == "name":
                bone["name"] = tok[1]
            elif tok[0] == "direction":
                bone["direction"] = np.array(tok[1:4], dtype=float)
            elif tok[0] == "length":
                bone["length"] = float(tok[1])
            elif tok[0] == "axis":
                bone["axis"], bone["axis_order"] = np.array(tok[1:4], dtype=float), tok[4]
            elif tok[0] == "dof":
                bone["dof"] = tok[1:]
        elif section == "hierarchy" and tok[0] not in ("begin", "end"):
            for child in tok[1:]:
                parent[child] = tok[0]
    return bones, parent, root, length_unit


def _asf_reference_fk(asf: Path, frame: dict[str, list[float]]) -> dict[str, np.ndarray]:
    """Tips of all bones, cm: G = G_parent C M C^-1, tip = parent tip + G (length * direction)."""
    bones, parent, root, length_unit = _parse_asf(asf)
    assert root["order"] == ["TX", "TY", "TZ", "RX", "RY", "RZ"] and root["axis"] == ["XYZ"]
    assert [float(v) for v in root["position"] + root["orientation"]] == [0.0] * 6
    cm = CM_PER_INCH / length_unit
    values = frame["root"]
    tips = {"root": np.array(values[:3]) * cm}
    rots = {"root": Rotation.from_euler("xyz", values[3:], degrees=True)}  # x first, about fixed axes
    pending = list(bones)
    while pending:
        name = pending.pop(0)
        if parent[name] not in tips:
            pending.append(name)
            continue
        b = bones[name]
        assert b["axis_order"] == "XYZ"
        angles = dict(zip(b["dof"], frame.get(name, [0.0] * len(b["dof"]))))
        motion = Rotation.from_euler("xyz", [angles.get(a, 0.0) for a in ("rx", "ry", "rz")], degrees=True)
        axis = Rotation.from_euler("xyz", b["axis"], degrees=True)
        rots[name] = rots[parent[name]] * axis * motion * axis.inv()
        offset = b["length"] * cm * b["direction"] / np.linalg.norm(b["direction"])
        tips[name] = tips[parent[name]] + rots[name].apply(offset)
    return tips


def test_asf_forward_kinematics_matches_reference(hdm05_dir, hdm05_labels, cmu_dir):
    for path in [hdm05_dir / _hdm05_clip(hdm05_labels, "dg", "kickLFront1Reps"),
                 cmu_dir / "amc" / "moderndance" / "md_02.amc"]:  # fmt: skip
        motion = load(path)
        frames = _amc_frames(path)
        assert len(frames) == motion.n_frames
        for f in (0, len(frames) // 3, len(frames) - 1):
            tips = _asf_reference_fk(find_asf(path), frames[f][1])
            assert set(tips) == set(motion.joint_names)
            for j, name in enumerate(motion.joint_names):
                np.testing.assert_allclose(motion.positions[f, j], tips[name], atol=1e-3, err_msg=f"{path.name} {name}")


def _parse_bvh(path: Path):
    """Joints (name, parent, offset, channels) in file order, and the frame values."""
    lines = _lines(path)
    joints, stack = [], []
    i = 0
    while not lines[i].startswith("MOTION"):
        tok = lines[i].split()
        if tok and tok[0] in ("ROOT", "JOINT"):
            joints.append({"name": tok[1], "parent": stack[-1] if stack else -1, "channels": []})
        elif tok and tok[0] == "End":
            joints.append({"name": joints[stack[-1]]["name"] + "_end", "parent": stack[-1], "channels": []})
        elif tok and tok[0] == "{":
            stack.append(len(joints) - 1)
        elif tok and tok[0] == "}":
            stack.pop()
        elif tok and tok[0] == "OFFSET":
            joints[stack[-1]]["offset"] = np.array(tok[1:4], dtype=float)
        elif tok and tok[0] == "CHANNELS":
            joints[stack[-1]]["channels"] = tok[2:]
        i += 1
    data = [[float(t) for t in s.split()] for s in lines[i + 3 :] if s.strip()]
    return joints, np.array(data)


def _bvh_reference_fk(joints, values: np.ndarray) -> dict[str, np.ndarray]:
    """R = R_c1 R_c2 R_c3 (channel order); position channels replace the offset; P = P_parent + G_parent t."""
    pos, rot = {}, {}
    col = 0
    for j, joint in enumerate(joints):
        t = joint["offset"].copy()
        r = Rotation.identity()
        for channel in joint["channels"]:
            axis = "XYZ".index(channel[0])
            if channel.endswith("position"):
                t[axis] = values[col]
            else:
                r = r * Rotation.from_euler(channel[0].lower(), values[col], degrees=True)
            col += 1
        p = joint["parent"]
        if p < 0:
            pos[j], rot[j] = t, r
        else:
            pos[j], rot[j] = pos[p] + rot[p].apply(t), rot[p] * r
    return {joints[j]["name"]: pos[j] for j in pos}


def test_bvh_forward_kinematics_matches_reference(bandai1_dir):
    for name in ("dataset-1_dash_childish_001.bvh", "dataset-1_kick_normal_001.bvh"):
        path = bandai1_dir / "data" / name
        motion = load(path)
        joints, data = _parse_bvh(path)
        assert len(data) == motion.n_frames
        for f in (0, len(data) // 2, len(data) - 1):
            ref = _bvh_reference_fk(joints, data[f])
            assert list(ref) == list(motion.joint_names)
            for j, joint in enumerate(motion.joint_names):
                np.testing.assert_allclose(motion.positions[f, j], ref[joint], atol=1e-3, err_msg=f"{name} {joint}")


# -------------------------------------------------------------------------------------------- units


def test_root_height_and_y_up(hdm05_dir, hdm05_labels, cmu_dir, bandai1_files):
    paths = [hdm05_dir / f for f in hdm05_labels[hdm05_labels["class"] == "grabHighR"].file]
    paths += sorted((cmu_dir / "amc" / "mjackson").glob("*.amc"))[:2] + [cmu_dir / "amc" / "walk" / "walk_03.amc"]
    paths += [p for p in bandai1_files if "_walk_" in p.name]
    for path in paths:
        c = load(path).canonical()
        first = c.positions[0]
        assert 70 < first[0, 1] < 110, (path.name, first[0, 1])  # root (hips) height in cm while standing
        y = c.positions[..., 1].mean(axis=0)
        assert y[c.joint_names.index("headtop")] > y[0] + 40 > y[c.joint_names.index("lankle")] + 40
        assert abs(first[0, 1] - first[:, 1].min()) > 70  # the vertical extent is along y, not x or z


def test_standing_head_height_per_hdm05_actor(hdm05_dir, hdm05_labels):
    actors = sorted(hdm05_labels.actor.unique())
    assert actors == ["bd", "bk", "dg", "mm", "tr"]
    for actor in actors:
        for cls in ("grabHighR", "depositFloorR"):
            c = load(hdm05_dir / _hdm05_clip(hdm05_labels, actor, cls)).canonical()
            head = c.joint("head")[0, 1]
            assert 140 < head < 200, (actor, cls, head)


# ----------------------------------------------------------------------------------- precision of the scanner


def test_scanner_matches_python_float(hdm05_dir, bandai1_dir):
    """Every number of a real AMC and a real BVH file converts to exactly Python's float, including tiny
    values like 3.10601e-018 (mantissa * 10.0**-23 computed by numba was one unit in the last place off)."""
    amc = hdm05_dir / "amc" / "HDM_mm_kickLFront1Reps_023_120.amc"
    bvh = bandai1_dir / "data" / "dataset-1_walk-back_normal_001.bvh"
    amc_first = next(i for i, s in enumerate(_lines(amc)) if _is_frame_number(s))
    bvh_first = next(i for i, s in enumerate(_lines(bvh)) if s.startswith("Frame Time")) + 1
    for path, first in ((amc, amc_first), (bvh, bvh_first)):
        body = "\n".join(_lines(path)[first:])
        assert re.search(r"\de-0?(1[89]|2\d)\b", body)
        sc = scan(body.encode("latin-1"), str(path), first + 1)
        expected = []
        for s in body.split("\n"):
            for t in s.split():
                try:
                    expected.append(float(t))
                except ValueError:
                    pass  # bone names
        expected = np.array(expected)
        assert sc.values.shape == expected.shape and expected.size > 3000
        assert np.array_equal(sc.values, expected), np.flatnonzero(sc.values != expected)[:5]
        assert len(set(np.round(np.abs(expected), 3))) > 1000  # many distinct numbers
        # the per-line layout: 22 joints x 6 channels per BVH frame line; AMC frame numbers and bone lines
        assert set(sc.n_values[sc.n_values > 0].tolist()) == ({132} if path.suffix == ".bvh" else {1, 2, 3, 6})


def test_scanner_number_forms():
    text = (
        "1 -2 +3.5 .25 -.5 1e3 1.5E-3 -2.5e+2 1.82882e-014 0.000001 123456789.123456\n"
        "7 8\n"
        "# a comment 1 2 3\n"
        "lfemur 3.10601e-018 -6.8554e-20 1e25 -1.5e-300 12345678901234567890 0.1234567890123456789\n"
        "\n"
        "x 9007199254740993 2.2250738585072014e-308 1e-400 4.9406564584124654e-324"
    )
    sc = scan(text.encode(), "x", first_line=5)
    numbers = []
    for s in text.split("\n"):
        tok = s.split()
        if tok and tok[0] != "#":
            numbers += [float(t) for t in tok if t[0] in "+-.0123456789"]
    assert sc.values.tolist() == numbers
    assert sc.n_values.tolist() == [11, 2, 0, 6, 0, 4]
    assert sc.token(3) == "lfemur" and sc.token(5) == "x" and sc.token(0) == ""
    assert sc.first_line == 5 and sc.n_lines == 6


# --------------------------------------------------------------------------------------------- bad input


def _raises(path: Path, line: int | None, **kw) -> MocapFormatError:
    with pytest.raises(MocapFormatError) as info:
        load(path, **kw)
    err = info.value
    assert isinstance(err, ValueError)
    assert err.line == line, (str(err), line)
    assert path.name in str(err) and err.reason in str(err)
    if line is not None:
        assert f"line {line}" in str(err)
    return err


@pytest.fixture
def amc_copy(hdm05_dir, hdm05_labels, tmp_path):
    """A short real HDM05 clip (its lines) and its ASF."""
    src = hdm05_dir / _hdm05_clip(hdm05_labels, "bk", "hopBothLegs1hops")
    return _lines(src), find_asf(src)


def _frame_line(lines: list[str], frame: int) -> int:
    """0-based index of the line holding frame number ``frame``."""
    return next(i for i, s in enumerate(lines) if _is_frame_number(s) and int(s) == frame)


def _bone_line(lines: list[str], frame: int, bone: str) -> int:
    """0-based index of bone ``bone``'s line in frame ``frame``."""
    i = _frame_line(lines, frame) + 1
    while lines[i].split()[0] != bone:
        i += 1
    return i


def test_amc_truncated_inside_a_bone_line(amc_copy, tmp_path):
    lines, asf = amc_copy
    last = max(int(s) for s in lines if _is_frame_number(s))
    k = _bone_line(lines, last, "lhumerus")
    cut = lines[:k] + [" ".join(lines[k].split()[:2])]  # 'lhumerus 12.3' and the file ends
    err = _raises(_write(tmp_path / "cut.amc", cut), k + 1, asf=asf)
    assert "lhumerus" in err.reason


def test_amc_nan(amc_copy, tmp_path):
    lines, asf = amc_copy
    k = _bone_line(lines, 10, "rtibia")
    lines[k] = "rtibia nan\r"
    err = _raises(_write(tmp_path / "nan.amc", lines), k + 1, asf=asf)
    assert "nan" in err.reason


def test_amc_unknown_bone(amc_copy, tmp_path):
    lines, asf = amc_copy
    k = _bone_line(lines, 20, "lfemur")
    lines[k] = lines[k].replace("lfemur", "lfemurX")
    err = _raises(_write(tmp_path / "bone.amc", lines), k + 1, asf=asf)
    assert "lfemurX" in err.reason


def test_amc_missing_value(amc_copy, tmp_path):
    lines, asf = amc_copy
    k = _bone_line(lines, 5, "lfemur")
    lines[k] = " ".join(lines[k].split()[:-1])
    err = _raises(_write(tmp_path / "short.amc", lines), k + 1, asf=asf)
    assert "lfemur" in err.reason


def test_amc_duplicated_bone_line(amc_copy, tmp_path):
    lines, asf = amc_copy
    k = _bone_line(lines, 3, "ltibia")
    lines.insert(k + 1, lines[k])
    err = _raises(_write(tmp_path / "dup.amc", lines), k + 2, asf=asf)
    assert "ltibia" in err.reason


def test_amc_frame_numbers_jump(amc_copy, tmp_path):
    lines, asf = amc_copy
    k = _frame_line(lines, 7)
    lines[k] = "8"
    err = _raises(_write(tmp_path / "jump.amc", lines), k + 1, asf=asf)
    assert "6" in err.reason and "8" in err.reason


def test_amc_bone_line_missing_from_one_frame(amc_copy, tmp_path):
    lines, asf = amc_copy
    k = _bone_line(lines, 12, "rhumerus")
    del lines[k]
    err = _raises(_write(tmp_path / "gap.amc", lines), _frame_line(lines, 12) + 1, asf=asf)
    assert "rhumerus" in err.reason and "12" in err.reason


@pytest.mark.parametrize("bone", ["root", "lfemur", "rtoes"])
def test_amc_bone_missing_from_every_frame(amc_copy, tmp_path, bone):
    """A bone with DOFs (or the root) deleted from every frame is refused at the first frame, not read as its rest
    pose (found by the mutation fuzzer: 70 such files loaded)."""
    lines, asf = amc_copy
    kept = [s for s in lines if s.split()[:1] != [bone]]
    err = _raises(_write(tmp_path / "no_bone.amc", kept), _frame_line(kept, 1) + 1, asf=asf)
    assert err.reason == f"no frame has a line for bone {bone!r} (the skeleton gives it values)"


def test_amc_bone_without_dofs_may_be_left_out(amc_copy, tmp_path):
    """A bone without DOFs has no values: real files never write it, and a file writing it in some frames only
    reads as the file without it."""
    lines, asf = amc_copy
    skeleton = read_asf(asf)
    no_dof = [n for n, d in zip(skeleton.bone_names, skeleton.dofs) if not d]
    assert "lhipjoint" in no_dof and not any(s.split()[:1] == ["lhipjoint"] for s in lines)
    some = list(lines)
    some.insert(_frame_line(some, 3) + 1, "lhipjoint\r")
    original = load(_write(tmp_path / "a.amc", lines), asf=asf)
    np.testing.assert_array_equal(load(_write(tmp_path / "b.amc", some), asf=asf).positions, original.positions)


def test_amc_empty_frames_and_no_bone_lines(amc_copy, tmp_path):
    """A frame without bone lines inside the file, a file of frame numbers only, and the one-byte file ``0`` are
    refused at the frame's line (they loaded as rest poses)."""
    lines, asf = amc_copy
    k = _frame_line(lines, 9)
    empty = lines[: k + 1] + lines[_frame_line(lines, 10) :]
    err = _raises(_write(tmp_path / "empty.amc", empty), k + 1, asf=asf)
    assert err.reason == "frame 9 has no bone lines"
    numbers = [s for s in lines if _is_frame_number(s) or s.startswith((":", "#"))]
    _raises(_write(tmp_path / "numbers.amc", numbers), _frame_line(numbers, 1) + 1, asf=asf)
    for text in ("0", "0\n", "1\r\n"):
        err = _raises(_write(tmp_path / "zero.amc", [text]), 1, asf=asf)
        assert "has no bone lines" in err.reason


def test_amc_cut_inside_its_only_frame(amc_copy, tmp_path):
    """A file of one frame cut before its last bone line is refused (it loaded with the rest at the rest pose)."""
    lines, asf = amc_copy
    one = lines[: _frame_line(lines, 2)]
    bones = [i for i in range(_frame_line(one, 1) + 1, len(one)) if one[i].strip()]
    load(_write(tmp_path / "one.amc", one), asf=asf)  # whole, it reads
    for cut in (bones[0], bones[len(bones) // 2], bones[-1]):
        err = _raises(_write(tmp_path / "cut.amc", one[:cut]), _frame_line(one, 1) + 1, asf=asf)
        if cut == bones[0]:
            assert err.reason == "frame 1 has no bone lines"
        else:  # one of the bones cut off named
            named = re.fullmatch(r"frame 1, the only one, has no line for bone '(\w+)' \(the file ends inside it\?\)",
                                 err.reason)
            assert named and named[1] in {one[i].split()[0] for i in bones if i >= cut}, err.reason


def test_amc_cut_inside_its_last_frame_loses_it_with_a_warning(amc_copy, tmp_path):
    """A file that ends inside its last frame (or right after its frame number) reads without it, with a
    MocapFormatWarning naming the file, the frame and its line."""
    lines, asf = amc_copy
    last = max(int(s) for s in lines if _is_frame_number(s))
    whole = load(_write(tmp_path / "whole.amc", lines), asf=asf)
    k = _frame_line(lines, last)
    for cut in (k + 1, _bone_line(lines, last, "lhumerus")):
        path = _write(tmp_path / "cut.amc", lines[:cut])
        with pytest.warns(MocapFormatWarning) as seen:
            motion = load(path, asf=asf)
        (w,) = seen
        assert w.message.path == str(path) and w.message.line == k + 1, str(w.message)
        assert f"last frame {last} is incomplete" in str(w.message) and str(path) in str(w.message)
        assert motion.n_frames == whole.n_frames - 1 == last - 1
        np.testing.assert_array_equal(motion.positions, whole.positions[:-1])


def _asf_error(lines: list[str], tmp_path, amc_lines) -> tuple[Path, Path]:
    """A corrupted ASF and an intact AMC beside it."""
    return _write(tmp_path / "bad.asf", lines), _write(tmp_path / "clip.amc", amc_lines)


def _raises_asf(amc: Path, asf: Path, line: int) -> MocapFormatError:
    with pytest.raises(MocapFormatError) as info:
        load(amc, asf=asf)
    err = info.value
    assert isinstance(err, ValueError)
    assert err.path == str(asf) and asf.name in str(err)
    assert err.line == line, (str(err), line)
    return err


def _asf_block(lines: list[str], bone: str) -> int:
    """0-based index of the 'name <bone>' line."""
    return next(i for i, s in enumerate(lines) if s.split()[:2] == ["name", bone])


def test_asf_bone_block_without_end(amc_copy, tmp_path):
    amc_lines, asf = amc_copy
    lines = _lines(asf)
    k = _asf_block(lines, "lfemur")
    end = next(i for i in range(k, len(lines)) if lines[i].split() == ["end"])
    del lines[end]
    next_begin = next(i for i in range(end, len(lines)) if lines[i].split() == ["begin"])
    bad, amc = _asf_error(lines, tmp_path, amc_lines)
    _raises_asf(amc, bad, next_begin + 1)


def test_asf_translation_dof(amc_copy, tmp_path):
    amc_lines, asf = amc_copy
    lines = _lines(asf)
    k = _asf_block(lines, "ltibia")
    dof = next(i for i in range(k, len(lines)) if lines[i].split()[:1] == ["dof"])
    lines[dof] = "    dof tx"
    bad, amc = _asf_error(lines, tmp_path, amc_lines)
    err = _raises_asf(amc, bad, dof + 1)
    assert "tx" in err.reason


def test_asf_bad_axis_order(amc_copy, tmp_path):
    amc_lines, asf = amc_copy
    lines = _lines(asf)
    k = _asf_block(lines, "lfemur")
    axis = next(i for i in range(k, len(lines)) if lines[i].split()[:1] == ["axis"])
    lines[axis] = lines[axis].replace("XYZ", "XXZ")
    bad, amc = _asf_error(lines, tmp_path, amc_lines)
    err = _raises_asf(amc, bad, axis + 1)
    assert "XXZ" in err.reason


@pytest.fixture
def bvh_copy(bandai1_dir):
    path = bandai1_dir / "data" / "dataset-1_bow_active_001.bvh"
    lines = _lines(path)
    data = next(i for i, s in enumerate(lines) if s.startswith("Frame Time")) + 1  # 0-based, first frame
    return lines, data


def test_bvh_fewer_frames_than_header(bvh_copy, tmp_path):
    """Named at the file's last line, which exists (it named line N + 1 of an N-line file), with or without a final
    line end, and with no frame at all."""
    lines, data = bvh_copy
    n = int(lines[data - 2].split()[1])
    kept = lines[: data + n - 5]  # lines 1 to data + n - 5
    for ending in ([""], []):
        path = _write(tmp_path / "short.bvh", kept + ending)
        assert len(path.read_bytes().splitlines()) == data + n - 5
        err = _raises(path, data + n - 5)
        assert err.reason == f"header says {n} frames, the file has {n - 5}: it ends at line {data + n - 5}"
    err = _raises(_write(tmp_path / "none.bvh", lines[:data]), data)
    assert err.reason == f"header says {n} frames, the file has 0: it ends at line {data}"


def test_bvh_more_frames_than_header(bvh_copy, tmp_path):
    lines, data = bvh_copy
    n = int(lines[data - 2].split()[1])
    longer = lines[: data + n] + [lines[data + n - 1]] * (FRAMES_SLACK + 1) + lines[data + n :]
    err = _raises(_write(tmp_path / "long.bvh", longer), data + n + 1)
    assert err.reason.startswith(f"header says {n} frames, the file has {n + FRAMES_SLACK + 1}")


@pytest.mark.parametrize("off", [-FRAMES_SLACK, -1, 1, FRAMES_SLACK])
def test_bvh_frames_line_off_by_a_few_rows_loads_the_rows_with_a_warning(bvh_copy, tmp_path, off):
    """issue 42 item 3: an exporter's slip (the peer file's Frames: line disagreed with its rows by one) loads every
    row the file holds, each as the file has it, with a MocapFormatWarning naming both counts and a line."""
    lines, data = bvh_copy
    n = int(lines[data - 2].split()[1])
    rows = lines[data:data + n]
    whole = read_bvh(_write(tmp_path / "whole.bvh", lines))
    header = [*lines[:data - 2], f"Frames: {n - off}", *lines[data - 1:data]]
    with pytest.warns(MocapFormatWarning, match=rf"header says {n - off} frames, the file has {n}: loaded") as seen:
        got = read_bvh(_write(tmp_path / "off.bvh", header + rows))
    assert seen[0].message.line >= data
    np.testing.assert_array_equal(got.positions, whole.positions)


def test_bvh_value_missing(bvh_copy, tmp_path):
    lines, data = bvh_copy
    k = data + 10
    lines[k] = " ".join(lines[k].split()[:-1])
    err = _raises(_write(tmp_path / "value.bvh", lines), k + 1)
    assert "values" in err.reason


@pytest.mark.parametrize("token", ["abc", "1.2.3", "nan", "-inf", "12x4", "1e999"])
def test_bvh_bad_number(bvh_copy, tmp_path, token):
    lines, data = bvh_copy
    k = data + 20
    tok = lines[k].split()
    tok[7] = token
    lines[k] = " ".join(tok)
    err = _raises(_write(tmp_path / "token.bvh", lines), k + 1)
    assert token in err.reason or "not finite" in err.reason


@pytest.mark.parametrize("token", ["1e999", "-1e400"])
def test_amc_overflowing_number(amc_copy, tmp_path, token):
    lines, asf = amc_copy
    k = _bone_line(lines, 9, "lhumerus")
    tok = lines[k].split()
    tok[2] = token
    lines[k] = " ".join(tok)
    _raises(_write(tmp_path / "huge.amc", lines), k + 1, asf=asf)


@pytest.mark.parametrize("value", ["0", "-3", "2.5", "nan", "inf", "many"])
def test_bvh_bad_frames_header(bvh_copy, tmp_path, value):
    lines, data = bvh_copy
    lines[data - 2] = f"Frames: {value}"
    err = _raises(_write(tmp_path / "frames.bvh", lines), data - 1)
    assert "Frames" in err.reason or value in err.reason


def test_bvh_channel_count_mismatch(bvh_copy, tmp_path):
    lines, _ = bvh_copy
    k = next(i for i, s in enumerate(lines) if s.split()[:1] == ["CHANNELS"] and i > 10)
    lines[k] = lines[k].replace(" Yrotation", "")
    err = _raises(_write(tmp_path / "channels.bvh", lines), k + 1)
    assert "6" in err.reason and "5" in err.reason


def test_bvh_unknown_channel(bvh_copy, tmp_path):
    lines, _ = bvh_copy
    k = [i for i, s in enumerate(lines) if s.split()[:1] == ["CHANNELS"]][4]
    lines[k] = lines[k].replace("Zrotation", "Wrotation")
    err = _raises(_write(tmp_path / "w.bvh", lines), k + 1)
    assert "Wrotation" in err.reason


@pytest.mark.parametrize("ext", [".amc", ".bvh"])
def test_empty_file(tmp_path, amc_copy, ext):
    path = tmp_path / f"empty{ext}"
    path.write_bytes(b"")
    _raises(path, None, **({"asf": amc_copy[1]} if ext == ".amc" else {}))


@pytest.mark.parametrize("ext", [".amc", ".bvh"])
def test_binary_file(tmp_path, amc_copy, ext):
    rng = np.random.default_rng(0)
    data = rng.integers(0, 256, 5000, dtype=np.uint8).tobytes()
    path = tmp_path / f"noise{ext}"
    path.write_bytes(b"\x00" + data)
    with pytest.raises(MocapFormatError) as info:
        load(path, **({"asf": amc_copy[1]} if ext == ".amc" else {}))
    assert isinstance(info.value, ValueError) and path.name in str(info.value)
    assert info.value.line in (None, 1)


def test_unsupported_extension(bvh_copy, tmp_path):
    path = _write(tmp_path / "clip.txt", bvh_copy[0])
    err = _raises(path, None)
    assert ".txt" in err.reason


def test_missing_file(tmp_path):
    _raises(tmp_path / "nothing.bvh", None)


def test_amc_without_asf(amc_copy, tmp_path):
    lines, _ = amc_copy
    _raises(_write(tmp_path / "lonely.amc", lines), None)


# ---------------------------------------------------------------------------------------------- units of BVH


def _rewrite_bvh(src: Path, dst: Path, factor: float = 1.0, hips_shift=(0.0, 0.0, 0.0)) -> Path:
    """``src`` with every length (OFFSETs, position channels) times ``factor`` and the Hips position channels
    moved by ``hips_shift`` (in the new unit)."""
    joints, data = _parse_bvh(src)
    lines = _lines(src)
    out, cols = [], []
    col = 0
    for joint in joints:
        for channel in joint["channels"]:
            if channel.endswith("position"):
                cols.append(col)
                if joint["name"] == "Hips":
                    data[:, col] = data[:, col] * factor + hips_shift["XYZ".index(channel[0])]
                    col += 1
                    continue
                data[:, col] *= factor
            col += 1
    for s in lines[: next(i for i, s in enumerate(lines) if s.startswith("MOTION")) + 3]:
        tok = s.split()
        if tok[:1] == ["OFFSET"]:
            s = "OFFSET " + " ".join(repr(float(t) * factor) for t in tok[1:])
        out.append(s)
    out += [" ".join(repr(v) for v in row) for row in data.tolist()]
    return _write(dst, out + [""])


def test_bvh_units_guess(bandai1_dir, tmp_path):
    src = bandai1_dir / "data" / "dataset-1_walk_normal_001.bvh"
    original = load(src)
    joints, data = _parse_bvh(src)
    assert joints[0]["name"] == "joint_Root" and not data[:, :6].any()  # the root: at the origin, unturned
    body = [j for j, n in enumerate(original.joint_names) if n != "joint_Root"]
    metres = load(_rewrite_bvh(src, tmp_path / "m.bvh", 0.01))
    np.testing.assert_allclose(metres.positions, original.positions, atol=1e-3)
    mm = load(_rewrite_bvh(src, tmp_path / "mm.bvh", 10.0))
    np.testing.assert_allclose(mm.positions, original.positions, atol=1e-3)
    np.testing.assert_allclose(load(tmp_path / "m.bvh", scale=1.0).positions, original.positions / 100, atol=1e-5)
    # the figure far from joint_Root (as in many Bandai Namco 2 files): its own size still decides the unit
    for name, factor, shift in (("far_cm.bvh", 1.0, 650.0), ("far_m.bvh", 0.01, 9.0), ("far_mm.bvh", 10.0, 7000.0)):
        far = load(_rewrite_bvh(src, tmp_path / name, factor, (0.0, 0.0, shift)))
        expected = original.positions[:, body] + [0.0, 0.0, shift / factor]
        np.testing.assert_allclose(far.positions[:, body], expected, atol=2e-3, err_msg=name)


# -------------------------------------------------------------------------------------------- up axis


def test_z_up_bvh_is_turned_to_y_up(bandai1_dir, tmp_path):
    """A genuinely z-up file: a new root joint turns the whole original figure by +90 degrees about x,
    (x, y, z) -> (x, -z, y), so the head is above the hips along z."""
    src = bandai1_dir / "data" / "dataset-1_walk-left_normal_001.bvh"
    lines = _lines(src)
    motion_at = next(i for i, s in enumerate(lines) if s.startswith("MOTION"))
    hierarchy = ["HIERARCHY", "ROOT ZUpFrame", "{", "  OFFSET 0 0 0", "  CHANNELS 3 Xrotation Yrotation Zrotation"]
    hierarchy += [s.replace("ROOT", "JOINT", 1) for s in lines[1:motion_at]] + ["}"]
    header = lines[motion_at : motion_at + 3]
    frames = ["90 0 0 " + s for s in lines[motion_at + 3 :] if s.strip()]
    z_file = _write(tmp_path / "zup.bvh", hierarchy + header + frames + [""])

    original = load(src)
    z_raw = load(z_file, up="z")  # forced: same as auto for this file
    z_auto = load(z_file)
    as_is = load(z_file, up="y")
    shared = [z_auto.joint_names.index(n) for n in original.joint_names]
    assert z_auto.joint_names[0] == "ZUpFrame" and len(shared) == original.n_joints
    # the file really stands on z
    head = as_is.joint("Head") - as_is.joint("Hips")
    assert head[:, 2].mean() > 30 and abs(head[:, 1].mean()) < 10
    p = original.positions
    np.testing.assert_allclose(as_is.positions[:, shared], np.stack([p[..., 0], -p[..., 2], p[..., 1]], -1), atol=1e-3)
    for m in (z_auto, z_raw):
        np.testing.assert_allclose(m.positions[:, shared], original.positions, atol=1e-3)
        q, q0 = m.quaternions[:, shared].astype(np.float64), original.quaternions.astype(np.float64)
        assert np.abs(np.abs(np.sum(q * q0, axis=-1)) - 1).max() < 1e-5
        np.testing.assert_allclose(np.abs(m.quaternions[:, 0, 0]), 1.0, atol=1e-6)  # the new root: identity
    # a y-up file is left alone under auto
    np.testing.assert_array_equal(load(src, up="auto").positions, load(src, up="y").positions)


# ------------------------------------------------------------------------------------------- resample


def test_resample_120_to_30(hdm05_dir, hdm05_labels):
    for cls in ("kickLFront1Reps", "hopBothLegs1hops"):
        motion = load(hdm05_dir / _hdm05_clip(hdm05_labels, "tr", cls))
        t = motion.n_frames
        low = motion.resample(30)
        assert low.fps == 30.0
        assert low.n_frames == (t - 1) // 4 + 1
        np.testing.assert_array_equal(low.positions, motion.positions[::4])
        q, q0 = low.quaternions.astype(np.float64), motion.quaternions[::4].astype(np.float64)
        assert np.abs(np.abs(np.sum(q * q0, axis=-1)) - 1).max() < 1e-5
        np.testing.assert_allclose(np.abs(q), np.abs(q0), atol=1e-5)
        assert low.duration == pytest.approx(low.n_frames / 30)


def test_resample_up_interpolates(hdm05_dir, hdm05_labels):
    motion = load(hdm05_dir / _hdm05_clip(hdm05_labels, "dg", "squat1Reps"))
    high = motion.resample(240)
    assert high.n_frames == 2 * motion.n_frames - 1
    np.testing.assert_array_equal(high.positions[::2], motion.positions)
    mid = (motion.positions[:-1].astype(np.float64) + motion.positions[1:]) / 2
    np.testing.assert_allclose(high.positions[1::2], mid, atol=1e-4)
    # slerp midpoint: half the angle of the step
    from mocapviz.motion import rotations

    q = high.quaternions.astype(np.float64)
    a, m, b = q[:-1:2], q[1::2], q[2::2]
    np.testing.assert_allclose(rotations.angle(a, m), rotations.angle(a, b) / 2, atol=2e-3)
    assert motion.resample(120) is motion
    with pytest.raises(ValueError):
        motion.resample(0)


# ------------------------------------------------------------------------------- keywords, white space, encodings
_BVH_KEYWORDS = re.compile(r"^(\s*)(HIERARCHY|ROOT|JOINT|End Site|OFFSET|CHANNELS|MOTION|Frames:|Frame Time:)")
_ODD_SPACES = ["\t", "\v", "\f", " \t ", "\t\v"]


def _same_motion(a, b) -> None:
    assert a.joint_names == b.joint_names and a.fps == b.fps
    for x, y in ((a.positions, b.positions), (a.quaternions, b.quaternions), (a.euler, b.euler)):
        np.testing.assert_array_equal(x, y)


def test_bvh_keywords_in_any_case_and_any_white_space(bvh_copy, bandai1_dir, tmp_path):
    """Keywords and channel names in other cases, words separated by tabs, vertical tabs and form feeds (also before
    MOTION), CR LF line ends: the same Motion as the original file."""
    lines, data = bvh_copy
    rng = np.random.default_rng(5)
    out = []
    for i, s in enumerate(lines):
        s = _BVH_KEYWORDS.sub(lambda m, i=i: m.group(1) + (m.group(2).lower() if i % 2 else m.group(2).swapcase()), s)
        s = re.sub("(X|Y|Z)(position|rotation)", lambda m: (m.group(1) + m.group(2)).upper(), s)
        if i < data + 5:  # the hierarchy, the header and a few frames
            s = re.sub(" +", lambda m: _ODD_SPACES[int(rng.integers(0, len(_ODD_SPACES)))], s)
        out.append(s.rstrip("\r") + "\r")
    out = [("\v" + s if s.strip().lower().startswith("motion") else s) for s in out]
    changed = _write(tmp_path / "odd.bvh", out)
    assert b"\vmotion" in changed.read_bytes().lower() and b"\r\n" in changed.read_bytes()
    _same_motion(load(changed), load(bandai1_dir / "data" / "dataset-1_bow_active_001.bvh"))


def test_asf_amc_keywords_in_any_case_and_any_white_space(amc_copy, tmp_path):
    """ASF keywords, DOF and axis-order names upper case, AMC header lower case, tabs and vertical tabs between
    numbers: the same Motion."""
    amc_lines, asf = amc_copy
    original = load(_write(tmp_path / "clip.amc", amc_lines), asf=asf)
    asf_lines = []
    for s in _lines(asf):
        tok = s.split()
        if tok and tok[0] in ("begin", "end", "name", "direction", "length", "axis", "dof", "order", "position",
                              "orientation", "angle", "mass", "id"):
            s = s.replace(tok[0], tok[0].upper(), 1)
        if tok and tok[0] in ("dof", "axis"):
            s = re.sub(r"\b(rx|ry|rz|XYZ)\b", lambda m: m.group(1).swapcase(), s)
        asf_lines.append(s.replace(":bonedata", ":BoneData").replace(":units", ":UNITS"))
    assert any("DOF RX" in s for s in asf_lines) and any(s.rstrip().endswith("xyz") for s in asf_lines)
    odd = [re.sub(" ", "\t\v", s) if i % 3 == 0 else s.lower() if s.startswith(":") else s
           for i, s in enumerate(amc_lines)]
    asf2 = _write(tmp_path / "odd.asf", asf_lines)
    _same_motion(load(_write(tmp_path / "odd.amc", odd), asf=asf2), original)


def test_bvh_encodings(bvh_copy, tmp_path):
    """UTF-8 joint names (with or without a BOM) read as UTF-8; other bytes as Latin-1; UTF-16 and NUL bytes are a
    typed error naming the file and line."""
    lines, _ = bvh_copy
    k = next(i for i, s in enumerate(lines) if "JOINT" in s)
    name = lines[k].split()[1]
    lines[k] = lines[k].replace(name, "Hüfte")
    text = "\n".join(lines)
    for prefix, encoding in ((b"", "utf-8"), (b"\xef\xbb\xbf", "utf-8"), (b"", "latin-1")):
        path = tmp_path / f"enc-{encoding}-{len(prefix)}.bvh"
        path.write_bytes(prefix + text.encode(encoding))
        assert "Hüfte" in load(path).joint_names
    path = tmp_path / "utf16.bvh"
    path.write_bytes(text.encode("utf-16"))
    assert "UTF-16" in _raises(path, 1).reason
    path = tmp_path / "nul.bvh"
    path.write_bytes(text.encode("latin-1").replace(b"\n", b"\n\x00", 30).replace(b"\n\x00", b"\n", 29))
    assert "binary" in _raises(path, 31).reason


def test_numbers_only_in_plain_decimal_notation(bvh_copy, tmp_path):
    """Python's float() takes '1_0', 'nan', 'Infinity' and non-ASCII digits; the readers take what the scanner takes."""
    lines, data = bvh_copy
    k = next(i for i, s in enumerate(lines) if s.split()[:1] == ["OFFSET"] and i > 5)
    for token in ("1_0", "Infinity", "nan", "\u0663", "0x10", "1e999"):
        bad = list(lines)
        bad[k] = f"  OFFSET {token} 0 0"
        path = tmp_path / "offset.bvh"
        path.write_bytes("\n".join(bad).encode("utf-8"))
        err = _raises(path, k + 1)
        assert "OFFSET" in err.reason
    bad = list(lines)
    bad[data - 1] = "Frame Time: 1_0"
    _raises(_write(tmp_path / "time.bvh", bad), data)


# ------------------------------------------------------------------------------------------------- limits
def test_bvh_values_beyond_the_limits(bvh_copy, tmp_path):
    """A rotation beyond 1e5 degrees, a position channel beyond 1e7 and an OFFSET beyond 1e7 are refused at their
    line, naming the channel and the value; 99,999 degrees is read."""
    from mocapviz.io.checks import ANGLE_LIMIT_DEG, DISTANCE_LIMIT_CM

    lines, data = bvh_copy
    k = data + 12
    tok = lines[k].split()
    for col, value, ok in ((10, ANGLE_LIMIT_DEG * 2, False), (10, -ANGLE_LIMIT_DEG + 1, True),
                           (0, DISTANCE_LIMIT_CM * 10, False)):  # fmt: skip
        bad = list(lines)
        bad[k] = " ".join(tok[:col] + [repr(value)] + tok[col + 1 :])
        path = _write(tmp_path / "limit.bvh", bad)
        if ok:
            assert np.isfinite(load(path).positions).all()
            continue
        err = _raises(path, k + 1)
        assert f"{value:.6g}" in err.reason and ("rotation" in err.reason or "position" in err.reason)
    o = next(i for i, s in enumerate(lines) if s.split()[:1] == ["OFFSET"] and i > 5)
    bad = list(lines)
    bad[o] = "OFFSET 0 2e7 0"
    _raises(_write(tmp_path / "offset.bvh", bad), o + 1)


def test_asf_amc_values_beyond_the_limits(amc_copy, tmp_path):
    """ASF: units length 1e-300 and 1e308, a bone of 1e308 units, a negative length, an axis of 1e6 degrees, a
    direction of -1e400 (found by the fuzzer: inf / inf in the normalisation); AMC: an angle of 1e6 degrees; fps 0.5:
    each refused, naming the file, line and value (fps: a ParameterError)."""
    amc_lines, asf = amc_copy
    asf_lines = _lines(asf)
    units = next(i for i, s in enumerate(asf_lines) if s.split()[:1] == ["length"])
    bone = _asf_block(asf_lines, "lfemur")
    length = next(i for i in range(bone, len(asf_lines)) if asf_lines[i].split()[:1] == ["length"])
    axis = next(i for i in range(bone, len(asf_lines)) if asf_lines[i].split()[:1] == ["axis"])
    direction = next(i for i in range(bone, len(asf_lines)) if asf_lines[i].split()[:1] == ["direction"])
    for line, text, shown in ((units, "  length 1e-300", "1e-300"), (units, "  length 1e308", "1e+308"),
                              (length, "  length 1e308", "1e+308"), (length, "  length -2", "-2"),
                              (axis, "  axis 0 0 1e6 XYZ", "1e+06"), (direction, "  direction 0 -1e400 0", "-1e400")
                              ):  # fmt: skip
        bad = list(asf_lines)
        bad[line] = text
        asf_bad, amc = _asf_error(bad, tmp_path, amc_lines)
        assert shown in _raises_asf(amc, asf_bad, line + 1).reason
    k = _bone_line(amc_lines, 4, "rfemur")
    bad = list(amc_lines)
    bad[k] = "rfemur 1e6 0 0"
    assert "1e+06" in _raises(_write(tmp_path / "angle.amc", bad), k + 1, asf=asf).reason
    from mocapviz.errors import ParameterError

    with pytest.raises(ParameterError, match="0.5 frames per second"):
        load(_write(tmp_path / "clip.amc", amc_lines), asf=asf, fps=0.5)


def _asf_lines_of(asf_lines: list[str], keyword: str) -> list[int]:
    """0-based indices of the ASF lines starting with ``keyword``."""
    return [i for i, s in enumerate(asf_lines) if s.split()[:1] == [keyword]]


def test_asf_directions_must_be_unit_vectors(amc_copy, tmp_path):
    """Every direction 0 0 0 (all joints at one point), one zero direction, and one of length 2 or 0.5 are refused
    naming the bone and line; a direction off unit length by 0.1 % is normalised (reads as the original)."""
    amc_lines, asf = amc_copy
    asf_lines = _lines(asf)
    directions = _asf_lines_of(asf_lines, "direction")
    zeroed = [("  direction 0 0 0" if i in directions else s) for i, s in enumerate(asf_lines)]
    bad, amc = _asf_error(zeroed, tmp_path, amc_lines)
    first = asf_lines[directions[0] - 1].split()[1]  # (the 'name' line comes before the direction in these files)
    err = _raises_asf(amc, bad, directions[0] + 1)
    assert err.reason.startswith(f"bone {first!r}: direction 0 0 0 has length 0, not 1 ± 0.05"), err.reason
    k = directions[5]
    values = np.array(asf_lines[k].split()[1:4], dtype=float)
    for factor, fails in ((0.0, True), (2.0, True), (0.5, True), (1.001, False)):
        edited = list(asf_lines)
        edited[k] = "  direction " + " ".join(f"{v:.9g}" for v in values * factor)
        bad, amc = _asf_error(edited, tmp_path, amc_lines)
        if fails:
            assert f"has length {np.linalg.norm(values) * factor:.6g}" in _raises_asf(amc, bad, k + 1).reason
        else:
            np.testing.assert_allclose(load(amc, asf=bad).positions, load(amc, asf=asf).positions, atol=1e-3)


@pytest.mark.parametrize("keyword, text, shown", [
    ("limits", "limits (nan 20.0)", "'nan' is not a number"),
    ("limits", "limits (-1e400 20.0)", "-1e400 is out of range (not finite)"),
    ("limits", "limits (-160.0 1e39)", "1e39 is beyond ±100000 degrees"),
    ("limits", "limits (-160.0)", "got 1 values"),
    ("limits", "limits (20.0 -160.0)", "the min is above the max"),
    ("(", "  (-70.0 inf0)", "'inf0' is not a number"),
    ("id", "id nan", "expected 1 numbers"),
    ("id", "id 1e400", "not finite"),
    ("direction", "direction 0.5 NaN 0", "expected 3 numbers"),
    ("direction", "direction 0 1e400 0", "not finite"),
])  # fmt: skip
def test_asf_limits_ids_and_directions_must_be_finite(amc_copy, tmp_path, keyword, text, shown):
    """NaN, inf and overflowing numbers in ``limits`` (and its continuation lines), ``id`` and ``direction`` are
    refused naming the line (they were not read, and 49 fuzzed files loaded)."""
    amc_lines, asf = amc_copy
    asf_lines = _lines(asf)
    k = next(i for i in range(_asf_block(asf_lines, "lfemur"), len(asf_lines))
             if asf_lines[i].split()[:1] == [keyword] or keyword == "(" and asf_lines[i].lstrip().startswith("("))
    asf_lines[k] = text
    bad, amc = _asf_error(asf_lines, tmp_path, amc_lines)
    assert shown in _raises_asf(amc, bad, k + 1).reason


def test_asf_limits_may_be_unbounded(amc_copy, tmp_path):
    """``limits (-inf inf)`` is the ASF's "no limit" (the Acclaim specification): read, the motion unchanged."""
    amc_lines, asf = amc_copy
    asf_lines = _lines(asf)
    limits = _asf_lines_of(asf_lines, "limits")
    for i in limits:
        asf_lines[i] = "    limits (-inf inf)"
    good, amc = _asf_error(asf_lines, tmp_path, amc_lines)
    np.testing.assert_array_equal(load(amc, asf=good).positions, load(amc, asf=asf).positions)


def test_forward_kinematics_in_blocks_equals_one_pass(bvh_copy, bandai1_dir, monkeypatch):
    """Blocks of 7 frames give the same positions and rotations as the whole clip at once."""
    from mocapviz.io import checks

    path = bandai1_dir / "data" / "dataset-1_bow_active_001.bvh"
    whole = load(path)
    monkeypatch.setattr(checks, "_BLOCK", 7 * whole.n_joints)
    _same_motion(load(path), whole)
