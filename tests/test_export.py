"""mocapviz.export (issue 27): every export read back equals what it was cut from.

Canonical rig: positions read back (mocapviz.io.load for BVH; pygltflib and forward kinematics for glTF) equal the
database's within 0.01 cm. Source rig: a BVH source's frame lines byte for byte, an AMC source's frame blocks line for
line (numbers renumbered from 1), an AMC as BVH on its ASF rig with the AMC's positions. Every file names its source.
On the embedded sample and on real clips of every archive (HDM05 and CMU ASF/AMC, Bandai Namco BVH), one at a
resampled rate.
"""
from __future__ import annotations

import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import MotionDB
from mocapviz.cli import main
from mocapviz.db.hits import hit_table
from mocapviz.errors import ParameterError, SourceFileError
from mocapviz.export import (export_hits, export_stretch, hit_files, hits_zip, read_hits, source_frames,
                              stretch_files)
from mocapviz.io import load
from mocapviz.motion import rotations
from mocapviz.motion.skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS

TOLERANCE_CM = 0.01
VALIDATOR = Path(__file__).resolve().parents[1] / ".cache" / "gltf" / "node_modules" / "gltf-validator"


# ------------------------------------------------------------------------------------------------ reading back
def _metadata(text: bytes) -> dict:
    found = re.search(rb"^# mocapviz export: (\{.*\})\r?$", text, re.MULTILINE)
    assert found, "no '# mocapviz export: {...}' line"
    return json.loads(found.group(1))


def _frame_lines(raw: bytes) -> list[bytes]:
    """The frame lines of a BVH file (after 'Frame Time:'), line ends stripped."""
    lines = raw.split(b"\n")
    at = next(i for i, line in enumerate(lines) if line.strip().lower().startswith(b"frame time"))
    return [line.rstrip(b"\r") for line in lines[at + 1:] if line.strip()]


def _amc_blocks(raw: bytes) -> tuple[list[int], list[list[bytes]]]:
    """Frame numbers and each frame's bone lines of an AMC file."""
    numbers, blocks = [], []
    for line in raw.split(b"\n"):
        s = line.strip()
        if not s or s.startswith((b"#", b":")):
            continue
        if s.isdigit():
            numbers.append(int(s))
            blocks.append([])
        else:
            blocks[-1].append(line.rstrip(b"\r"))
    return numbers, blocks


def _glb_positions(data: bytes) -> tuple[dict, np.ndarray, tuple]:
    """(asset extras, positions [T, J, 3] in cm, node names) of a .glb: its animation sampled at its key times and
    the node tree run forward (T * R of every node, parents first)."""
    import pygltflib

    gltf = pygltflib.GLTF2.load_from_bytes(data)
    blob = gltf.binary_blob()

    def read(k):
        acc = gltf.accessors[k]
        view = gltf.bufferViews[acc.bufferView]
        width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc.type]
        return np.frombuffer(blob, "<f4", acc.count * width, view.byteOffset + (acc.byteOffset or 0)).reshape(acc.count, width)

    n = len(gltf.nodes)
    anim = gltf.animations[0]
    n_frames = gltf.accessors[anim.samplers[0].input].count
    translation = np.tile(np.array([nd.translation or [0, 0, 0] for nd in gltf.nodes], float), (n_frames, 1, 1))
    rotation = np.tile([0.0, 0.0, 0.0, 1.0], (n_frames, n, 1))
    for ch in anim.channels:
        values = read(anim.samplers[ch.sampler].output).astype(float)
        (translation if ch.target.path == "translation" else rotation)[:, ch.target.node] = values
    parent = {c: j for j, nd in enumerate(gltf.nodes) for c in nd.children or []}
    world_q = np.zeros((n_frames, n, 4))
    pos = np.zeros((n_frames, n, 3))
    order = list(gltf.scenes[0].nodes)
    for j in order:  # parents first
        q = rotation[:, j][:, [3, 0, 1, 2]]
        if j in parent:
            p = parent[j]
            pos[:, j] = pos[:, p] + rotations.rotate(world_q[:, p], translation[:, j])
            world_q[:, j] = rotations.multiply(world_q[:, p], q)
        else:
            pos[:, j], world_q[:, j] = translation[:, j], q
        order += gltf.nodes[j].children or []
    return gltf.asset.extras, pos * 100.0, tuple(nd.name for nd in gltf.nodes)


def _validate(data: bytes, tmp_path: Path) -> dict:
    """The Khronos glTF validator's report of ``data`` (skips when node or the validator is not installed)."""
    if shutil.which("node") is None:
        pytest.skip("the glTF validator needs node (apt-get install nodejs)")
    if not VALIDATOR.is_dir():
        pytest.skip(f"the glTF validator is not installed: `make gltf-validator` (npm install --prefix "
                    f"{VALIDATOR.parents[1]} gltf-validator)")
    f = tmp_path / "check.glb"
    f.write_bytes(data)
    script = ("const v = require(process.argv[1]); v.validateBytes(new Uint8Array(require('fs').readFileSync("
              "process.argv[2]))).then(r => console.log(JSON.stringify(r.issues)))")
    out = subprocess.run(["node", "-e", script, str(VALIDATOR), str(f)], capture_output=True, text=True, timeout=120,
                         check=True)
    return json.loads(out.stdout)


# ------------------------------------------------------------------------------------------------ round trips
def _by_name(motion, names) -> np.ndarray:
    return motion.positions[:, [motion.joint_names.index(n) for n in names]]


