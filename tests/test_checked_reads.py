"""Nothing silently wrong on read (issue 29): every block of a frame array or numeric feature set verified by its xxh3
when first read, manifests checked against one schema, readers never broken by a commit (real processes), and the
small ones (a folder left holding only a lock, a kNN query whose exclusion leaves nothing).

Real clips of the embedded sample; the commits of the reader/writer test append copies of sample documents (derived
data, said here) so that one writer can commit hundreds of generations in seconds.
"""

import json
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import xxhash

from mocapviz import MotionDB, MotionDBError, ParameterError
from mocapviz.checked_map import CheckedMap, open_checked, verified_blocks
from mocapviz.cli import main
from mocapviz.io import datasets
from mocapviz.store import fingerprint


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    return MotionDB.ingest(datasets.sample(), tmp_path_factory.mktemp("ref") / "db", progress=False)


def _copy(db, folder):
    shutil.copytree(db.path, folder)
    return folder


def _manifest(folder):
    return json.loads((folder / "manifest.json").read_text())


# ------------------------------------------------------------------------------------------ blocks verified on read
def _small_blocks(path, block=4096):
    """A fingerprint of ``path`` with small blocks (the stored one uses 16 MiB: the sample is one block)."""
    data = path.read_bytes()
    return {"size": len(data), "block": block,
            "xxh3": [xxhash.xxh3_64_hexdigest(data[i : i + block]) for i in range(0, len(data), block)]}  # fmt: skip


@pytest.fixture
def damaged(reference, tmp_path):
    """The sample's positions with one byte flipped in the middle: (map, damaged row, fingerprint, file)."""
    f = tmp_path / "positions.npy"
    shutil.copy(reference.path / reference.manifest["arrays"]["positions"], f)
    fp = _small_blocks(f)
    raw = bytearray(f.read_bytes())
    at = len(raw) // 2
    raw[at] ^= 0xFF
    f.write_bytes(bytes(raw))
    arr = open_checked(f, fp)
    offset = np.load(f, mmap_mode="r").offset  # (the .npy header's length)
    return arr, (at - offset) // arr.strides[0], fp, f


