"""Storage in one place (issue 38, item 4): the database folder's layout is named by ``mocapviz.db.layout`` alone, and
every derived file of arrays is written and read by ``mocapviz.db.arrays``: a round trip keeps arrays and header, a
changed byte is a MotionDBError naming the file, another version is stale (for ``mocapviz check`` too: exit 3)."""
from __future__ import annotations

import ast
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from mocapviz.db import layout
from mocapviz.db.arrays import load_arrays, save_arrays
from mocapviz.errors import MotionDBError, StaleDataError

PACKAGE = Path(__file__).resolve().parent.parent / "mocapviz"
FORMAT = "mocapviz.Test"


def _arrays() -> dict:
    return {"f": np.linspace(0, 1, 12, dtype=np.float32).reshape(3, 4), "i": np.arange(5, dtype=np.int64),
            "b": np.array([True, False, True]), "s": np.array(["a", "bc"]), "empty": np.zeros((0, 24, 3))}  # fmt: skip


def test_arrays_and_header_round_trip(tmp_path):
    header = {"meta": {"generation": 3, "names": ["x", "y"]}, "ratio": 0.1, "none": None}
    save_arrays(tmp_path / "sub" / "a.npz", _arrays(), header, FORMAT, 2)  # the folder is created
    arrays, back = load_arrays(tmp_path / "sub" / "a.npz", FORMAT, 2, "test file")
    assert sorted(arrays) == sorted(_arrays())
    for name, a in _arrays().items():
        assert arrays[name].dtype == a.dtype and arrays[name].shape == a.shape
        np.testing.assert_array_equal(arrays[name], a)
    assert {k: back[k] for k in header} == header and (back["format"], back["version"]) == (FORMAT, 2)
    assert back["written_by"].startswith("mocapviz ") and len(back["sha256"]) == 64
    assert [p.name for p in (tmp_path / "sub").iterdir()] == ["a.npz"]  # no temporary file left


def test_a_flipped_bit_anywhere_reads_back_as_written_or_is_a_motiondb_error_naming_the_file(tmp_path):
    """Every byte of a saved file, three of its bits in turn: never another exception, never other values (a bit of
    the zip's bookkeeping that nothing reads, a time stamp, may change unnoticed)."""
    path = tmp_path / "a.npz"
    save_arrays(path, _arrays(), {"x": 1}, FORMAT, 1)
    good, outcomes = path.read_bytes(), set()
    for at in range(len(good)):
        for bit in (0x01, 0x20, 0x80):
            raw = bytearray(good)
            raw[at] ^= bit
            path.write_bytes(bytes(raw))
            try:
                arrays, header = load_arrays(path, FORMAT, 1, "test file", "rebuild it")
            except MotionDBError as exc:
                assert str(exc).startswith(f"{path}: ") and str(exc).endswith("; rebuild it"), (at, bit, exc)
                assert not isinstance(exc, StaleDataError), (at, bit, exc)
                outcomes.add("damaged")
                continue
            assert header["x"] == 1 and sorted(arrays) == sorted(_arrays()), (at, bit)
            for name, a in _arrays().items():
                assert arrays[name].dtype == a.dtype and np.array_equal(arrays[name], a), (at, bit, name)
            outcomes.add("as written")
    assert outcomes == {"damaged", "as written"}


def test_arrays_changed_under_their_header_are_damaged(tmp_path):
    path = tmp_path / "a.npz"
    save_arrays(path, _arrays(), {}, FORMAT, 1)
    with np.load(path) as z:  # a readable archive, the same header, one value changed
        arrays = {k: z[k] for k in z.files}
    arrays["i"][2] += 1
    np.savez(path, **arrays)
    with pytest.raises(MotionDBError, match=rf"^{path}: its arrays differ from those written \(sha256\): the test "
                                            r"file is damaged; rebuild it$"):  # fmt: skip
        load_arrays(path, FORMAT, 1, "test file", "rebuild it")
    path.write_bytes(b"not an archive")
    with pytest.raises(MotionDBError, match=rf"^{path}: not a readable test file \(not an .npz archive\)"):
        load_arrays(path, FORMAT, 1, "test file")
    with pytest.raises(MotionDBError, match=r"none.npz: not a readable test file"):
        load_arrays(tmp_path / "none.npz", FORMAT, 1, "test file")


