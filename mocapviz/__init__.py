"""mocapviz: content-based retrieval and similarity search in motion-capture databases.

Pipeline (see the repository's ARCHITECTURE): ``io`` reads files into a :class:`Motion`, ``skeleton`` maps
it onto 24 canonical joints, ``database`` concatenates many into a :class:`MotionDB` on disk.
"""
__version__ = "0.1.0"

from .database import MotionDB
from .errors import MocapFormatError, MocapvizError, MotionDBError, ParameterError, SkeletonMappingError
from .io import load
from .motion import Motion

__all__ = ["MocapFormatError", "MocapvizError", "Motion", "MotionDB", "MotionDBError", "ParameterError", "SkeletonMappingError",
           "__version__", "load"]