def test_rows_away_from_a_damaged_block_read_and_the_block_is_named_when_touched(damaged, reference):
    arr, row, fp, f = damaged
    assert isinstance(arr, CheckedMap)
    np.testing.assert_array_equal(arr[:100], reference.positions[:100])  # other blocks: read, equal
    np.testing.assert_array_equal(arr[[0, 5, -1]], reference.positions[[0, 5, -1]])
    block = (len(f.read_bytes()) // 2) // fp["block"]
    message = rf"positions.npy: bytes {block * 4096:,}–{(block + 1) * 4096:,} \(block {block + 1} of {len(fp['xxh3'])}\)"
    for touch in (lambda: arr[row], lambda: arr[row - 3 : row + 3], lambda: arr[[1, row]], lambda: arr[::7][row // 7],
                  lambda: arr[np.arange(len(arr)) == row]):  # fmt: skip
        with pytest.raises(MotionDBError, match=message):
            touch()


@pytest.mark.parametrize("use", ["sum", "mean", "reshape", "copy", "astype", "add", "all-slice", "ellipsis"])
def test_whole_array_uses_verify_every_block(damaged, use):
    arr = damaged[0]
    run = {"sum": lambda: arr.sum(), "mean": lambda: np.mean(arr), "reshape": lambda: arr.reshape(len(arr), -1),
           "copy": lambda: arr.copy(), "astype": lambda: arr.astype(np.float64), "add": lambda: arr + 1.0,
           "all-slice": lambda: arr[:], "ellipsis": lambda: arr[..., 0]}[use]  # fmt: skip
    with pytest.raises(MotionDBError, match=r"positions.npy: bytes .* differ from what was written"):
        run()


def test_a_block_is_hashed_once_per_process_and_a_deleted_file_is_still_checked_from_its_map(reference, tmp_path):
    f = tmp_path / "positions.npy"
    shutil.copy(reference.path / reference.manifest["arrays"]["positions"], f)
    arr = open_checked(f, _small_blocks(f))
    f.unlink()  # (a later commit deleted this generation: the map still holds it, and is still checked)
    np.testing.assert_array_equal(arr[10:20], reference.positions[10:20])
    assert type(arr[10:20]) is np.ndarray


def test_a_same_size_edit_of_the_frames_is_refused_by_a_search_not_answered(reference, tmp_path):
    """Positions + 30 cm on one document: with exit 0 and other answers before; now the search names the file."""
    folder = _copy(reference, tmp_path / "db")
    arr = folder / _manifest(folder)["arrays"]["positions"]
    data = np.load(arr, mmap_mode="r+")
    data[reference.frames(7)] += 30.0
    data.flush()
    del data
    db = MotionDB.open(folder)  # sizes agree: opening is instant and says nothing
    with pytest.raises(MotionDBError, match=rf"{arr.name}: bytes 0–[\d,]+ \(block 1 of 1\) differ .* damaged"):
        db.motion(7)
    assert main(["search", str(folder), "--example", "7"]) == 1


def test_numeric_features_are_verified_on_first_load(tmp_path, reference):
    from mocapviz.features import load_numeric, store_numeric

    folder = _copy(reference, tmp_path / "db")
    db = MotionDB.open(folder)
    store_numeric(db, ["F15E"], progress=False)
    f = folder / "features" / "numeric-F15E.npy"
    np.testing.assert_array_equal(load_numeric(db, "F15E")[:], np.load(f))
    data = np.load(f, mmap_mode="r+")
    data[100] *= 1.5  # F15E x 1.5 on one frame, same size
    data.flush()
    del data
    with pytest.raises(MotionDBError, match=r"numeric-F15E.npy: bytes .* differ from what was written"):
        load_numeric(db, "F15E")


def test_verified_blocks_without_block_hashes_checks_nothing(tmp_path):
    f = tmp_path / "a.npy"
    np.save(f, np.arange(10.0))
    verified_blocks(f, None)
    verified_blocks(f, {"size": 208, "sha256": "0" * 64})  # (a fingerprint from before blocks were hashed)
    assert type(open_checked(f, {"size": 208, "sha256": "0" * 64})) is np.memmap


def test_check_adds_block_hashes_to_an_older_manifest_after_verifying_its_sha256(reference, tmp_path):
    folder = _copy(reference, tmp_path / "db")
    manifest = _manifest(folder)
    for fp in manifest["checksums"].values():
        fp.pop("block"), fp.pop("xxh3")
    (folder / "manifest.json").write_text(json.dumps(manifest))
    assert type(MotionDB.open(folder).positions) is np.memmap  # older manifest: sizes only
    assert main(["check", str(folder)]) == 0
    after = _manifest(folder)["checksums"]
    for name, fp in after.items():
        assert fp == fingerprint(folder / name)
    assert isinstance(MotionDB.open(folder).positions, CheckedMap)


def test_check_adds_block_hashes_to_an_older_numeric_set(reference, tmp_path):
    from mocapviz.features import load_numeric, store_numeric

    folder = _copy(reference, tmp_path / "db")
    db = MotionDB.open(folder)
    store_numeric(db, ["F15E"], progress=False)
    header_file, data = folder / "features" / "numeric-F15E.json", folder / "features" / "numeric-F15E.npy"
    header = json.loads(header_file.read_text())
    header["data"] = {k: header["data"][k] for k in ("size", "sha256")}  # as written before block hashes were kept
    header_file.write_text(json.dumps(header))
    assert main(["check", str(folder)]) == 0
    assert json.loads(header_file.read_text())["data"] == fingerprint(data)
    values = np.load(data, mmap_mode="r+")
    values[7] += 1.0
    values.flush()
    del values
    with pytest.raises(MotionDBError, match=r"numeric-F15E.npy: bytes .* differ"):
        load_numeric(db, "F15E")


# ------------------------------------------------------------------------------------------------ manifest schema
_BAD_MANIFESTS = {
    "no arrays": (lambda m: m.pop("arrays"), r"no 'arrays'"),
    "no documents": (lambda m: m.pop("documents"), r"no 'documents'"),
    "arrays a list": (lambda m: m.update(arrays=list(m["arrays"].values())), r"'arrays' is \[.*it must be"),
    "array outside the folder": (lambda m: m["arrays"].update(positions="../positions.g1.npy"), r"'arrays' is"),
    "absolute array path": (lambda m: m["arrays"].update(quaternions="/etc/hosts"), r"'arrays' is"),
    "documents outside": (lambda m: m.update(documents="../x/documents.g1.parquet"), r"'documents' is"),
    "frames a string": (lambda m: m.update(n_frames="5543"), r"'n_frames' is \"5543\", it must be a whole number"),
    "unknown key": (lambda m: m.update(extra=1), r"unknown key 'extra'"),
    "checksums a list": (lambda m: m.update(checksums=[]), r"'checksums' is \[\]"),
    "joints renamed": (lambda m: m["joint_names"].reverse(), r"'joint_names'"),
}


@pytest.mark.parametrize("case", sorted(_BAD_MANIFESTS))
def test_a_malformed_manifest_is_a_typed_error_from_the_api_info_knn_and_check(reference, tmp_path, case, capsys):
    folder = _copy(reference, tmp_path / "db")
    manifest = _manifest(folder)
    edit, message = _BAD_MANIFESTS[case]
    edit(manifest)
    (folder / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(MotionDBError, match=rf"manifest.json: damaged manifest: {message}"):
        MotionDB.open(folder)
    for command in (["info", str(folder)], ["knn", str(folder), "--frame", "3:10"], ["check", str(folder)]):
        assert main(command) == 1, command
        out, err = capsys.readouterr()
        assert "damaged manifest" in out + err and "Traceback" not in out + err


# ----------------------------------------------------------------------------------- readers during commits
_WRITER = textwrap.dedent(
    """
    import sys, time
    from mocapviz import MotionDB
    db = MotionDB.open(sys.argv[1])
    clips = [db.motion(d) for d in (3, 7, 11)]
    stop = time.monotonic() + float(sys.argv[2])
    commits = 0
    while time.monotonic() < stop:
        db = db.append_motions([clips[commits % 3]])  # a copy of a sample document (derived data)
        commits += 1
    print(commits)
    """
)
_READER = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    from mocapviz import MotionDB, MocapvizError
    expected = {d: float(np.asarray(MotionDB.open(sys.argv[1]).motion(d).positions, np.float64).sum()) for d in (3, 7)}
    stop, reads, errors = time.monotonic() + float(sys.argv[2]), 0, []
    while time.monotonic() < stop:
        try:
            db = MotionDB.open(sys.argv[1])
            for d in (3, 7):
                if float(np.asarray(db.motion(d).positions, np.float64).sum()) != expected[d]:
                    errors.append(f"document {d} changed")
            reads += 1
        except MocapvizError as exc:
            errors.append(str(exc))
    print(reads, len(errors), errors[:3])
    """
)


def test_readers_are_never_broken_by_repeated_commits(reference, tmp_path):
    """One writer commits as fast as it can while two reader processes open the database and read two documents in
    a loop: no read fails or sees other frames (before: "…g1.npy: cannot read" when a commit deleted the files of
    the generation a reader had just read the manifest of)."""
    folder = _copy(reference, tmp_path / "db")
    seconds = "8"
    writer = subprocess.Popen([sys.executable, "-c", _WRITER, str(folder), seconds], stdout=subprocess.PIPE, text=True)
    readers = [subprocess.Popen([sys.executable, "-c", _READER, str(folder), seconds], stdout=subprocess.PIPE,
                                text=True) for _ in range(2)]  # fmt: skip
    commits = int(writer.communicate(timeout=120)[0])
    results = [r.communicate(timeout=120)[0].split(maxsplit=2) for r in readers]
    print(f"{commits} commits, reads and errors per reader: {[(int(r[0]), int(r[1])) for r in results]}")
    assert commits >= 5
    for reads, errors, first in results:
        assert int(reads) >= 20 and int(errors) == 0, first
    generations = {int(f.name.split(".g")[1].split(".")[0]) for f in folder.iterdir() if ".g" in f.name}
    assert len(generations) == 2  # the current one and the one before; older ones deleted


# ---------------------------------------------------------------------------------------------------- small ones
def test_a_folder_holding_only_a_lock_file_is_ingested_into(tmp_path):
    out = tmp_path / "db"
    out.mkdir()
    (out / ".lock").touch()  # left by a killed ingest that was removing the database it created
    (out / ".positions.g0.npy.x1.tmp").touch()
    amc = datasets.sample() / "hdm05-cut" / "amc"
    db = MotionDB.ingest(amc / "HDM_dg_squat1Reps_033_120.amc", out, progress=False)
    assert len(db) == 1 and db.n_frames == 159
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(MotionDBError, match="exists and is not an empty directory"):
        MotionDB.create(tmp_path / "other")


def test_knn_with_every_frame_excluded_is_an_error_not_rows_of_inf(reference):
    from mocapviz.similarity.knn import KnnIndex

    index = KnnIndex(np.arange(20.0)[:, None])
    with pytest.raises(ParameterError, match=r"query 1 leaves out frames 0:20, every indexed frame"):
        index.query([[1.0], [2.0]], k=2, exclude=[[5, 6], [0, 20]])
    d, i = index.query([1.0], k=2, exclude=[1, 20])  # one left: it, then padding (as with a radius)
    assert i.tolist() == [0, -1] and d[1] == np.inf
    _, i = index.query([1.0], k=2, exclude=[0, 18])
    assert i.tolist() == [18, 19]
