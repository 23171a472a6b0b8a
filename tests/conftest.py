"""Shared fixtures: the real archives (unpacked once into a cache) and small helpers over them.

The archives come from :func:`mocapviz.datasets.fetch` (base location ``MOCAPVIZ_DATA_URL`` or the shared
data folder beside the repository). The cache defaults to ``<repo>/.cache/mocapviz`` so that a second test
run does not unpack again. Without the archives the tests that need them are skipped, with the reason.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: runs over a whole archive and takes more than 10 s")


def _fetch(name: str) -> Path:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    try:
        from mocapviz import datasets
    except ImportError as exc:  # pragma: no cover - the package is broken, not the data missing
        pytest.skip(f"mocapviz.datasets cannot be imported ({exc}); real-data tests need it")
    try:
        datasets.data_url()
    except datasets.DatasetError as exc:
        pytest.skip(f"real data archive {name!r} not available: {exc}")
    try:
        folder = datasets.fetch(name)
    except datasets.DatasetError as exc:
        if "not found" in str(exc):
            pytest.skip(f"real data archive {name!r} not available: {exc}")
        raise
    return Path(folder)


@pytest.fixture(scope="session")
def hdm05_dir() -> Path:
    """The unpacked HDM05 cut clips: ``asf/``, ``amc/``, ``labels.tsv``."""
    return _fetch("hdm05-cut")


@pytest.fixture(scope="session")
def cmu_dir() -> Path:
    """The unpacked CMU trials: ``asf/``, ``amc/<group>/``, ``labels.tsv``."""
    return _fetch("cmu-asfamc")


@pytest.fixture(scope="session")
def bandai1_dir() -> Path:
    """The unpacked Bandai Namco dataset 1: ``data/*.bvh`` (+ ``.json``), ``cfg/``."""
    return _fetch("bandai-namco-1")


@pytest.fixture(scope="session")
def bandai2_dir() -> Path:
    """The unpacked Bandai Namco dataset 2 (2,902 BVH files, about 0.5 GB unpacked): for slow tests only."""
    return _fetch("bandai-namco-2")


@pytest.fixture(scope="session")
def hdm05_labels(hdm05_dir):
    """``labels.tsv`` of HDM05 (file, actor, class, take, frames, fps, split)."""
    import pandas as pd

    return pd.read_csv(hdm05_dir / "labels.tsv", sep="\t")


@pytest.fixture(scope="session")
def bandai1_files(bandai1_dir) -> list[Path]:
    """All BVH files of Bandai Namco 1, sorted."""
    files = sorted((bandai1_dir / "data").glob("*.bvh"))
    assert files, f"no BVH files under {bandai1_dir / 'data'}"
    return files


@pytest.fixture(scope="session")
def hdm05_db30(hdm05_dir, tmp_path_factory):
    """All 287 HDM05 cut clips ingested at 30 Hz (the papers' kNN rate), labelled; shared by the test modules."""
    from mocapviz import MotionDB

    return MotionDB.ingest([hdm05_dir], tmp_path_factory.mktemp("hdm05-30") / "db", fps=30, progress=False, n_jobs=2)


@pytest.fixture(scope="session")
def cmu_db30(cmu_dir, tmp_path_factory):
    """The 32 shared CMU trials ingested at 30 Hz."""
    from mocapviz import MotionDB

    return MotionDB.ingest([cmu_dir], tmp_path_factory.mktemp("cmu-30") / "db", fps=30, progress=False, n_jobs=2)