def check_canonical(db, doc, start, end, tmp_path) -> float:
    """Canonical BVH and glTF of one stretch read back against the database; the largest error, cm."""
    want = db.positions[db.frames(doc)][start:end]
    [bvh] = export_stretch(db, doc, tmp_path / "bvh", start, end, "bvh", "canonical", search="a test")
    got = load(bvh).canonical({c: c for c in CANONICAL_JOINTS})  # up="auto": the rest pose says y up
    assert got.fps == db.document(doc)["fps"] and got.n_frames == end - start
    err_bvh = np.abs(got.positions - want).max()
    meta = _metadata(bvh.read_bytes())
    assert (meta["doc_id"], meta["frames"], meta["rig"], meta["search"]) == (doc, [start, end], "canonical", "a test")
    [glb] = export_stretch(db, doc, tmp_path / "glb", start, end, "glb", search="a test")
    extras, pos, names = _glb_positions(glb.read_bytes())
    assert names == CANONICAL_JOINTS and extras["doc_id"] == doc and extras["frames"] == [start, end]
    err_glb = np.abs(pos - want).max()
    assert err_bvh < TOLERANCE_CM and err_glb < TOLERANCE_CM, (err_bvh, err_glb)
    return max(err_bvh, err_glb)


def check_amc_source(db, doc, start, end, tmp_path) -> float:
    """AMC of a stretch: the source's frame blocks, renumbered; its ASF a copy; as BVH on the ASF rig, the AMC's
    positions. The largest position error, cm."""
    row = db.document(doc)
    a, b = source_frames(row, start, end)
    src = Path(row["path"])
    source = load(src)[a:b]
    amc, asf = export_stretch(db, doc, tmp_path / "amc", start, end, "amc")
    numbers, blocks = _amc_blocks(amc.read_bytes())
    assert numbers == list(range(1, b - a + 1))
    assert blocks == _amc_blocks(src.read_bytes())[1][a:b]
    from mocapviz.io import find_asf

    assert asf.read_bytes() == find_asf(src).read_bytes()
    meta = _metadata(amc.read_bytes())
    assert (meta["source"], meta["source_frames"], meta["sha256"]) == (str(src), [a, b], row["sha256"])
    back = load(amc)
    assert np.array_equal(back.positions, source.positions)
    [bvh] = export_stretch(db, doc, tmp_path / "asfbvh", start, end, "bvh")
    rig = load(bvh)
    tips = []  # an ASF bone's tip is its first child's BVH joint, or its End Site
    for j, name in enumerate(source.joint_names):
        kids = np.flatnonzero(source.parents == j)
        tips.append(name if j == 0 else source.joint_names[kids[0]] if kids.size else f"{name}_end")
    err = np.abs(_by_name(rig, tips) - source.positions).max()
    assert err < TOLERANCE_CM, err
    return float(err)


def check_bvh_source(db, doc, start, end, tmp_path) -> float:
    """BVH of a BVH source's stretch: header and frame lines byte for byte; read back equal to the source's frames."""
    row = db.document(doc)
    a, b = source_frames(row, start, end)
    src = Path(row["path"]).read_bytes()
    [bvh] = export_stretch(db, doc, tmp_path / "src", start, end, "bvh")
    raw = bvh.read_bytes()
    assert _frame_lines(raw) == _frame_lines(src)[a:b]
    head, src_head = raw.split(b"MOTION")[0], src.split(b"MOTION")[0]
    assert re.sub(rb"(?m)^# mocapviz export: .*\n", b"", head) == src_head
    assert re.search(rb"(?m)^Frames:\s*(\d+)", raw).group(1) == str(b - a).encode()
    assert _metadata(raw)["source_frames"] == [a, b]
    err = np.abs(load(bvh).positions - load(row["path"])[a:b].positions).max()
    assert err == 0.0
    return float(err)


def test_sample_every_document_round_trips(tmp_path):
    db = MotionDB.sample()
    worst = {"canonical": 0.0, "amc": 0.0}
    for doc in db.documents["doc_id"]:
        n = int(db.document(doc)["n_frames"])
        start, end = n // 5, n - n // 7
        worst["canonical"] = max(worst["canonical"], check_canonical(db, doc, start, end, tmp_path / str(doc)))
        worst["amc"] = max(worst["amc"], check_amc_source(db, doc, start, end, tmp_path / str(doc)))
    print("sample, largest errors (cm):", worst)


def test_source_rig_glb_reproduces_the_source_positions(tmp_path):
    db = MotionDB.sample()
    row = db.document(0)
    files = stretch_files(db, 0, 10, 50, "glb", "source")
    [(_, data)] = files.items()
    _, pos, names = _glb_positions(data)
    source = load(row["path"])[10:50]
    assert names == source.joint_names
    assert np.abs(pos - source.positions).max() < TOLERANCE_CM


@pytest.fixture(scope="module")
def archive_dbs(tmp_path_factory, hdm05_dir, cmu_dir, bandai1_files):
    """Small databases of real clips: three HDM05 clips (one lying on the floor) at their 120 Hz and at 30 Hz, two
    CMU trials, two Bandai Namco BVH files."""
    root = tmp_path_factory.mktemp("export")
    hdm = sorted((hdm05_dir / "amc").glob("*.amc"))[:2] + sorted((hdm05_dir / "amc").glob("*lieDownFloor*.amc"))[:1]
    cmu = sorted((cmu_dir / "amc").rglob("*.amc"))[:2]
    return {
        "hdm05": MotionDB.ingest(hdm, root / "hdm05", progress=False),
        "hdm05@30": MotionDB.ingest(hdm, root / "hdm05-30", fps=30, progress=False),
        "cmu": MotionDB.ingest(cmu, root / "cmu", progress=False),
        "bandai": MotionDB.ingest(bandai1_files[:2], root / "bandai", progress=False),
    }


