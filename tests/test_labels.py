"""mocapviz.io.labels on real label tables: the packaged sample (HDM05, CMU) and the Bandai Namco 1 archive.

The sample tests never need the shared archives; the Bandai tests are skipped, with the reason, without them.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from mocapviz.io import datasets
from mocapviz.io.labels import bandai_labels, labels_for, read_labels_tsv


@pytest.fixture(scope="module")
def module_home(tmp_path_factory):
    home = tmp_path_factory.mktemp("home")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(datasets.HOME_ENV, str(home))
        yield home


@pytest.fixture(scope="module")
def sample(module_home) -> Path:
    return datasets.sample()


@pytest.fixture(scope="module")
def bandai1(module_home, fetch_archive) -> Path:
    return fetch_archive("bandai-namco-1")


@pytest.fixture
def bandai_copy(bandai1, tmp_path) -> Path:
    """A writable Bandai layout holding one real BVH, its json and the real cfg folder; returns the BVH."""
    (tmp_path / "data").mkdir()
    shutil.copytree(bandai1 / "cfg", tmp_path / "cfg")
    bvh = tmp_path / "data" / "dataset-1_bow_active_001.bvh"
    for suffix in (".bvh", ".json"):
        shutil.copyfile((bandai1 / "data" / bvh.name).with_suffix(suffix), bvh.with_suffix(suffix))
    return bvh


def test_bandai_labels_match_every_file_name(bandai1):
    files = sorted((bandai1 / "data").glob("*.bvh"))
    assert len(files) == 174
    for bvh in files:
        _, content, style, _ = bvh.stem.split("_")
        assert bandai_labels(bvh) == {"content": content, "style": style}, bvh.name


def test_labels_for_bandai_uses_content_as_label(bandai1):
    labels = labels_for(bandai1 / "data" / "dataset-1_walk-left_tired_001.bvh")
    assert labels == {"content": "walk-left", "style": "tired", "label": "walk-left"}


def test_bandai_without_json_has_no_labels(bandai_copy):
    bandai_copy.with_suffix(".json").unlink()
    assert bandai_labels(bandai_copy) == {}
    assert labels_for(bandai_copy) == {}


@pytest.mark.parametrize(
    ("text", "error"),
    [
        ('{"content": 6, "style"', "malformed label json"),
        ('{"content": 17, "style": 0}', "content index 17 outside 0..16"),
        ('{"content": 0, "style": -1}', "style index -1 outside 0..14"),
        ('{"content": "bow", "style": 0}', "'content' must be an integer index"),
        ("[6, 11]", "not an object"),
    ],
)
def test_bad_bandai_json_names_the_file(bandai_copy, text, error):
    meta = bandai_copy.with_suffix(".json")
    meta.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError, match=error) as raised:
        bandai_labels(bandai_copy)
    assert str(meta) in str(raised.value)


def test_read_labels_tsv_types_and_paths(sample):
    hdm05 = read_labels_tsv(sample / "hdm05-cut" / "labels.tsv")
    assert list(hdm05.columns) == ["file", "actor", "class", "take", "frames", "fps", "split", "path"]
    assert hdm05[["take", "frames", "fps"]].dtypes.map(str).eq("int64").all()
    assert all(Path(p).is_absolute() and Path(p).is_file() for p in hdm05["path"])
    cmu = read_labels_tsv(sample / "cmu-asfamc" / "labels.tsv").set_index("file")
    assert cmu.loc["amc/martialwalk/135_08.amc", "cmu_trial"] == "08"
    assert cmu.loc["amc/mjackson/131_01.amc", "cmu_trial"] == "01"
    assert cmu["fps"].tolist() == [120, 120]


def test_labels_for_hdm05_clip(sample):
    labels = labels_for(sample / "hdm05-cut" / "amc" / "HDM_dg_kickLFront1Reps_017_120.amc")
    assert labels == {
        "actor": "dg",
        "class": "kickLFront1Reps",
        "take": 17,
        "frames": 129,
        "fps": 120,
        "split": "train",
        "label": "kickLFront1Reps",
    }


def test_labels_for_cmu_trial_two_levels_down(sample):
    labels = labels_for(sample / "cmu-asfamc" / "amc" / "mjackson" / "131_01.amc")
    assert labels["label"] == "Start Walk Stop"
    assert (labels["cmu_subject"], labels["cmu_trial"], labels["asf"]) == ("131", "01", "asf/mjackson.asf")


def test_labels_for_unlisted_file_is_empty(sample, tmp_path):
    assert labels_for(sample / "hdm05-cut" / "asf" / "HDM_dg.asf") == {}
    assert labels_for(tmp_path / "walk.amc") == {}


def test_labels_for_rereads_a_changed_table(sample, tmp_path):
    folder = shutil.copytree(sample / "hdm05-cut", tmp_path / "hdm05-cut")
    clip = folder / "amc" / "HDM_mm_squat1Reps_037_120.amc"
    assert labels_for(clip)["label"] == "squat1Reps"
    table = folder / "labels.tsv"
    table.write_text(table.read_text(encoding="utf-8").replace("\tsquat1Reps\t", "\tsquat\t"), encoding="utf-8")
    stat = table.stat()
    os.utime(table, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
    assert labels_for(clip)["label"] == "squat"
