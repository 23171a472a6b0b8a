"""`mocapviz reproduce`: the files written equal the experiment functions' output on the real HDM05 clips, a
failed write leaves nothing behind, bad names are clear errors."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from mocapviz import reproduction as rp
from mocapviz.cli import main
from mocapviz.experiments.matching import similarity_matrices
from mocapviz.experiments.relational import index_statistics

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def written(hdm05_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    lines = []
    folders = rp.reproduce(["index_statistics", "similarity_matrices"], out, progress=False, log=lines.append)
    return out, folders, lines


def test_tables_equal_the_experiment_functions(written, hdm05_db30):
    out, folders, lines = written
    assert set(folders) == {"index_statistics", "similarity_matrices"} and len(lines) == 2
    table2 = pd.read_csv(out / "index_statistics" / "table2.csv")
    settings = json.loads((out / "index_statistics" / "settings.json").read_text())
    assert settings["database"]["frames"] == 70_996 and settings["full"] is False
    ours = table2[table2["source"] != "paper"].reset_index(drop=True)
    assert ours["frames"].eq(70_996).all() and list(ours["group"]) == ["lower", "upper", "mix"]
    assert (table2["source"] == "paper").sum() == 6

    matches = pd.read_csv(out / "similarity_matrices" / "matches.csv")
    assert "path" not in matches.columns, "array columns are left out of the CSV"
    jog = hdm05_db30.select(label="jogLeftCircle4StepsRstart")["doc_id"].astype(int).tolist()
    ref = similarity_matrices(hdm05_db30, jog[0], k=64, n_matches=3)
    for name, part in matches.groupby("set"):
        expected = ref[name]["matches"]
        assert np.array_equal(part["start"], expected["start"]) and np.allclose(part["cost"], expected["cost"])


def test_index_statistics_table_matches_function(written, hdm05_dir, tmp_path):
    from mocapviz import MotionDB

    out, _, _ = written
    db = MotionDB.ingest([hdm05_dir], tmp_path / "db120", progress=False)
    ours = index_statistics(db, "2005")
    table2 = pd.read_csv(out / "index_statistics" / "table2.csv")
    written_ours = table2[table2["source"] != "paper"].reset_index(drop=True)
    assert written_ours["segments"].tolist() == ours["segments"].tolist()
    assert written_ours["lists"].tolist() == ours["lists"].tolist()


def test_figures_are_png_and_html(written):
    out, _, _ = written
    for stem in ("index_statistics/segments", "index_statistics/bytes_per_segment", "similarity_matrices/fig3"):
        png = (out / f"{stem}.png").read_bytes()
        assert png[:8] == PNG_MAGIC and len(png) > 5_000
        html = (out / f"{stem}.html").read_text()
        assert "<html" in html.lower() and "bokeh" in html.lower()
    assert not [p for p in out.iterdir() if p.name.startswith(".")], "no temporary folders left"


def test_failed_write_keeps_the_earlier_result(written, monkeypatch):
    out, _, _ = written
    before = sorted(p.name for p in (out / "index_statistics").iterdir())

    def broken(result, folder):
        (folder / "partial.csv").write_text("half")
        raise OSError("disk full")

    monkeypatch.setattr(rp, "write_result", broken)
    with pytest.raises(OSError, match="disk full"):
        rp.reproduce("index_statistics", out, progress=False, log=lambda line: None)
    assert sorted(p.name for p in (out / "index_statistics").iterdir()) == before
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_unknown_experiment_is_a_clear_error(tmp_path, capsys):
    with pytest.raises(ValueError, match="unknown experiment.*'nope'.*rank_correlations"):
        rp.reproduce(["nope"], tmp_path)
    assert main(["reproduce", "nope", "--out", str(tmp_path)]) == 1
    assert "unknown experiment" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_cli_writes_alignment(hdm05_dir, tmp_path, capsys):
    assert main(["reproduce", "alignment", "--out", str(tmp_path), "--quiet"]) == 0
    assert "alignment:" in capsys.readouterr().out
    summary = pd.read_csv(tmp_path / "alignment" / "summary.csv")
    assert len(summary) == 1 and summary["cost_band"].iloc[0] >= summary["cost_full"].iloc[0] * (1 - 1e-12)
    path = pd.read_csv(tmp_path / "alignment" / "path_full.csv")
    assert path.iloc[0].tolist() == [0, 0] and (np.diff(path.to_numpy(), axis=0) >= 0).all()
    assert (tmp_path / "alignment" / "alignment.png").read_bytes()[:8] == PNG_MAGIC


def test_correlation_matrix_csv_keeps_the_measure_names(hdm05_db30, tmp_path):
    from mocapviz.experiments.correlation import pose_correlations
    from mocapviz.viz.correlation import correlation_heatmap

    sets = ("F15E", "F30E", "F15x3E")
    matrix = pose_correlations(hdm05_db30, rows=sets, columns=sets, n_queries=16, k=32)
    files = rp.write_result(rp.Result(tables={"pose": matrix}, figures={"pose": correlation_heatmap(matrix)}), tmp_path)
    assert {f.name for f in files} == {"pose.csv", "pose.png", "pose.html", "settings.json"}
    back = pd.read_csv(tmp_path / "pose.csv", index_col=0)
    assert list(back.index) == list(back.columns) == list(sets) and back.index.name == "neighbours by"
    np.testing.assert_allclose(back.to_numpy(), matrix.to_numpy())
    assert (tmp_path / "pose.png").read_bytes()[:8] == PNG_MAGIC