@pytest.mark.parametrize("archive", ["hdm05", "hdm05@30", "cmu", "bandai"])
def test_real_clips_round_trip(archive_dbs, archive, tmp_path):
    db = archive_dbs[archive]
    errors = []
    for doc in db.documents["doc_id"]:
        n = int(db.document(doc)["n_frames"])
        start, end = n // 4, n - n // 6
        errors.append(check_canonical(db, doc, start, end, tmp_path / str(doc)))
        source = check_bvh_source if archive == "bandai" else check_amc_source
        errors.append(source(db, doc, start, end, tmp_path / str(doc)))
    print(f"{archive}: largest error {max(errors):.2e} cm")


def _lying_stretch(db) -> tuple[int, int, int]:
    """(doc, start, end): the HDM05 lieDownFloor document's last frames, all on the floor (head - root more
    sideways than up), at least a second of them."""
    [doc] = db.documents.loc[db.documents["name"].str.contains("lieDownFloor"), "doc_id"]
    p = db.positions[db.frames(doc)]
    d = p[:, CANONICAL_JOINTS.index("head")] - p[:, CANONICAL_JOINTS.index("root")]
    lying = d[:, 1] < 0.5 * np.linalg.norm(d[:, [0, 2]], axis=1)
    start, end = int(np.flatnonzero(~lying)[-1]) + 1, len(p)
    assert end - start >= db.document(doc)["fps"]
    return int(doc), start, end


