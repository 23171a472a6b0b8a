"""Ingest and feature extraction on a real dask.distributed LocalCluster (2 worker processes) give exactly the
serial results; a worker killed mid-ingest does not change them; the CLI reaches a scheduler by address."""
from __future__ import annotations

import importlib
import os
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

distributed = pytest.importorskip("distributed")
cloudpickle = pytest.importorskip("cloudpickle")

from mocapviz import MotionDB, parallel
from mocapviz.cli import main
from mocapviz.db.batches import document_batches
from mocapviz.errors import MocapFormatError, MocapFormatWarning
from mocapviz.features import load_numeric, relational_features, store_numeric
from mocapviz.relational.index import build

numeric_module = importlib.import_module("mocapviz.features.numeric")
relational_module = importlib.import_module("mocapviz.features.relational")

# the kill plugin below is sent to the workers by value (this module is not importable there)
cloudpickle.register_pickle_by_value(sys.modules[__name__])

FPS = 60  # resampled on ingest, so that the resampling runs on the workers too
SETS = ["F15E", "F30x3E", "Fp16"]  # a frame set, a windowed set, a PCA set (PCA fitted on the database)


@pytest.fixture(scope="module")
def files(hdm05_dir) -> list[Path]:
    """All 287 HDM05 cut clips (about 37k frames at 60 Hz), sorted."""
    found = sorted((hdm05_dir / "amc").rglob("*.amc"))
    assert len(found) > 200
    return found


@pytest.fixture(autouse=True)
def small_batches(monkeypatch):
    """Batches of whole documents of about 4096 frames (not 32768), so that the features of these 37k frames are
    about ten Dask tasks, and their order matters. The client plans the batches; the workers only run them."""
    monkeypatch.setattr(numeric_module, "_BATCH_FRAMES", 4096)
    monkeypatch.setattr(relational_module, "_BATCH_FRAMES", 4096)


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as lc, distributed.Client(lc) as c:  # fmt: skip
        yield c


@pytest.fixture(scope="module")
def serial_db(files, tmp_path_factory) -> MotionDB:
    return MotionDB.ingest(files, tmp_path_factory.mktemp("serial") / "db", fps=FPS, progress=False)


@pytest.fixture(scope="module")
def cluster_db(files, client, tmp_path_factory) -> MotionDB:
    return MotionDB.ingest(files, tmp_path_factory.mktemp("cluster") / "db", fps=FPS, progress=False,
                           scheduler=client)  # fmt: skip


def _assert_same_db(a: MotionDB, b: MotionDB) -> None:
    assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(a.quaternions, b.quaternions, equal_nan=True)
    pd.testing.assert_frame_equal(a.documents, b.documents)


def test_ingest_on_the_cluster_equals_serial(serial_db, cluster_db, files):
    assert len(cluster_db) == len(files) and cluster_db.manifest["generation"] == 1
    _assert_same_db(serial_db, cluster_db)
    # re-running skips every file (by checksum): no new generation
    again = MotionDB.ingest(files, cluster_db.path, fps=FPS, progress=False, scheduler=None)
    assert again.manifest["generation"] == 1


def test_numeric_features_on_the_cluster_equal_serial(serial_db, cluster_db, client):
    a = store_numeric(serial_db, SETS, progress=False)
    b = store_numeric(cluster_db, SETS, progress=False, scheduler=client)
    assert len(document_batches(cluster_db, numeric_module._BATCH_FRAMES)[1]) >= 8  # several tasks per set
    for name in SETS:
        assert a[name].shape == (serial_db.n_frames, b[name].shape[1])
        assert np.array_equal(a[name], b[name]), name
        assert np.array_equal(load_numeric(cluster_db, name), b[name])
    with np.load(serial_db.path / "features" / "pca.npz") as pa, np.load(cluster_db.path / "features" / "pca.npz") as pb:
        for key in ("mean", "components", "explained_variance"):
            assert np.array_equal(pa[key], pb[key]), key


def test_relational_features_and_index_on_the_cluster_equal_serial(serial_db, cluster_db, client):
    values, names = relational_features(serial_db, "2005", progress=False)
    on_cluster, names_cluster = relational_features(cluster_db, "2005", progress=False, scheduler=client)
    assert names == names_cluster and values.shape == (serial_db.n_frames, 31)
    assert np.array_equal(values, on_cluster)
    serial_index = build(serial_db, "2005", progress=False, values=values)
    cluster_index = build(cluster_db, "2005", progress=False, scheduler=client)
    assert serial_index.keys() == cluster_index.keys() == {"lower", "upper", "mix"}
    for group, index in serial_index.items():
        mine, theirs = index._stored(), cluster_index[group]._stored()
        assert mine.keys() == theirs.keys()
        for key in mine:
            assert np.array_equal(mine[key], theirs[key]), (group, key)



def _square_late(x: int) -> int:
    """A task that often finishes after the ones submitted after it; 5 fails late and 7 early."""
    import time

    time.sleep(0.2 if x == 5 else 0.02 * (x % 3))
    if x in (5, 7):
        raise ValueError(f"item {x}")
    return x * x


