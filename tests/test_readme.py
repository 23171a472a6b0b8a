"""Every code example of the README and of the user guide's pages (``GUIDE``, docs/index.md's order) runs as written.

- The demo commands on the demo database (the embedded demo at 30 Hz with its indexes and numeric feature sets, as
  `make demo` builds it), each of which must give the answer its comment says (:data:`DEMO_ANSWERS`).
- Every ```python block, in order (the README, then the guide's pages) in one namespace (a later block uses the ``db``
  of an earlier one), in an empty working folder: the examples use the embedded sample, so they never need the
  shared archives.
- Every line of every ```sh / ```bash block, in the same order in one working folder, through bash with the
  installed ``mocapviz`` command. Lines that cannot run in a test are checked instead, each for a stated reason
  (:data:`CHECKED_ONLY`): make targets by ``make -n`` (a dry run), long-running ``mocapviz`` commands by the CLI's own
  argument parser. Lines that need the shared archives skip, with the reason, when they are absent.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from mocapviz import MotionDB
from mocapviz.cli import main

README = Path(__file__).resolve().parent.parent / "README.md"
GUIDE = [README.parent / "docs" / f"{page}.md" for page in
         ("use", "relational", "similarity", "templates", "reproduce", "files", "dashboard")]  # docs/index.md's order
MARKER = "<!-- demo commands: each line is run by tests/test_readme.py -->"


def demo_commands() -> list[str]:
    text = README.read_text()
    block = re.search(re.escape(MARKER) + r"\s*```sh\n(.*?)```", text, re.DOTALL)
    assert block, f"README.md has no demo command block after {MARKER!r}"
    return [line.strip() for line in block.group(1).splitlines() if line.strip()]


@pytest.fixture(scope="module")
def demo_build(tmp_path_factory):
    """A folder laid out like the repository's build/ after `make demo`: demo.mdb (the embedded demo at 30 Hz, the
    HDM05 clips first) with its relational indexes and the F15E/F30E numeric sets."""
    build = tmp_path_factory.mktemp("demo") / "build"
    build.mkdir()
    shutil.copytree(MotionDB.demo().path, build / "demo.mdb")
    assert main(["index", str(build / "demo.mdb"), "--no-cluster", "--quiet"]) == 0
    assert main(["features", str(build / "demo.mdb"), "--numeric-sets", "F15E,F30E", "--no-cluster", "--quiet"]) == 0
    return build


def _ranked(out: str) -> list[int]:
    """The document ids of the ranked rows a search command printed, best first."""
    return [int(m.group(1)) for m in re.finditer(r"^\s+\d+\s+(\d+)\s", out, re.MULTILINE)]


KICK, SQUAT, CMU_KICKS = "kickLFront1Reps", "squat1Reps", {"Front Kick", "Mawashigeri", "Yokogeri"}
# what each demo command of the README must answer (its comment says it): (a part of the command, the check of the
# document ids it ranked, given the demo's labels and actors); every demo command has exactly one
DEMO_ANSWERS = {
    "search build/demo.mdb --example 5 ": lambda docs, label, actor: [label[d] for d in docs[:3]] == [KICK] * 3
    and {actor[d] for d in docs[:3]} == {"dg", "mm", "tr"},
    "--stretches": lambda docs, label, actor: docs[:2] == [45, 45],  # the query, then the same take's next kick
    "mocapviz knn": lambda docs, label, actor: len(docs) == 5 and {label[d] for d in docs} == {KICK} and 5 not in docs,
    "mocapviz match": lambda docs, label, actor: docs and label[docs[0]] == SQUAT and 9 not in docs,
    "mocapviz query": lambda docs, label, actor: len(docs) >= 2 and label[docs[0]] == KICK and 5 not in docs,
    "kick_right then kick_left": lambda docs, label, actor: docs and {label[d] for d in docs} <= CMU_KICKS,
    "kick_right then punch_left": lambda docs, label, actor: docs == [],
    "template learn": lambda docs, label, actor: docs == [],
    "template search": lambda docs, label, actor: [label[d] for d in docs[:4]] == [SQUAT] * 4
    and "tr" in {actor[d] for d in docs[:4]},
    "mocapviz export": lambda docs, label, actor: docs == [],
}


def _answer(command: str):
    [check] = [check for part, check in DEMO_ANSWERS.items() if part in command]
    return check


def test_every_demo_command_has_its_expected_answer():
    assert [len([p for p in DEMO_ANSWERS if p in c]) for c in demo_commands()] == [1] * len(demo_commands())
    assert len(demo_commands()) == len(DEMO_ANSWERS)


@pytest.mark.parametrize("command", demo_commands())
def test_readme_demo_command_answers_what_it_says(command, demo_build, capsys):
    words = shlex.split(command, comments=True)  # (the comment says what it answers)
    assert words[0] == "mocapviz"
    args = [str(demo_build / w.removeprefix("build/")) if w.startswith("build/") else w for w in words[1:]]
    status = main(args)
    out, err = capsys.readouterr()
    assert status == 0, f"{command!r} failed: {err}"
    documents = MotionDB.open(demo_build / "demo.mdb").documents.set_index("doc_id")
    docs = _ranked(out)
    assert _answer(command)(docs, documents["label"], documents["actor"]), f"{command!r} answered:\n{out}"
    if "punch_left" in command:  # say why: both parts were found, never in one take within 2 s
        assert "found nothing (its parts found:" in out and "punch_left (" in out
    if command.startswith("mocapviz export"):
        assert len(list((demo_build / "kicks").glob("*.bvh"))) == 3


# ------------------------------------------------------------------------------------------- every example
FENCE = re.compile(r"^```(\w+)\n(.*?)^```", re.MULTILINE | re.DOTALL)
CHECKED_ONLY = {  # line prefix -> why it is checked, not run
    "make ": "a make target (`make test` is what CI runs; demo, reproduce and notebooks take minutes to hours): make -n",
    "mocapviz serve": "serves until stopped (tests/test_app_*.py serve the dashboard): argument parser",
    "mocapviz reproduce": "minutes to hours on the shared archives (tests/test_reproduce.py runs experiments): "
    "argument parser",
    "export MOCAPVIZ_DATA_URL": "points at the user's archives; the test's environment provides its own",
}
ARCHIVES = ("hdm05-cut", "cmu-asfamc", "bandai-namco")


def _examples(languages: tuple[str, ...]) -> list[tuple[str, str]]:
    """("file:line", code) of every fenced block in ``languages``: the README's, then each guide page's, in order."""
    out = []
    for page in (README, *GUIDE):
        text = page.read_text()
        where = page.relative_to(README.parent)
        out += [(f"{where}:{text[: m.start()].count(chr(10)) + 2}", m.group(2)) for m in FENCE.finditer(text)
                if m.group(1) in languages]  # fmt: skip
    return out


def test_the_guide_is_the_index_in_its_order():
    """The pages whose examples run, in the order they run, are the guide as docs/index.md lists it."""
    index = (README.parent / "docs" / "index.md").read_text()
    listed = re.findall(r"^\d+\. \[[^]]+\]\(([\w-]+\.md)\)", index, re.MULTILINE)
    assert listed == [p.name for p in GUIDE]


def _shell_lines() -> list[tuple[str, str]]:
    out = []
    for first, code in _examples(("sh", "bash")):
        page, line = first.rsplit(":", 1)
        for offset, text in enumerate(code.splitlines()):
            command = re.sub(r"\s+#.*$", "", text).strip()  # (a comment after two spaces or more)
            if command and not command.startswith("#"):
                out.append((f"{page}:{int(line) + offset}", command))
    return out


@pytest.fixture(scope="module")
def namespace(tmp_path_factory):
    """One namespace for all the Python examples, run in an empty folder."""
    folder = tmp_path_factory.mktemp("readme-python")
    old = Path.cwd()
    os.chdir(folder)
    yield {"__name__": "readme"}
    os.chdir(old)


@pytest.mark.parametrize(("line", "code"), _examples(("python",)), ids=lambda v: v if ".md:" in v else "")
def test_readme_python_example_runs(line, code, namespace):
    exec(compile(code, f"{line} (block)", "exec"), namespace)  # noqa: S102 - the README's and the guide's own code


@pytest.fixture(scope="module")
def shell_folder(tmp_path_factory, demo_build):
    """The working folder of the shell examples: the demo build beside it (``build/demo.mdb``), and the
    installed ``mocapviz`` on PATH."""
    folder = tmp_path_factory.mktemp("readme-shell")
    shutil.copytree(demo_build, folder / "build")
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    return folder, env


def _archives_present() -> bool:
    from mocapviz.io import datasets

    try:
        datasets.data_url()
        return True
    except datasets.DatasetError:
        return False


@pytest.mark.parametrize(("line", "command"), _shell_lines(), ids=lambda v: v if ".md:" in v else "")
def test_readme_shell_example_runs(line, command, shell_folder):
    folder, env = shell_folder
    reason = next((why for prefix, why in CHECKED_ONLY.items() if command.startswith(prefix)), None)
    if reason is None and any(a in command for a in ARCHIVES) and not _archives_present():
        pytest.skip(f"{line} needs the shared archives (set MOCAPVIZ_DATA_URL or put ../shared beside)")
    if reason is None:
        done = subprocess.run(["bash", "-ec", command], cwd=folder, env=env, capture_output=True, text=True,
                              timeout=900, check=False)  # fmt: skip
        assert done.returncode == 0, f"{line}: {command!r} failed:\n{done.stdout}\n{done.stderr}"
        assert "Traceback" not in done.stderr
    elif command.startswith("make "):
        words = shlex.split(command)
        dry = subprocess.run(["make", "-n", *words[1:]], cwd=README.parent, capture_output=True, text=True,
                             check=False, env=dict(os.environ, FULL=""))  # fmt: skip
        assert dry.returncode == 0, f"{line}: {command!r} is not a make target:\n{dry.stderr}"
    elif command.startswith("mocapviz "):
        from mocapviz.cli import build_parser

        build_parser().parse_args(shlex.split(command)[1:])  # SystemExit(2) on an unknown option or value


def test_readme_c3d_ingest_reads_both_demo_takes(tmp_path):
    """The README's C3D line, run as written in an empty folder: both takes of the demo become documents of the
    lengths their headers give (2,900 and 810 frames at 120 Hz, so 725 and 203 at 30 Hz), the CMU take with the label
    its table gives and the unlabelled scene take without one."""
    [command] = [c for _, c in _shell_lines() if "c3d-markers" in c and c.startswith("mocapviz ingest")]
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    done = subprocess.run(["bash", "-ec", command], cwd=tmp_path, env=env, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    documents = MotionDB.open(tmp_path / "build" / "c3d.mdb").documents.set_index("name")
    assert documents["n_frames"].to_dict() == {"HDM_bd_01-02_01_120": 725, "cmu_85_02": 203}
    assert documents["label"].get("cmu_85_02") == "JumpTwist" and documents["label"].isna().sum() == 1
