"""`mocapviz check` tells derived data that is merely stale (intact, computed before an ingest added documents:
the row names the command that computes it again, exit status 3) from damaged data (a checksum mismatch: exit
status 1), in `mocapviz.integrity.check`'s table and on the command line; and a check beside a running ingest never
calls an intact database damaged (issue 37: 26 of 38 checks during concurrent ingests said DAMAGED)."""
from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
import textwrap
import time

import pytest

from mocapviz import MotionDB
from mocapviz.cli import main
from mocapviz.features import store_numeric
from mocapviz.integrity import check, rebuild_commands
from mocapviz.relational import index

SETS = ["F15E", "Fp8"]  # a frame set and a PCA set


def _mocapviz(*args, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mocapviz.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env={**os.environ, "PYTHONWARNINGS": "ignore"})  # fmt: skip


@pytest.fixture
def indexed(sample_db, tmp_path) -> MotionDB:
    """A copy of the sample database with its 2005 relational indexes and two numeric sets, all current, and no other
    derived data (the session's sample database gathers what earlier tests computed: other sets, templates)."""
    folder = tmp_path / "db"
    shutil.copytree(sample_db.path, folder, ignore=shutil.ignore_patterns("index", "features", "templates"))
    db = MotionDB.open(folder)
    index.build(db, "2005", progress=False)
    store_numeric(db, SETS, progress=False)
    return db


@pytest.fixture
def new_files(hdm05_dir, c3d_dir, tmp_path) -> list:
    """Ten motion files the sample database does not hold: eight copies of one HDM05 take told apart by a comment
    line (each its own checksum, its ASF beside it) and two CMU C3D trials (their markers are stored after the
    commit)."""
    take = next((hdm05_dir / "amc").glob("HDM_bd_*.amc"))
    files = []
    for i in range(8):
        folder = tmp_path / "new" / f"copy{i}"
        folder.mkdir(parents=True)
        shutil.copy(hdm05_dir / "asf" / "HDM_bd.asf", folder)
        files.append(folder / f"{take.stem}_copy{i}.amc")
        files[-1].write_bytes(f"# copy {i}\n".encode() + take.read_bytes())
    return [*files[:4], c3d_dir / "cmu_07_01.c3d", *files[4:], c3d_dir / "cmu_16_07.c3d"]


def test_an_ingest_leaves_stale_derived_data_that_the_printed_commands_rebuild(indexed, new_files, capsys):
    assert main(["check", str(indexed.path)]) == 0
    # an append through the library leaves the derived data as they were (`mocapviz ingest` brings them up to date
    # itself: tests/test_incremental_derived.py), so they are stale
    MotionDB.open(indexed.path).append([new_files[0]], progress=False)
    report = check(indexed.path).set_index("file")
    derived = [f for f in report.index if f.startswith(("index/", "features/numeric-"))]
    assert len(derived) == 3 + len(SETS)
    assert set(report.loc[derived, "status"]) == {"stale"} and not report.loc[derived, "ok"].any()
    assert (report["status"] != "damaged").all(), report
    assert report.loc["index/relational-2005-mix.npz", "detail"].endswith(
        f"built for generation {indexed.manifest['generation']} ({indexed.n_frames} frames); the database is at "
        f"generation {indexed.manifest['generation'] + 1} ({MotionDB.open(indexed.path).n_frames} frames)")
    where = shlex.quote(str(indexed.path))
    commands = [f"mocapviz index {where}", f"mocapviz features {where} --numeric-sets {','.join(SETS)}"]
    assert rebuild_commands(report.reset_index()) == commands

    cli = _mocapviz("check", indexed.path)
    assert cli.returncode == 3, cli.stderr
    assert "DAMAGED" not in cli.stdout and cli.stdout.count(" stale ") == len(derived)
    assert f"{len(derived)} files of {len(report)} are stale derived data" in cli.stderr
    assert "nothing is damaged); compute them again" in cli.stderr
    assert cli.stderr.strip().splitlines()[-2:] == [f"  {c}" for c in commands]
    for command in commands:  # the commands as printed (in this process, on threads: no cluster to start)
        assert main([*shlex.split(command)[1:], "--no-cluster", "--quiet"]) == 0, command
    after = _mocapviz("check", indexed.path)
    assert after.returncode == 0 and " stale " not in after.stdout and after.stderr == "", after.stderr