def test_another_version_is_stale_and_another_format_damaged(tmp_path):
    path = tmp_path / "a.npz"
    save_arrays(path, _arrays(), {}, FORMAT, 1)
    with pytest.raises(StaleDataError, match=rf"^{path}: stale: a {FORMAT} version 1 file; this mocapviz reads "
                                             r"version 2; rebuild it$"):  # fmt: skip
        load_arrays(path, FORMAT, 2, "test file", "rebuild it")
    with pytest.raises(MotionDBError, match=r"not a mocapviz.Other version 1 file \(mocapviz.Test version 1 found\)") \
            as caught:  # fmt: skip
        load_arrays(path, "mocapviz.Other", 1, "test file")
    assert not isinstance(caught.value, StaleDataError)


def test_files_of_an_older_version_are_stale_for_mocapviz_check(sample_db, tmp_path):
    """A PCA model as mocapviz wrote it before the one format (version 1: its fields as arrays, no checksum) and a
    motion template of version 1 (the sha256 of its values alone) are stale, not damaged: ``mocapviz check`` exits
    with 3 and the loaders say how to write them again."""
    from mocapviz.cli import main
    from mocapviz.features import PCAModel
    from mocapviz.integrity import check
    from mocapviz.relational.templates import MotionTemplate
    from mocapviz.store import digest

    folder = tmp_path / "db"
    shutil.copytree(sample_db.path, folder, ignore=shutil.ignore_patterns("index", "features", "templates"))
    pca, template = layout.pca_file(folder), layout.template_file(folder, "old")
    pca.parent.mkdir()
    np.savez(pca, format=np.str_("mocapviz.PCAModel"), version=np.int64(1), mean=np.zeros(72),
             components=np.eye(1, 72), explained_variance=np.ones(1), total_variance=np.float64(2),
             n_frames=np.int64(10), reference=np.str_("old"))  # fmt: skip
    template.parent.mkdir()
    values = np.full((3, 2), 0.5)
    header = {"format": "mocapviz.MotionTemplate", "version": 1, "features": ["a", "b"], "label": "old",
              "n_examples": 2, "iterations": 1, "meta": {}, "sha256": digest({"values": values})}  # fmt: skip
    np.savez(template, header=np.array(json.dumps(header)), values=values)
    with pytest.raises(StaleDataError, match=r"pca.npz: stale: a mocapviz.PCAModel version 1 file.*`mocapviz features"):
        PCAModel.load(pca)
    with pytest.raises(StaleDataError, match=r"old.npz: stale: .* version 1 file.*`mocapviz template learn`"):
        MotionTemplate.load(template)
    report = check(folder).set_index("file")
    assert report.loc[["features/pca.npz", "templates/old.npz"], "status"].tolist() == ["stale", "stale"]
    assert set(report["status"]) == {"ok", "stale"}
    assert main(["check", str(folder)]) == 3


def test_layout_names_each_file():
    db = Path("DB")
    assert layout.manifest_file(db) == db / "manifest.json"
    assert layout.generation_file(db, "quaternions", 12) == db / "quaternions.g12.npy"
    names = ("documents.g7.parquet", "positions.g0.npy", "manifest.json", "positions.g1.npy.tmp")
    assert [layout.generation_of(n) for n in names] == [7, 0, None, None]
    assert layout.index_file(db, "2006", "mix") == db / "index" / "relational-2006-mix.npz"
    assert (layout.numeric_data(db, "Fp8"), layout.numeric_header(db, "Fp8")) == (
        db / "features" / "numeric-Fp8.npy", db / "features" / "numeric-Fp8.json")  # fmt: skip
    assert layout.template_file(db, "squat") == db / "templates" / "squat.npz"
    assert layout.markers_file(db, "ab12") == db / "markers" / "ab12.npz"


