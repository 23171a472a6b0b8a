"""The README's demo commands run as written on the demo database (the embedded sample with its indexes and
numeric feature sets, as `make demo` builds it)."""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import pytest

from mocapviz.cli import main

README = Path(__file__).resolve().parent.parent / "README.md"
MARKER = "<!-- demo commands: each line is run by tests/test_readme.py -->"


def demo_commands() -> list[str]:
    text = README.read_text()
    block = re.search(re.escape(MARKER) + r"\s*```sh\n(.*?)```", text, re.DOTALL)
    assert block, f"README.md has no demo command block after {MARKER!r}"
    return [line.strip() for line in block.group(1).splitlines() if line.strip()]


@pytest.fixture(scope="module")
def demo_build(sample_db, tmp_path_factory):
    """A folder laid out like the repository's build/ after `make demo`: sample.mdb with indexes and F15E/F30E."""
    build = tmp_path_factory.mktemp("demo") / "build"
    build.mkdir()
    shutil.copytree(sample_db.path, build / "sample.mdb")
    assert main(["index", str(build / "sample.mdb"), "--no-cluster", "--quiet"]) == 0
    assert main(["features", str(build / "sample.mdb"), "--sets", "F15E,F30E", "--no-cluster", "--quiet"]) == 0
    return build


@pytest.mark.parametrize("command", demo_commands())
def test_readme_demo_command_runs(command, demo_build, capsys):
    words = shlex.split(command)
    assert words[0] == "mocapviz"
    args = [str(demo_build / w.removeprefix("build/")) if w.startswith("build/") else w for w in words[1:]]
    status = main(args)
    out, err = capsys.readouterr()
    assert status == 0, f"{command!r} failed: {err}"
    assert "no matches" not in out and "Empty DataFrame" not in out, f"{command!r} found nothing:\n{out}"
    lines = [line for line in out.splitlines() if re.match(r"\s+1\s", line)]
    assert lines, f"{command!r} printed no ranked row 1:\n{out}"
