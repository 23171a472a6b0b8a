"""The two environment descriptions agree: environment.yml (conda-forge) lists every requirement of
pyproject.toml (dependencies and every extra) with the same version bound."""
from __future__ import annotations

import re
from pathlib import Path

import tomllib

REPO = Path(__file__).resolve().parent.parent
_REQ = re.compile(r"^\s*([A-Za-z0-9_.\-]+)\s*(.*?)\s*$")


def _requirements(lines) -> dict[str, str]:
    """{normalised name: version bound} of requirement strings such as ``numpy>=1.26``."""
    out = {}
    for line in lines:
        name, bound = _REQ.match(line).groups()
        out[re.sub(r"[-_.]+", "-", name).lower()] = bound.replace(" ", "")
    return out


def test_environment_yml_matches_pyproject():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    wanted = project["dependencies"] + [r for extra in project["optional-dependencies"].values() for r in extra]
    wanted = _requirements(r for r in wanted if not r.startswith(project["name"]))
    dependencies = (REPO / "environment.yml").read_text().split("dependencies:", 1)[1]
    listed = [m.group(1) for m in re.finditer(r"^\s*-\s+([A-Za-z][^\s#:]*)\s*$", dependencies, re.MULTILINE)]
    listed = _requirements(x for x in listed if x not in ("pip",) and not x.startswith(("python", "-e")))
    assert listed == wanted


def test_a_script_beside_a_checkout_named_mocapviz_imports_the_package(tmp_path):
    """A script run from the folder above a checkout named ``mocapviz/`` imports the installed package, not that
    folder as an empty namespace package (`mocapviz.load` was an AttributeError there): the Makefile installs the
    checkout through a .pth file (compat editable mode), on which a regular package further down sys.path wins."""
    import subprocess
    import sys

    (tmp_path / "mocapviz" / "tests").mkdir(parents=True)  # a checkout's folder: no __init__.py
    done = subprocess.run([sys.executable, "-c", "import mocapviz; print(mocapviz.__file__, callable(mocapviz.load))"],
                          cwd=tmp_path, capture_output=True, text=True, check=False)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == [str(Path(__file__).resolve().parent.parent / "mocapviz" / "__init__.py"), "True"]