def test_map_ordered_on_dask_keeps_order_bounds_look_ahead_and_raises_the_first_failure(client):
    assert list(parallel.map_ordered(_square_late, [0, 1, 2, 3, 4, 6, 8, 9], client=client)) == [0, 1, 4, 9, 16, 36, 64, 81]
    got = []
    with pytest.raises(ValueError, match="item 5"):
        for value in parallel.map_ordered(_square_late, range(20), client=client, name="mocapviz-test"):
            got.append(value)  # noqa: PERF402 - the values before the exception
    assert got == [x * x for x in range(5)]
    pulled = []

    def items():
        for i in (0, 1, 2, 3, 4, 6, 8, 9, 10, 11, 12, 13, 14, 15, 16):
            pulled.append(i)
            yield i

    results = parallel.map_ordered(_square_late, items(), client=client)
    assert next(results) == 0
    assert len(pulled) <= parallel.AHEAD_PER_THREAD * parallel.n_threads(client) + 1
    results.close()


class _KillOnce(distributed.WorkerPlugin):
    """Kill the worker process (no clean-up) when it starts its ``after``-th ingest task (a chunk of files), once in the whole
    cluster: the first worker to create ``flag`` dies; the nanny starts a new one."""

    def __init__(self, flag: str, after: int):
        self.flag, self.after, self.started = flag, after, 0

    def transition(self, key, start, finish, *args, **kwargs):
        if finish != "executing" or not str(key).startswith("mocapviz-read"):
            return
        self.started += 1
        if self.started < self.after:
            return
        try:
            os.close(os.open(self.flag, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            return
        os._exit(1)


def test_a_worker_killed_mid_ingest_changes_nothing(files, serial_db, client, tmp_path):
    flag = tmp_path / "killed"
    client.register_plugin(_KillOnce(str(flag), after=2), name="kill-once")
    try:
        db = MotionDB.ingest(files, tmp_path / "db", fps=FPS, progress=False, scheduler=client)
    finally:
        client.unregister_worker_plugin("kill-once")
    assert flag.exists(), "no worker was killed: the test did not test anything"
    _assert_same_db(serial_db, db)
    client.wait_for_workers(2, timeout=60)  # the nanny's replacement, for the tests after this one


def test_a_bad_file_fails_as_in_serial_and_skip_bad_skips_it(files, client, tmp_path):
    bad = tmp_path / "broken.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n")
    out = tmp_path / "db"
    with pytest.raises(MocapFormatError) as err:
        MotionDB.ingest([files[0], bad, files[1]], out, progress=False, scheduler=client)
    assert err.value.path == str(bad) and str(bad) in str(err.value)
    assert not out.exists()  # the database it would have created is not left behind
    with pytest.warns(UserWarning, match="broken.bvh"):
        db = MotionDB.ingest([files[0], bad, files[1]], out, progress=False, scheduler=client, skip_bad=True)
    assert db.documents["name"].tolist() == [files[0].stem, files[1].stem]


def test_format_warnings_of_the_workers_are_issued_here(files, client, tmp_path):
    """A file read on a worker process with a frame left out gives its MocapFormatWarning here, naming it and the
    line (a warning on a worker would only reach the worker's log)."""
    import shutil

    from test_database import cut_in_last_frame

    (tmp_path / "amc").mkdir()
    shutil.copytree(files[0].parent.parent / "asf", tmp_path / "asf")
    cut = Path(shutil.copy(files[0], tmp_path / "amc"))
    line = cut_in_last_frame(cut)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        db = MotionDB.ingest([files[1], cut, files[2]], tmp_path / "db", progress=False, scheduler=client)
    named = [w.message for w in seen if issubclass(w.category, MocapFormatWarning)]
    assert [(Path(w.path), w.line) for w in named] == [(cut.resolve(), line)], [str(w) for w in named]
    assert "last frame" in named[0].reason and len(db) == 3


def test_cli_ingest_on_a_scheduler_by_address(files, serial_db, client, tmp_path, capsys):
    out = tmp_path / "db"
    address = client.scheduler_info()["address"]
    argv = ["ingest", *map(str, files[:8]), "--out", str(out), "--fps", str(FPS), "--scheduler", address, "--quiet"]
    assert main(argv) == 0
    assert "8 documents" in capsys.readouterr().out
    db = MotionDB.open(out)
    n = int(serial_db.documents["n_frames"][:8].sum())
    assert np.array_equal(db.positions, serial_db.positions[:n])
    assert db.documents["sha256"].tolist() == serial_db.documents["sha256"][:8].tolist()
    assert client.status == "running"  # the command disconnected; the cluster it used keeps running


def test_cli_unreachable_scheduler_is_one_line(files, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(parallel, "CONNECT_TIMEOUT", 1.0)
    out = tmp_path / "db"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code = main(["ingest", str(files[0]), "--out", str(out), "--scheduler", "tcp://127.0.0.1:9", "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 1 and len(err.splitlines()) == 1
    assert err.startswith("mocapviz: error: cannot reach dask scheduler at tcp://127.0.0.1:9")
    assert not out.exists()
