"""benchmarks/report.py: a run of some benchmarks (``python -m benchmarks --only NAME``) rewrites their sections of
benchmarks/REPORT.md and keeps every other section as the report had it, never replacing one by "not run"."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import report


@pytest.fixture
def here(tmp_path, monkeypatch):
    """report.py writing into tmp_path (its REPORT.md and results/) instead of the repository's."""
    monkeypatch.setattr(report, "HERE", tmp_path)
    monkeypatch.setattr(report, "RESULTS", tmp_path / "results")
    (tmp_path / "results").mkdir()
    return tmp_path


def _save(here: Path, name: str, text: str) -> None:
    (here / "results" / f"{name}.md").write_text(text)


def _sections(text: str) -> dict[str, str]:
    return report.existing_sections(text)


def test_a_benchmark_left_out_keeps_its_section_and_one_that_ran_is_replaced(here):
    _save(here, "io", "### io\n\nio figures, first run")
    _save(here, "search", "### search\n\nsearch figures, first run")
    first = report.build(out_dir=here / "results", ran=[name for name, _ in report.SECTIONS])
    assert first == here / "REPORT.md"
    before = _sections(first.read_text())
    assert "io figures, first run" in before["io"] and "search figures, first run" in before["search"]

    # the saved outputs are not committed: a fresh checkout has none, only the report
    for f in (here / "results").glob("*.md"):
        f.unlink()
    _save(here, "startup", "### startup\n\nstartup figures")
    report.build(out_dir=here / "results", ran=["startup"])
    after = _sections((here / "REPORT.md").read_text())
    assert after["io"] == before["io"] and after["search"] == before["search"]  # kept as they were, word for word
    assert "startup figures" in after["startup"]
    assert "not run" not in after["io"] + after["search"]


def test_a_stale_saved_output_does_not_replace_the_report_section_of_a_benchmark_left_out(here):
    (here / "REPORT.md").write_text("# report\n\n## 1. Parse + forward kinematics and MotionDB.ingest (bench_io)\n\n"
                                    "io figures in the report\n")  # fmt: skip
    _save(here, "io", "### io\n\nan old local run")
    _save(here, "startup", "### startup\n\nstartup figures")
    report.build(out_dir=here / "results", ran=["startup"])
    text = (here / "REPORT.md").read_text()
    assert "io figures in the report" in text and "an old local run" not in text
    # reassembling without a run (python -m benchmarks.report) takes every saved output
    report.build(out_dir=here / "results")
    assert "an old local run" in (here / "REPORT.md").read_text()


def test_not_run_only_for_a_section_with_no_figures_anywhere(here):
    _save(here, "startup", "### startup\n\nstartup figures")
    report.build(out_dir=here / "results", ran=["startup"])
    sections = _sections((here / "REPORT.md").read_text())
    assert set(sections) == {"startup"}
    assert (here / "REPORT.md").read_text().count(report.NOT_RUN) == len(report.SECTIONS) - 1
    # a "not run" section of the report is no figures: a saved output (of a benchmark not in this run) fills it
    _save(here, "io", "### io\n\nio figures")
    report.build(out_dir=here / "results", ran=["startup"])
    assert "io figures" in _sections((here / "REPORT.md").read_text())["io"]


def test_sections_are_found_by_their_bench_name_when_a_title_changes(here):
    text = ("# report\n\n## 3. Some older title of the relational benchmark (bench_relational)\n\n"
            "relational figures\n\n## 4. Unknown section\n\nnot kept\n")  # fmt: skip
    assert _sections(text) == {"relational": "relational figures"}


def test_the_committed_report_parses():
    text = (Path(report.__file__).parent / "REPORT.md").read_text()
    sections = _sections(text)
    assert sections, "no section with figures found in benchmarks/REPORT.md"
    assert set(sections) <= {name for name, _ in report.SECTIONS}
