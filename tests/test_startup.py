"""Start-up (issue 24 item 6): a command imports what it needs when it needs it. What is loaded is tested here; how
long it takes is measured in benchmarks/bench_startup.py, not in a timed test."""

from __future__ import annotations

import subprocess
import sys

import pytest

HEAVY = ("pandas", "numba", "scipy", "pyarrow", "tqdm", "dask", "distributed", "pooch")


def _loaded(code: str) -> set[str]:
    """The HEAVY packages a fresh interpreter has imported after running ``code``."""
    probe = f"{code}\nimport sys\nprint(' '.join(m for m in {HEAVY!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    return set(out.split())


@pytest.mark.parametrize("code", [
    "import mocapviz",
    "import mocapviz.features, mocapviz.match, mocapviz.similarity, mocapviz.relational, mocapviz.db, mocapviz.io",
    "from mocapviz.features import NUMERIC_SETS, RELATIONAL_SETS",
    "from mocapviz.motion import Motion, FPS_RANGE",
    ("import contextlib, io\nfrom mocapviz.cli import main\nwith contextlib.redirect_stdout(io.StringIO()):\n"
     "    assert main(['--help']) == 0"),
    ("import contextlib, io\nfrom mocapviz.cli import main\nwith contextlib.redirect_stdout(io.StringIO()):\n"
     "    assert main(['search', '--help']) == 0"),
])  # fmt: skip
def test_import_and_help_load_no_heavy_package(code):
    assert _loaded(code) == set()


def test_opening_a_database_loads_no_reader_and_no_numba(tmp_path):
    """``mocapviz info`` needs pandas, not numba: the readers (and their kernels) load with the first file read."""
    code = ("from mocapviz.db.database import MotionDB\nfrom mocapviz.io import FORMATS, find_asf, load\n"
            "import mocapviz.features.numeric")  # fmt: skip
    assert _loaded(code) <= {"pandas", "pyarrow"}


def test_a_search_of_whole_clips_loads_no_kd_tree(sample_db):
    code = (f"from mocapviz.db.database import MotionDB\nfrom mocapviz.similarity.search import SimilaritySearch\n"
            f"SimilaritySearch(MotionDB.open({str(sample_db.path)!r})).clips(7, n_matches=3)\n"
            f"import sys\nassert 'scipy.spatial' not in sys.modules, 'the kd-tree was imported'")  # fmt: skip
    subprocess.run([sys.executable, "-c", code], check=True)


def test_the_set_names_of_the_package_are_those_its_modules_define():
    from mocapviz import features
    from mocapviz.features import numeric, relational

    assert numeric.NUMERIC_SETS is features.NUMERIC_SETS == tuple(numeric._SETS)
    assert relational.RELATIONAL_SETS is features.RELATIONAL_SETS


def test_the_lazy_names_are_the_modules_own():
    from mocapviz import features, io, match
    from mocapviz.features import numeric, relational
    from mocapviz.io import asfamc, bvh
    from mocapviz.match import neighbourhood_graph, time_warping

    assert features.numeric_of is numeric.numeric_of and features.feature_names is relational.feature_names
    assert io.read_asf is asfamc.read_asf and io.read_bvh is bvh.read_bvh and io.AsfSkeleton is asfamc.AsfSkeleton
    assert match.lng is neighbourhood_graph.lng and match.dtw is time_warping.dtw
    assert {"load", "find_asf", "FORMATS", "read_amc", "AsfSkeleton"} <= set(dir(io))
    assert set(features.__all__) <= set(dir(features)) and set(match.__all__) <= set(dir(match))
    with pytest.raises(AttributeError):
        features.no_such_name  # noqa: B018


@pytest.mark.parametrize("argv, status, out, err", [
    (["--help"], 0, "usage: mocapviz", ""),
    (["info", "/nonexistent/db"], 1, "", "does not exist"),
    (["search", "--no-such-option"], 2, "", "mocapviz: error:"),
])  # fmt: skip
def test_the_command_exits_with_its_status_after_its_output_and_the_atexit_handlers(argv, status, out, err):
    """``mocapviz`` (cli.run) leaves out the interpreter's teardown, not what a normal exit does for the command."""
    code = ("import atexit, sys\natexit.register(lambda: print('atexit handler ran', file=sys.stderr))\n"
            f"sys.argv[1:] = {argv!r}\nfrom mocapviz.cli import run\nrun()")  # fmt: skip
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert proc.returncode == status
    assert out in proc.stdout and err in proc.stderr and "atexit handler ran" in proc.stderr
