"""``python -m mocapviz.cli``: the ``mocapviz`` command (:func:`mocapviz.cli.run`)."""
from __future__ import annotations

from . import run

if __name__ == "__main__":  # not when a walk of the package imports this module
    run()
