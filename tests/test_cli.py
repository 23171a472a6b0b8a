"""The `mocapviz` command: ingest, info, datasets; one-line errors with non-zero exit."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from mocapviz import MotionDB, datasets
from mocapviz.cli import main

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def sample_dir() -> Path:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    return datasets.sample()


def test_ingest_then_info(sample_dir, tmp_path, capsys):
    out = tmp_path / "db"
    assert main(["ingest", str(sample_dir / "hdm05-cut"), "--out", str(out), "--fps", "30", "--quiet"]) == 0
    assert "22 documents" in capsys.readouterr().out
    db = MotionDB.open(out)
    assert main(["info", str(out), "--documents"]) == 0
    text = capsys.readouterr().out
    total = next(line for line in text.splitlines() if line.startswith("total")).split()
    assert int(total[1]) == 22 and int(total[2]) == db.n_frames
    assert all(name in text for name in db.documents["name"])


def test_datasets_list_and_fetch_sample(capsys):
    assert main(["datasets", "list"]) == 0
    text = capsys.readouterr().out
    for name in ("hdm05-cut", "cmu-asfamc", "bandai-namco-1", "bandai-namco-2"):
        assert name in text
    assert main(["datasets", "fetch", "sample"]) == 0
    assert Path(capsys.readouterr().out.strip()) == datasets.sample()


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["info", "/nonexistent/db"], "not a MotionDB"),
        (["ingest", "/nonexistent/*.amc", "--out", "{tmp}/db"], "no .amc or .bvh files"),
        (["datasets", "fetch", "no-such-archive"], "no-such-archive"),
        (["ingest", "{bad}", "--out", "{tmp}/db2", "--quiet"], "line 4: OFFSET needs three"),
    ],
)
def test_errors_are_one_line_and_exit_1(argv, needle, tmp_path, sample_dir, capsys):
    bad = tmp_path / "broken.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\n")
    argv = [a.format(tmp=tmp_path, bad=bad) for a in argv]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("mocapviz: error:") and needle in err and "\n" not in err


def test_console_script_runs_as_module(sample_dir, tmp_path):
    """The same command through a fresh interpreter (as the installed `mocapviz` script runs it)."""
    res = subprocess.run([sys.executable, "-m", "mocapviz.cli", "info", str(tmp_path)], capture_output=True, text=True, check=False)
    assert res.returncode == 1 and res.stderr.count("\n") == 1 and "not a MotionDB" in res.stderr