def test_canonical_rest_pose_is_upright_and_one_layout_for_every_archive(archive_dbs, tmp_path):
    """Every canonical BVH starts from the same upright T-pose (y up, facing +z, left on +x), its bones as long as
    the document's: legs down, feet forward, spine up, arms out; every stretch of a document gets the same rig."""
    from mocapviz.io.bvh import _hierarchy

    for archive, db in archive_dbs.items():
        for doc in db.documents["doc_id"]:
            n = int(db.document(doc)["n_frames"])
            files = [stretch_files(db, doc, a, b, "bvh", "canonical")
                     for a, b in ((0, n // 2), (n // 3, n))]  # fmt: skip
            heads = [data.split(b"MOTION")[0].decode() for [data] in (list(f.values()) for f in files)]
            first, second = (_hierarchy(re.sub(r"(?m)^# .*\n", "", h)) for h in heads)
            assert np.array_equal(first.offsets, second.offsets)  # (a joint with position channels: OFFSET 0 0 0)
            off = dict(zip(first.names, first.offsets))
            p = db.positions[db.frames(doc)]
            length = {c: np.median(np.linalg.norm(p[:, j] - p[:, CANONICAL_PARENTS[j]], axis=-1))
                      for j, c in enumerate(CANONICAL_JOINTS) if j}  # fmt: skip
            for joint, axis, sign in (("knee", 1, -1), ("ankle", 1, -1), ("toes", 2, 1), ("shoulder", 0, 1),
                                      ("elbow", 0, 1), ("wrist", 0, 1), ("fingers", 0, 1)):
                for side, flip in (("l", 1), ("r", -1)):
                    want = np.zeros(3)
                    want[axis] = (flip if axis == 0 else 1) * sign * length[side + joint]
                    if off[side + joint].any():  # (not where the joint has position channels)
                        np.testing.assert_allclose(off[side + joint], want, atol=1e-5, err_msg=(archive, side + joint))
            for joint in ("chest", "neck", "headtop"):
                if off[joint].any():
                    np.testing.assert_allclose(off[joint], [0, length[joint], 0], atol=1e-5, err_msg=(archive, joint))
            for pair in ("hip", "clavicle"):  # across the body (x), below their parent; a zero bone: zero
                left, right = off["l" + pair], off["r" + pair]
                assert left[0] >= 0 >= right[0] and left[1] == right[1] <= 0 and left[2] == right[2] == 0, (archive, pair)
                for side in "lr":
                    if off[side + pair].any() or length[side + pair] < 1e-4:
                        assert np.linalg.norm(off[side + pair]) == pytest.approx(length[side + pair], abs=1e-4)


def test_a_figure_lying_on_the_floor_throughout_reads_back_with_up_auto(archive_dbs, tmp_path):
    """A canonical export of a stretch lying on the floor, its mean head - root vector along +z (the motion
    alone would take it for a figure standing in a z-up file): read with up="auto" it equals the database, as the
    rest pose is y up. The same file with every axis turned to z up (offsets, positions and rotations) is turned
    back, although its motion's head - root vector points along -y."""
    db = archive_dbs["hdm05"]
    doc, start, end = _lying_stretch(db)
    p = db.positions[db.frames(doc)][start:end]
    d = (p[:, CANONICAL_JOINTS.index("head")] - p[:, 0]).mean(0)
    assert d[2] > abs(d[0]) and d[2] > abs(d[1])  # what made up="auto" turn such a clip before
    check_canonical(db, doc, start, end, tmp_path)  # (reads the BVH with the default up="auto")
    [bvh] = export_stretch(db, doc, tmp_path / "zup", start, end, "bvh", "canonical")
    z_up = tmp_path / "z_up.bvh"
    z_up.write_text(_turned_to_z_up(bvh.read_text()))
    as_is = load(z_up, up="y").canonical({c: c for c in CANONICAL_JOINTS})  # the file's own axes: M p
    assert np.abs(as_is.positions - np.stack([p[..., 0], -p[..., 2], p[..., 1]], -1)).max() < TOLERANCE_CM
    d = (as_is.positions[:, CANONICAL_JOINTS.index("head")] - as_is.positions[:, 0]).mean(0)
    assert -d[1] > abs(d[0]) and -d[1] > abs(d[2])  # the motion alone would leave it as it is
    got = load(z_up).canonical({c: c for c in CANONICAL_JOINTS})
    assert np.abs(got.positions - p).max() < TOLERANCE_CM


def _turned_to_z_up(text: str) -> str:
    """A canonical export (channels ``[X/Y/Zposition] Zrotation Xrotation Yrotation``) in z-up axes: every vector
    turned by M = +90 degrees about x, (x, y, z) -> (x, -z, y), every rotation R to M R M^T: Rz(a) Rx(b) Ry(c) ->
    Ry(-a) Rx(b) Rz(c), so forward kinematics of the new file is M times that of the old."""
    head, motion = text.split("MOTION\n")
    turn = lambda v: [v[0], -v[2], v[1]]
    kinds = []
    lines = []
    for line in head.splitlines():
        w = line.split()
        if w and w[0] == "OFFSET":
            line = line[: line.index("OFFSET")] + "OFFSET " + " ".join(f"{x:.6f}" for x in turn([float(x) for x in w[1:]]))
        elif w and w[0] == "CHANNELS":
            assert w[-3:] == ["Zrotation", "Xrotation", "Yrotation"]
            kinds += ["position"] * (len(w) == 8) + ["rotation"]
            line = line.replace("Zrotation Xrotation Yrotation", "Yrotation Xrotation Zrotation")
        lines.append(line)
    frames = motion.splitlines()
    out = []
    for frame in frames[2:]:
        v = [float(x) for x in frame.split()]
        k = 0
        for kind in kinds:
            v[k : k + 3] = turn(v[k : k + 3]) if kind == "position" else [-v[k], v[k + 1], v[k + 2]]
            k += 3
        out.append(" ".join(f"{x:.6f}" for x in v))
    return "\n".join(lines + ["MOTION"] + frames[:2] + out) + "\n"


def test_resampled_database_cuts_the_source_at_the_same_seconds(archive_dbs, tmp_path):
    """A 30 Hz database of 120 Hz files: the source AMC exported for frames start:end holds the source frames of the
    same seconds, so every 4th of its frames is the database's frame."""
    db = archive_dbs["hdm05@30"]
    doc = int(db.documents["doc_id"].iloc[0])
    row = db.document(doc)
    assert (row["fps"], row["source_fps"]) == (30.0, 120.0)
    amc, _ = export_stretch(db, doc, tmp_path, 5, 25, "amc")
    back = load(amc).canonical()
    assert back.n_frames == (25 - 1 - 5) * 4 + 1
    assert np.abs(back.positions[::4] - db.positions[db.frames(doc)][5:25]).max() < TOLERANCE_CM


def test_glb_passes_the_khronos_validator(tmp_path):
    db = MotionDB.sample()
    for rig in ("canonical", "source"):
        [(_, data)] = stretch_files(db, 7, 0, 60, "glb", rig).items()
        report = _validate(data, tmp_path)
        assert report["numErrors"] == 0 and report["numWarnings"] == 0, report["messages"]


def test_document_without_rotations_exports_on_the_canonical_rig(tmp_path):
    db = MotionDB.sample()
    m = db.motion(7)
    bare = MotionDB.create(tmp_path / "db").append_motions(
        [type(m)(positions=np.array(m.positions), fps=m.fps, joint_names=m.joint_names, parents=m.parents,
                 labels={"label": "bare"})])
    assert bare.motion(0).quaternions is None
    check_canonical(bare, 0, 0, 60, tmp_path)


def _forward(pose, parents) -> np.ndarray:
    """Positions [T, J, 3] of a fitted Pose: P[j] = P[p] + R(Q[p]) t[j], Q[j] = Q[p] q[j]."""
    world = np.zeros(pose.rotations.shape)
    pos = np.zeros(pose.translations.shape)
    for j, p in enumerate(parents):
        if p < 0:
            world[:, j], pos[:, j] = pose.rotations[:, j], pose.translations[:, j]
        else:
            world[:, j] = rotations.multiply(world[:, p], pose.rotations[:, j])
            pos[:, j] = pos[:, p] + rotations.rotate(world[:, p], pose.translations[:, j])
    return pos


def test_fit_pose_moves_only_the_joints_no_rotation_reproduces():
    """A root with two rigid hips and a spine bending against them, a spine whose length varies: the hips and the
    neck need no position channels, the spine (against its siblings) and the head (length) do; all exact."""
    from mocapviz.motion.rig import fit_pose

    rng = np.random.default_rng(5)
    n = 50
    parents = np.array([-1, 0, 0, 0, 3, 4])  # root, lhip, rhip, spine, neck, head
    turn = rotations.from_euler("ZXY", rng.normal(scale=40, size=(n, 3)))
    bend = rotations.from_euler("X", np.linspace(0, 60, n)[:, None])
    pos = np.zeros((n, 6, 3))
    pos[:, 0] = rng.normal(scale=50, size=(n, 3))
    pos[:, 1] = pos[:, 0] + rotations.rotate(turn, [10.0, -5, 0])
    pos[:, 2] = pos[:, 0] + rotations.rotate(turn, [-10.0, -5, 0])
    spine = rotations.multiply(turn, bend)
    pos[:, 3] = pos[:, 0] + rotations.rotate(spine, [0.0, 20, 0])
    pos[:, 4] = pos[:, 3] + rotations.rotate(spine, [0.0, 30, 2])
    pos[:, 5] = pos[:, 4] + rotations.rotate(spine, [0.0, 1, 0]) * np.linspace(10, 12, n)[:, None]
    pose = fit_pose(pos, parents, pos[0] - pos[0, np.maximum(parents, 0)])
    assert pose.moving.tolist() == [True, False, False, True, False, True]
    assert np.abs(_forward(pose, parents) - pos).max() < 1e-9


# ------------------------------------------------------------------------------------------------ hits, zip, CLI
def test_hits_export_files_sort_by_rank_and_the_zip_holds_the_same_bytes(tmp_path):
    db = MotionDB.sample()
    hits = hit_table(db, [22, 11, 7], [30, 0, 5], [90, 60, 100], cost=[0.1, 0.2, 0.3])
    paths = export_hits(db, hits, tmp_path, format="bvh", rig="canonical", search="squats")
    assert [p.name[:4] for p in paths] == ["001_", "002_", "003_"] and sorted(paths) == paths
    meta = _metadata(paths[1].read_bytes())
    assert (meta["doc_id"], meta["frames"], meta["rank"], meta["scores"]) == (11, [0, 60], 2, {"cost": 0.2})
    before = set(os.listdir(tmp_path))
    archive = zipfile.ZipFile(io.BytesIO(hits_zip(db, hits, format="bvh", rig="canonical", search="squats")))
    assert archive.namelist() == [p.name for p in paths]
    assert all(archive.read(p.name) == p.read_bytes() for p in paths)
    assert set(os.listdir(tmp_path)) == before


@pytest.mark.parametrize("table, message", [
    (pd.DataFrame({"doc_id": [7], "start": [0]}), "no column end"),
    (pd.DataFrame({"doc_id": [7], "start": [0.5], "end": [10]}), "row 1: start must be a whole number"),
    (pd.DataFrame({"doc_id": [999], "start": [0], "end": [10]}), "no document 999"),
    (pd.DataFrame({"doc_id": [7, 7], "start": [0, 100], "end": [10, 500]}), "hit 2: frames 100:500"),
    (pd.DataFrame({"doc_id": [], "start": [], "end": []}), "no rows"),
])  # fmt: skip
def test_bad_hit_tables_are_refused_naming_what_to_pass(table, message):
    with pytest.raises(ParameterError, match=message):
        read_hits(MotionDB.sample(), table)


def test_bad_requests_are_parameter_errors():
    db = MotionDB.sample()
    with pytest.raises(ParameterError, match="unknown export format"):
        stretch_files(db, 7, format="fbx")
    with pytest.raises(ParameterError, match="copies the frames of an ASF/AMC source"):
        stretch_files(db, 7, format="amc", rig="canonical")
    with pytest.raises(ParameterError, match="frames 0:500 are outside document 7"):
        stretch_files(db, 7, 0, 500)


def test_a_gone_or_changed_source_is_a_typed_error(tmp_path):
    src = Path(MotionDB.sample().document(7)["path"])  # hdm05-cut/amc/HDM_dg_....amc, its skeleton in hdm05-cut/asf
    (tmp_path / "amc").mkdir()
    shutil.copytree(src.parent.parent / "asf", tmp_path / "asf")
    copy = Path(shutil.copy(src, tmp_path / "amc" / src.name))
    db = MotionDB.ingest([copy], tmp_path / "db", progress=False)
    assert stretch_files(db, 0, format="amc")
    copy.write_bytes(copy.read_bytes() + b"\n")
    with pytest.raises(SourceFileError, match="has changed since it was ingested"):
        stretch_files(db, 0, format="amc")
    copy.unlink()
    with pytest.raises(SourceFileError, match="is gone; export it with --rig canonical"):
        stretch_files(db, 0, format="bvh")
    assert stretch_files(db, 0, format="bvh", rig="canonical")  # the database's own frames need no source


def test_cli_exports_a_hits_csv_and_refuses_bad_options(tmp_path, capsys):
    db = MotionDB.sample()
    csv = tmp_path / "hits.csv"
    hit_table(db, [3, 0], [10, 0], [70, 120], cost=[1.5, 2.0]).to_csv(csv, index=False)
    assert main(["export", str(db.path), "--hits", str(csv), "--format", "glb", "--out", str(tmp_path / "out")]) == 0
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert names == sorted(stretch_files(db, 3, 10, 70, "glb", rank=1)) + sorted(stretch_files(db, 0, 0, 120, "glb",
                                                                                                   rank=2))
    extras, _, _ = _glb_positions((tmp_path / "out" / names[0]).read_bytes())
    assert extras["search"] == "hits of hits.csv" and extras["scores"] == {"cost": 1.5}
    assert main(["export", str(db.path), "--doc", "7", "--frames", "0:500", "--format", "bvh", "--out",
                 str(tmp_path)]) == 1
    assert "--frames 0:500 are outside document 7" in capsys.readouterr().err
    assert main(["export", str(db.path), "--hits", str(csv), "--frames", "0:5", "--format", "bvh", "--out",
                 str(tmp_path)]) == 1
    bad = tmp_path / "bad.csv"
    bad.write_text("doc_id,first\n3,0\n")
    assert main(["export", str(db.path), "--hits", str(bad), "--format", "bvh", "--out", str(tmp_path)]) == 1
    assert "has no column start, end" in capsys.readouterr().err


def test_bvh_reader_skips_comment_lines_in_the_hierarchy(tmp_path):
    from mocapviz.io.bvh_writer import bvh_bytes

    f = tmp_path / "c.bvh"
    f.write_bytes(bvh_bytes(["hips", "knee"], [-1, 0], [[0, 0, 0], [0, -40, 0]],
                            [["Xposition", "Yposition", "Zposition"], ["Xrotation"]], [[0, 90, 0, 90]], 30,
                            comments=["first", "# second"]))
    m = load(f, up="y")
    assert m.joint_names == ("hips", "knee", "knee_end")
    assert np.allclose(m.positions[0, 1], [0, 50, 0])


def test_cut_bvh_keeps_the_lines_and_line_ends_of_a_crlf_file(tmp_path):
    from mocapviz.io.bvh_writer import bvh_bytes, cut_bvh

    values = np.arange(12.0).reshape(4, 3) * [1, 10, 100]
    raw = bvh_bytes(["hips"], [-1], [[0, 0, 0]], [["Xposition", "Yposition", "Zrotation"]], values, 60)
    raw = raw.replace(b"\n", b"\r\n")
    f = tmp_path / "cut.bvh"
    f.write_bytes(cut_bvh(raw, 1, 3, ["a note"]))
    cut = f.read_bytes()
    assert _frame_lines(cut) == _frame_lines(raw)[1:3] and b"\n" not in cut.replace(b"\r\n", b"")
    assert _metadata(b"# mocapviz export: {}\r\n") == {} and b"# a note\r\n" in cut
    np.testing.assert_allclose(load(f, up="y").positions[:, 0, :2], values[1:3, :2])


# ------------------------------------------------------------------------------------------------ all or nothing
# issue 37: round3's export/ reproducers, on 12 Bandai Namco takes ingested from copies renamed as they were made
RENAMED = {4: "a b.bvh", 6: "a_b.bvh", 9: "x" * 240 + ".bvh"}
PAUSE_AT_THIRD_HIT = """
import sys, time
import mocapviz.export.hits as hits
made = []
def paused(*args, **kwargs):
    made.append(args)
    if len(made) == 3:  # hits 1 and 2 are written by now
        print("third hit", flush=True)
        time.sleep(120)
    return stretch_files(*args, **kwargs)
stretch_files, hits.stretch_files = hits.stretch_files, paused
from mocapviz.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.fixture(scope="module")
def renamed_db(tmp_path_factory, bandai1_files):
    """The first 12 Bandai Namco 1 takes ingested from copies named so that doc 4 is ``a b.bvh`` and doc 6
    ``a_b.bvh`` (both clean to ``a_b``), doc 9 240 x's + ``.bvh``."""
    root = tmp_path_factory.mktemp("renamed")
    (root / "files").mkdir()
    files = [Path(shutil.copy(f, root / "files" / RENAMED.get(i, f.name))) for i, f in enumerate(bandai1_files[:12])]
    db = MotionDB.ingest(files, root / "db", progress=False)
    assert [Path(p).name for p in db.documents["path"]] == [f.name for f in files]
    return db


def _tree(root: Path) -> dict:
    """Every file and folder under ``root`` (hidden ones too): relative path -> bytes (None for a folder)."""
    return {str(p.relative_to(root)): None if p.is_dir() else p.read_bytes() for p in sorted(root.rglob("*"))}


def _cli(*args, prologue: str = "", **popen) -> subprocess.Popen:
    """``mocapviz ARGS`` in a new Python process (after ``prologue``), its output piped."""
    code = f"{prologue}\nimport sys\nfrom mocapviz.cli import main\nsys.exit(main(sys.argv[1:]))"
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **popen)


def _existing_destination(folder: Path, first_name: str) -> Path:
    """A destination that holds a file of its own, a folder and an earlier export's file of the name the first hit
    will have."""
    (folder / "out" / "notes").mkdir(parents=True)
    (folder / "out" / "mine.txt").write_bytes(b"mine")
    (folder / "out" / first_name).write_bytes(b"an earlier export")
    return folder / "out"


def test_round3_two_hits_whose_names_clean_alike_give_two_files(renamed_db, round3, tmp_path, capsys):
    csv = round3 / "export" / "dup_rank.csv"
    rows = pd.read_csv(csv)
    assert main(["export", str(renamed_db.path), "--hits", str(csv), "--format", "bvh", "--out",
                 str(tmp_path / "out")]) == 0
    assert f"{len(rows)} file(s) written" in capsys.readouterr().out
    files = sorted((tmp_path / "out").iterdir())
    assert [f.name for f in files] == ["001_doc4_a_b_0-70.bvh", "001_doc6_a_b_0-70.bvh"]
    for f, doc in zip(files, rows["doc_id"]):
        assert _metadata(f.read_bytes())["doc_id"] == doc
        assert _frame_lines(f.read_bytes()) == _frame_lines(Path(renamed_db.document(doc)["path"]).read_bytes())[:70]


def test_the_same_hit_twice_is_refused_naming_both_rows(renamed_db, tmp_path):
    hits = pd.DataFrame({"rank": [1, 2, 1], "doc_id": [4, 6, 4], "start": [0, 0, 0], "end": [70, 70, 70]})
    with pytest.raises(ParameterError, match=r"rows 1 and 3 are the same hit \(rank 1, document 4, frames 0:70\)"):
        export_hits(renamed_db, hits, tmp_path / "out")
    assert _tree(tmp_path) == {}


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.tuples(st.integers(1, 3), st.sampled_from([0, 4, 6, 9]), st.integers(0, 20),
                               st.integers(1, 20)), min_size=1, max_size=6, unique=True))
