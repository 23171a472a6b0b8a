"""mocapviz: content-based retrieval and similarity search in motion-capture databases.

Pipeline (see the repository's ARCHITECTURE): ``io`` reads files into a :class:`Motion`, ``skeleton`` maps
it onto 24 canonical joints, ``database`` concatenates many into a :class:`MotionDB` on disk.
"""
__version__ = "0.1.0"

from .database import MotionDB  # noqa: E402
from .errors import MocapFormatError, MotionDBError, SkeletonMappingError  # noqa: E402
from .io import load  # noqa: E402
from .motion import Motion  # noqa: E402

__all__ = ["Motion", "MotionDB", "MocapFormatError", "MotionDBError", "SkeletonMappingError", "load", "__version__"]