def test_listings_find_what_the_writers_wrote(tmp_path):
    for f in (layout.index_file(tmp_path, "2006", "mix"), layout.index_file(tmp_path, "2005", "lower"),
              tmp_path / "index" / "lower.npz", layout.numeric_header(tmp_path, "F15x3E"),
              layout.numeric_header(tmp_path, "F15E"), layout.template_file(tmp_path, "kick-dg"),
              layout.template_file(tmp_path, "kick"), layout.markers_file(tmp_path, "ff00")):  # fmt: skip
        f.parent.mkdir(exist_ok=True)
        f.touch()
    assert {f.name: s for f, s in layout.index_files(tmp_path).items()} == {
        "lower.npz": "2005", "relational-2005-lower.npz": "2005", "relational-2006-mix.npz": "2006"}  # fmt: skip
    assert layout.numeric_sets(tmp_path) == ["F15E", "F15x3E"]
    assert list(layout.template_files(tmp_path).items()) == [(name, layout.template_file(tmp_path, name))
                                                            for name in ("kick", "kick-dg")]  # by name, not file name
    assert layout.markers_files(tmp_path) == {"ff00": layout.markers_file(tmp_path, "ff00")}
    assert layout.index_files(tmp_path / "nothing") == {} and layout.numeric_sets(tmp_path / "nothing") == []


# ------------------------------------------------------------------------------ nothing else names a file of it
NAMES = {"index", "features", "templates", "markers", "manifest.json", "pca.npz"}  # a folder or file of a MotionDB
PATTERNS = re.compile(r"(^|/)(relational|numeric)-|\.g\{\}\.(npy|parquet)$")  # and generation files
PATH_CALLS = {"Path", "PurePath", "join", "joinpath", "glob", "rglob", "with_name"}
OWNERS = {"mocapviz/db/layout.py", "mocapviz/store.py"}
ALLOWED = {  # (file, name): why it is left, for now
    ("mocapviz/cli.py", "index"): "`mocapviz index` prints Path(db.path) / 'index'; cli.py is being rewritten on the "
                                  "engine (issue 38 item 3): it is to print layout.index_folder(db.path)",
    ("mocapviz/cli.py", "features"): "`mocapviz features` prints Path(db.path) / 'features' (the same rewrite): it is "
                                     "to print layout.features_folder(db.path)",
    ("mocapviz/app/backend.py", "manifest.json"): "the dashboard's cache key stats Path(path) / 'manifest.json'; app/ "
                                                  "is being rewritten on the engine: it is to use layout.manifest_file",
}


def _text(node) -> str | None:
    """A string literal's text, an f-string's with ``{}`` for each field; None for anything else."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
    return None


def _named(text: str) -> bool:
    return text in NAMES or PATTERNS.search(text) is not None


def path_names(source: str) -> list[tuple[int, str]]:
    """(line, text) of every string that names a file or folder of a MotionDB where a path is built: an operand of
    ``/``, or an argument of Path(), os.path.join, joinpath, glob, rglob, with_name."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
            operands = [node.left, node.right]
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", None)) in PATH_CALLS:
            operands = node.args
        else:
            continue
        found += [(o.lineno, o.col_offset, t) for o in operands if (t := _text(o)) is not None and _named(t)]
    return [(line, t) for line, _, t in sorted(found)]


def test_the_scan_finds_a_path_built_by_name_and_nothing_else():
    source = '''
db.path / "index" / f"relational-{s}-{g}.npz"
Path(db.path, "features") / f"numeric-{name}.json"
os.path.join(root, "pca.npz"); folder.glob("numeric-*.json"); path / f"{name}.g{gen}.npy"
row = {"index": 1, "features": []}; print("see DB/features/pca.npz"); raise ValueError(f"numeric-{x} bad")
x = a / "index_of"; y = df["markers"]; layout.index_file(db.path, "2005", "lower")
'''
    assert [t for _, t in path_names(source)] == [
        "index", "relational-{}-{}.npz", "features", "numeric-{}.json", "pca.npz", "numeric-*.json", "{}.g{}.npy"]


def test_only_the_layout_names_the_files_of_a_database():
    found = []
    for f in sorted(PACKAGE.rglob("*.py")):
        rel = f.relative_to(PACKAGE.parent).as_posix()
        if rel not in OWNERS:
            found += [f"{rel}:{line}: {text!r}" for line, text in path_names(f.read_text())
                      if (rel, text) not in ALLOWED]  # fmt: skip
    assert not found, "a path of a MotionDB built outside mocapviz/db/layout.py (ask layout.py):\n" + "\n".join(found)