def test_every_row_is_its_own_file_in_the_folder_and_in_the_zip(renamed_db, tmp_path, rows):
    """Random hit tables of documents whose names clean alike (and one cut to fit 255 bytes): one file per row,
    each naming its row, the zip holding the same names and bytes."""
    hits = pd.DataFrame(rows, columns=["rank", "doc_id", "start", "length"])
    hits["end"] = hits["start"] + hits["length"]
    with tempfile.TemporaryDirectory(dir=tmp_path) as folder:
        paths = export_hits(renamed_db, hits, Path(folder) / "out", search="random")
        assert len(paths) == len(hits) == len(os.listdir(Path(folder) / "out"))
        assert all(len(os.fsencode(p.name)) <= 255 for p in paths)
        for p, row in zip(paths, hits.itertuples()):
            meta = _metadata(p.read_bytes())
            assert (meta["rank"], meta["doc_id"], meta["frames"]) == (row.rank, row.doc_id, [row.start, row.end])
        archive = zipfile.ZipFile(io.BytesIO(hits_zip(renamed_db, hits, search="random")))
        assert archive.namelist() == [p.name for p in paths]
        assert all(archive.read(p.name) == p.read_bytes() for p in paths)


def _fail_third(monkeypatch, where: str, out: Path) -> None:
    """Make the third hit fail while it is made, written, or moved into the existing ``out``."""
    import mocapviz.export.hits as hits_module
    from mocapviz import store

    calls = []

    def third(real, error, wanted=lambda *a, **k: True):
        def call(*args, **kwargs):
            calls.append(wanted(*args, **kwargs))
            if sum(calls) == 3 and calls[-1]:
                raise error
            return real(*args, **kwargs)
        return call

    if where == "made":
        monkeypatch.setattr(hits_module, "stretch_files", third(hits_module.stretch_files, SourceFileError("gone")))
    elif where == "written":
        monkeypatch.setattr(store, "atomic_write", third(store.atomic_write, OSError(28, "No space left on device")))
    else:
        monkeypatch.setattr(os, "rename", third(os.rename, OSError(28, "No space left on device"),
                                                lambda src, dst: Path(dst).parent == out))