def test_a_flipped_byte_is_damaged_even_in_stale_data(indexed, new_files):
    data = indexed.path / "features" / "numeric-F15E.npy"
    raw = bytearray(data.read_bytes())
    raw[-7] ^= 0x10
    data.write_bytes(bytes(raw))
    report = check(indexed.path).set_index("file")
    assert report.loc["features/numeric-F15E.npy", "status"] == "damaged"
    assert "sha256 differs" in report.loc["features/numeric-F15E.npy", "detail"]
    assert set(report["status"]) == {"ok", "damaged"} and (report["status"] == "damaged").sum() == 1
    MotionDB.open(indexed.path).append([new_files[0]], progress=False)  # derived data left as they were
    report = check(indexed.path).set_index("file")  # now stale as well: damaged wins
    assert report.loc["features/numeric-F15E.npy", "status"] == "damaged"
    assert report.loc["features/numeric-Fp8.npy", "status"] == "stale"
    cli = _mocapviz("check", indexed.path)
    assert cli.returncode == 1 and "DAMAGED" in cli.stdout and "numeric-F15E.npy" in cli.stdout
    err = cli.stderr.strip().splitlines()
    assert err[0].startswith(f"mocapviz: error: {indexed.path}: 1 file of ") and " is damaged; 4 stale" in err[0]
    assert "Traceback" not in cli.stderr


def test_derived_data_written_after_the_check_opened_the_database_is_not_stale(indexed, new_files, monkeypatch):
    """The check opened generation G; meanwhile an ingest committed G+1 (a C3D document, its markers stored after
    the commit) and `mocapviz index` rebuilt the index for it. The index and the markers are current, not stale or
    of no document; the numeric sets are as the check opened the database: current for G."""
    from mocapviz import integrity

    opened = MotionDB.open(indexed.path)
    db = opened.append([new_files[4]], progress=False)  # cmu_07_01.c3d
    index.build(db, "2005", progress=False)

    class AsOpened:  # the database as the check opened it, before the ingest; as it is now afterwards
        @staticmethod
        def open(path, verify=False):
            return opened if verify else MotionDB.open(path)

    monkeypatch.setattr(integrity, "MotionDB", AsOpened)
    report = check(indexed.path)
    assert set(report["status"]) == {"ok"}, report[~report["ok"]].to_dict("records")
    assert report["what"].tolist()[-1] == f"markers of document {len(opened)}"
    monkeypatch.undo()
    assert set(check(indexed.path).set_index("what").loc[[f"numeric set {s}" for s in SETS], "status"]) == {"stale"}


_WRITER = textwrap.dedent(
    """
    import sys
    from mocapviz import MotionDB
    from mocapviz.relational import index
    for i, f in enumerate(sys.argv[2:]):  # one ingest per file; every second one rebuilds the index too
        db = MotionDB.open(sys.argv[1]).append([f], progress=False)
        if i % 2:
            index.build(db, "2005", progress=False)
    print(MotionDB.open(sys.argv[1]).manifest["generation"])
    """
)


@pytest.mark.slow
def test_checks_beside_a_running_ingest_never_say_damaged(indexed, new_files):
    """Ten ingests (one file each, two of them C3D with markers stored after the commit; every second one followed
    by an index build, so that an index can be newer than what a check opened) in one process, checks in this one
    and by the command line until the writer is done."""
    generation = indexed.manifest["generation"]
    writer = subprocess.Popen([sys.executable, "-c", _WRITER, str(indexed.path), *map(str, new_files)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    seen, cli_statuses = [], []
    try:
        deadline = time.monotonic() + 240
        while writer.poll() is None and len(seen) < 200 and time.monotonic() < deadline:
            if len(seen) % 3 == 2:
                cli = _mocapviz("check", indexed.path, timeout=120)
                assert cli.returncode in (0, 3) and "DAMAGED" not in cli.stdout, (cli.stdout, cli.stderr)
                cli_statuses.append(cli.returncode)
            report = check(indexed.path)
            assert (report["status"] != "damaged").all(), report[report["status"] == "damaged"].to_dict("records")
            seen.append(report)
        out, err = writer.communicate(timeout=240)
    finally:
        writer.kill()
        writer.wait()
    assert writer.returncode == 0, err
    assert int(out) == generation + len(new_files)
    assert len(seen) >= 5, f"only {len(seen)} checks ran beside the ingests"
    final = check(indexed.path)
    assert set(final["status"]) == {"ok", "stale"}  # the numeric sets are stale, the index of the last round not
    assert (final["what"].str.startswith("markers of document")).sum() == 2 and final.loc[
        final["what"].str.startswith("markers"), "ok"].all()


@pytest.mark.parametrize(("stale", "line"), [(1, "1 file of 3 is stale derived data"), (2, "2 files of 3 are stale")])
def test_the_stale_line_counts_in_number(stale, line, monkeypatch, capsys):
    """mocapviz check's line on stale derived data agrees with its count ("1 file of 3 is ... compute it again")."""
    import pandas as pd

    from mocapviz.cli import database

    rows = [{"file": f"index/relational-2005-{g}.npz", "what": "index", "status": "stale" if i < stale else "ok",
             "ok": i >= stale, "detail": "", "rebuild": "mocapviz index DB" if i < stale else ""}
            for i, g in enumerate(("lower", "upper", "mix"))]  # fmt: skip
    monkeypatch.setattr(database, "check", lambda path: pd.DataFrame(rows))
    assert main(["check", "DB"]) == 3
    err = capsys.readouterr().err
    assert line in err and f"compute {'it' if stale == 1 else 'them'} again with:" in err
