"""pytest configuration shared by the tests (tests/) and the doctests of the package's Examples (mocapviz/).

The Examples use the embedded sample (:meth:`mocapviz.MotionDB.sample`); its unpacked files and database are
cached under ``<repo>/.cache/mocapviz`` unless ``MOCAPVIZ_HOME`` says otherwise.
"""
import os
from pathlib import Path

os.environ.setdefault("MOCAPVIZ_HOME", str(Path(__file__).resolve().parent / ".cache" / "mocapviz"))