@pytest.mark.parametrize("where, existing", [("made", False), ("made", True), ("written", False),
                                             ("written", True), ("moved", True)])  # fmt: skip
def test_a_failure_at_the_third_hit_leaves_the_destination_as_it_was(renamed_db, round3, tmp_path, monkeypatch,
                                                                     where, existing):
    csv = round3 / "export" / "partial.csv"
    first = next(iter(hit_files(renamed_db, csv)))
    out = _existing_destination(tmp_path, first) if existing else tmp_path / "out"
    before = _tree(tmp_path)
    _fail_third(monkeypatch, where, out)
    with pytest.raises((SourceFileError, OSError)):
        export_hits(renamed_db, csv, out)
    monkeypatch.undo()
    assert _tree(tmp_path) == before
    assert len(export_hits(renamed_db, csv, out)) == 4  # the reproducer's third hit (doc 9) itself exports


def test_a_real_full_file_system_at_the_third_hit_leaves_nothing(renamed_db, tmp_path):
    """A real process whose files may not grow past a limit (RLIMIT_FSIZE, between the first two hits' sizes and
    the third's: EFBIG, as a full disk's ENOSPC) exports nothing, into a new or an existing folder."""
    import resource

    hits = pd.DataFrame({"doc_id": [0, 1, 2, 3], "start": [0, 0, 0, 0], "end": [10, 10, renamed_db.document(2)[
        "n_frames"], 10]})
    hits.to_csv(tmp_path / "hits.csv", index=False)
    files = hit_files(renamed_db, hits)
    sizes = [len(data) for data in files.values()]
    limit = (max(sizes[:2]) + sizes[2]) // 2
    assert sizes[2] > limit > max(sizes[:2] + sizes[3:])

    def small_files():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    for out in (tmp_path / "new", _existing_destination(tmp_path, next(iter(files)))):
        before = _tree(tmp_path)
        run = _cli("export", renamed_db.path, "--hits", tmp_path / "hits.csv", "--format", "bvh", "--out", out,
                   preexec_fn=small_files)
        _, err = run.communicate(timeout=120)
        assert run.returncode == 1 and "File too large" in err, err
        assert _tree(tmp_path) == before


