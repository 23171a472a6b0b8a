"""The documentation site (docs/conf.py, ``make docs``) builds with warnings as errors, every internal link and
cross-reference resolved, and holds what it is for: the API reference from the docstrings, the CLI reference from
the parser, the notebooks with the outputs of their execution.

The build goes to ``build/docs/html`` with its notebook cache (``build/docs/jupyter_cache``), as ``make docs``: after
it, or a previous run, only changed pages are read again (10 s). From scratch, as in CI, it executes the 13
notebooks: 7 min 36 s on the 2-core machine, 435 s of it the notebooks, so the tests that need the site are slow;
the check of the reference lookup takes 2 s.
"""
from __future__ import annotations

import argparse
import html
import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("sphinx", reason="the docs extra (make docs installs it)")
pytest.importorskip("myst_nb", reason="the docs extra (make docs installs it)")

import mocapviz
from mocapviz.cli.parser import build_parser
from mocapviz.engine.parameters import PARAMETERS

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "build" / "docs" / "html"
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


@pytest.fixture(scope="module")
def references():
    """docs/_ext/references.py, the build's check of the docstrings' cross-references."""
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        yield importlib.import_module("references")
    finally:
        sys.path.remove(str(ROOT / "docs" / "_ext"))


@pytest.fixture(scope="module")
def site() -> Path:
    """The site, built as ``make docs`` builds it (-W --keep-going: any warning fails)."""
    run = subprocess.run([sys.executable, "-m", "sphinx", "-q", "-c", "docs", "-W", "--keep-going", ".", str(OUT)],
                         check=False, cwd=ROOT, capture_output=True, text=True, timeout=3600)  # fmt: skip
    warnings = [line for line in run.stderr.splitlines() if "WARNING:" in line or "ERROR:" in line]
    assert run.returncode == 0, "\n".join(warnings) or run.stderr[-4000:]
    return OUT


def test_references_are_checked_against_the_code(references):
    """A docstring's reference finds what the code would: through a re-export, relative to the documented object,
    an instance attribute; an old (moved) or unknown name finds nothing, so the build fails on it."""
    templates = ["mocapviz.relational.templates.learn_class", "mocapviz.relational.templates"]
    assert references.named_object("mocapviz.engine.Engine", []) is mocapviz.Engine
    assert references.named_object("learn_template", templates).__name__ == "learn_template"
    assert references.named_object("positions", ["mocapviz.db.database.MotionDB"]) is references.ATTRIBUTE
    assert references.named_object("numeric_set", ["mocapviz.similarity.search.SimilaritySearch"]) \
        is references.ATTRIBUTE  # assigned as `self.db, self.numeric_set, self.k = ...`
    for stale in ("mocapviz.sharded", "learn_templates", "mocapviz.relational.templates.nosuch"):
        assert references.named_object(stale, templates) is references.MISSING, stale
        assert not references._external(stale)
    assert references._external("np.ndarray") and references._external("dict")


def _text(source: str) -> str:
    """The text of HTML: tags dropped, entities and typographic quotes undone, white space collapsed."""
    text = html.unescape(re.sub(r"<[^>]+>", " ", source))
    return re.sub(r"\s+", " ", text.replace("\u2019", "'").replace("\u201c", '"').replace("\u201d", '"'))


def _section(page: Path, ident: str) -> str:
    """The text of the <section id=ident> of a page, up to the next section of the same level."""
    source = page.read_text()
    start = source.index(f'<section id="{ident}"')
    depth, end = 0, start
    for tag in re.finditer(r"<(/?)section\b", source[start:]):
        depth += -1 if tag.group(1) else 1
        if depth == 0:
            end = start + tag.end()
            break
    return _text(source[start:end])


@pytest.mark.slow
def test_the_guide_and_its_references_are_pages(site):
    """Every page of docs/ and the repository's pages that docs/ links to are in the site."""
    pages = [*(ROOT / "docs").glob("*.md"), ROOT / "README.md", ROOT / "benchmarks" / "REPORT.md"]
    for page in pages:
        assert (site / page.relative_to(ROOT).with_suffix(".html")).exists(), page
    assert "docs/index.html" in (site / "index.html").read_text()  # the site's root sends to the guide


@pytest.mark.slow
def test_api_reference_documents_the_top_level_and_every_engine_method(site):
    """Each name of ``mocapviz.__all__`` and each public method of the Engine has its entry, from its docstring."""
    page = (site / "docs" / "api.html").read_text()
    ids = set(re.findall(r'<dt class="sig [^"]*" id="([^"]+)"', page))
    wanted = {f"mocapviz.{name}" for name in ("Engine", "MotionDB", "Motion", "load")}
    wanted |= {f"mocapviz.errors.{name}" for name in mocapviz.__all__ if name.endswith(("Error", "Warning"))}
    wanted |= {f"mocapviz.Engine.{name}" for name in vars(mocapviz.Engine)
               if not name.startswith("_") and callable(getattr(mocapviz.Engine, name))}  # fmt: skip
    assert wanted - ids == set()
    first_line = mocapviz.Engine.clips.__doc__.strip().splitlines()[0][:60]
    assert first_line.split("(")[0].strip() in _text(page)


def _commands(parser: argparse.ArgumentParser, path=()):
    """(("search",), its parser), (("template", "learn"), ...), ...: every command of the parser, nested."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield (*path, name), sub
                yield from _commands(sub, (*path, name))


@pytest.mark.slow
def test_cli_reference_lists_every_command_and_option_of_the_parser(site):
    """Each sub-command has its section, holding every option string the parser gives it."""
    page = site / "docs" / "cli.html"
    commands = list(_commands(build_parser()))
    assert {" ".join(path) for path, _ in commands} >= {"search", "find", "template learn", "template search"}
    for path, sub in commands:
        text = _section(page, "mocapviz-" + "-".join(path))
        flags = {flag for action in sub._actions for flag in action.option_strings if flag not in ("-h", "--help")}
        assert flags <= set(re.findall(r"(?<![\w-])(--?[\w-]+)", text)), (path, flags)


@pytest.mark.slow
def test_cli_reference_gives_search_mode_choices_from_the_parser(site):
    """``mocapviz search --mode``: its help as the parser writes it, with the parameter table's choices."""
    search = dict(_commands(build_parser()))[("search",)]
    mode = next(action for action in search._actions if "--mode" in action.option_strings)
    choices = PARAMETERS["mode"].choices
    assert f"one of {', '.join(choices)}" in mode.help
    text = _section(site / "docs" / "cli.html", "mocapviz-search")
    assert "--mode" in text and re.sub(r"\s+", " ", mode.help % {}) in text


@pytest.mark.slow
@pytest.mark.parametrize("notebook", NOTEBOOKS, ids=[n.stem for n in NOTEBOOKS])
def test_notebooks_are_rendered_with_their_outputs(site, notebook):
    """Every notebook is a page with outputs, though stored without: the build executed it."""
    page = (site / "notebooks" / notebook.name).with_suffix(".html").read_text()
    assert page.count('class="cell_output') >= 1


@pytest.mark.slow
def test_a_notebook_output_is_its_computation(site):
    """00_motiondb prints the canonical clip's arrays: 24 joints (positions and quaternions) per frame."""
    text = _text((site / "notebooks" / "00_motiondb.html").read_text())
    assert re.search(r"\(\d+, 24, 3\) \(\d+, 24, 4\)", text)