@pytest.mark.parametrize("signal_name", ["SIGTERM", "SIGKILL"])
def test_an_export_killed_at_the_third_hit_leaves_the_destination_as_it_was(renamed_db, round3, tmp_path,
                                                                            signal_name):
    """A real ``mocapviz export`` paused at its third hit (two written) and killed: SIGTERM leaves nothing;
    SIGKILL leaves the destination as it was and a hidden folder that the next export into it removes, never one
    of an export that is running."""
    from mocapviz import store

    csv = round3 / "export" / "partial.csv"
    out = tmp_path / "out"
    before = _tree(tmp_path)
    run = _cli("export", renamed_db.path, "--hits", csv, "--format", "bvh", "--out", out, prologue=PAUSE_AT_THIRD_HIT)
    assert run.stdout.readline() == "third hit\n", run.communicate()
    [staging] = store.leftovers(out, ".export")
    assert len(os.listdir(staging)) == 2 and not out.exists()
    if signal_name == "SIGTERM":
        run.send_signal(signal.SIGTERM)
        assert run.wait(timeout=30) == 128 + signal.SIGTERM
        assert _tree(tmp_path) == before
        return
    export_hits(renamed_db, hit_table(renamed_db, [5], [0], [10]), out)  # the running export's folder is kept
    assert store.leftovers(out, ".export") == [staging]
    after_ours = _tree(tmp_path)
    run.kill()
    assert run.wait(timeout=30) == -signal.SIGKILL
    assert _tree(tmp_path) == after_ours  # the destination as the last export left it, and the killed one's folder
    assert len(export_hits(renamed_db, csv, out)) == 4
    assert store.leftovers(out, ".export") == [] and len(os.listdir(out)) == 5


def test_names_and_temporary_names_fit_255_bytes(renamed_db, tmp_path, capsys):
    """Doc 9 (240 x's): its final name cut to 255 bytes, written with the temporaries of an output folder whose
    own name is 255 bytes; store's temporary names of 253- and 255-byte targets (ASCII and two-byte UTF-8) fit."""
    from mocapviz import store

    out = tmp_path / ("o" * 255)
    assert main(["export", str(renamed_db.path), "--doc", "9", "--frames", "0:70", "--format", "bvh", "--out",
                 str(out)]) == 0
    assert "1 file(s) written" in capsys.readouterr().out
    [f] = out.iterdir()
    assert len(os.fsencode(f.name)) == 255 and f.name.startswith("001_doc9_xxx") and f.name.endswith("x_0-70.bvh")
    assert _frame_lines(f.read_bytes()) == _frame_lines(Path(renamed_db.document(9)["path"]).read_bytes())[:70]
    for name in ("y" * 249 + ".bvh", "y" * 251 + ".bvh", "é" * 125 + ".bvh"):
        with store.temporary_file(tmp_path / name) as tmp:
            assert len(os.fsencode(tmp.name)) <= 255 and tmp.name.startswith(f".{name[:50]}")
        with store.temporary_folder(tmp_path / name) as tmp:
            assert len(os.fsencode(tmp.name)) <= 255
        store.atomic_write(tmp_path / name, b"1")
        assert (tmp_path / name).read_bytes() == b"1"


UMASK_RUN = """
import os, sys
from mocapviz import MotionDB
from mocapviz.cli import main
db, hits, out = sys.argv[1:4]
for mask in (0o022, 0o077):
    os.umask(mask)
    assert main(["export", db, "--hits", hits, "--format", "bvh", "--out", f"{out}/new-{mask:o}"]) == 0
    os.makedirs(f"{out}/old-{mask:o}")
    assert main(["export", db, "--hits", hits, "--format", "glb", "--out", f"{out}/old-{mask:o}"]) == 0
    MotionDB.ingest([MotionDB.open(db).document(0)["path"]], f"{out}/db-{mask:o}", progress=False)
"""


def test_files_are_readable_under_the_users_umask(renamed_db, round3, tmp_path):
    """Under umask 022 every exported and stored file is 0644 and every folder 0755 (under 077: 0600 and 0700),
    in a process of its own (the umask is the process's)."""
    run = subprocess.run([sys.executable, "-c", UMASK_RUN, str(renamed_db.path), str(round3 / "export" / "partial.csv"),
                          str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    for mask, file_mode, folder_mode in ((0o022, 0o644, 0o755), (0o077, 0o600, 0o700)):
        for name in (f"new-{mask:o}", f"db-{mask:o}"):
            assert (tmp_path / name).stat().st_mode & 0o777 == folder_mode, name
        files = [p for name in ("new", "old", "db") for p in (tmp_path / f"{name}-{mask:o}").rglob("*") if p.is_file()]
        assert len(files) > 8 and {p.stat().st_mode & 0o777 for p in files} == {file_mode}, files


def test_a_folder_scan_passes_over_hidden_names_and_load_reads_a_dotted_name_by_its_ending(bandai1_files, tmp_path):
    """round3: ``....bvh`` in a folder aborted its ingest ("unsupported file type '(none)'"). A folder scan passes
    over names starting with a dot (files and folders below it); a file named explicitly is read by its ending."""
    from mocapviz.db.ingest import expand_paths
    from mocapviz.errors import MocapFormatError

    scan = tmp_path / "scan"
    (scan / ".git").mkdir(parents=True)
    for name in ("....bvh", ".x.bvh", ".bvh", ".git/c.bvh"):
        shutil.copy(bandai1_files[0], scan / name)
    (scan / "._a b.bvh").write_bytes(b"\x00\x05\x16\x07\x00\x02\x00\x00Mac OS X")  # a macOS AppleDouble file
    shutil.copy(bandai1_files[1], scan / "a b.bvh")
    assert expand_paths(scan) == expand_paths(str(scan / "*.bvh")) == [(scan / "a b.bvh").resolve()]
    assert main(["ingest", str(scan), "--out", str(tmp_path / "db"), "--no-cluster"]) == 0
    assert MotionDB.open(tmp_path / "db").documents["name"].tolist() == ["a b"]
    want = load(bandai1_files[0]).positions
    for name in ("....bvh", ".x.bvh", ".bvh"):
        assert np.array_equal(load(scan / name).positions, want)
    db = MotionDB.ingest([scan / "....bvh"], tmp_path / "dots", progress=False)
    assert db.documents[["name", "format"]].values.tolist() == [["...", "bvh"]]
    with pytest.raises(MocapFormatError, match=r"\._a b\.bvh, line 1: binary data \(a NUL byte\), not a text file"):
        load(scan / "._a b.bvh")
    assert main(["ingest", str(scan / "._a b.bvh"), "--out", str(tmp_path / "bad"), "--no-cluster"]) == 1
