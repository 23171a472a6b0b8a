"""What an export can write, declared once: the formats, the rigs, the rig a format is written on by default and the
extension of its files. Light (no pandas): the engine's parameter table takes the choices from here for the command
line, the dashboard's download buttons and docs/parameters.md.

FORMATS      bvh, amc, glb, humanml3d.
RIGS         source, canonical.
default_rig  the rig of a format when none is asked for.
EXTENSIONS   format -> the extension of its files (without the dot).
"""
from __future__ import annotations

FORMATS = ("bvh", "amc", "glb", "humanml3d")
RIGS = ("source", "canonical")
EXTENSIONS = {"bvh": "bvh", "amc": "amc", "glb": "glb", "humanml3d": "npy"}
CANONICAL_ONLY = ("humanml3d",)
"""Formats made from the database's canonical joints alone (no source rig to write them on)."""


def default_rig(format: str) -> str:
    """The rig a format is exported on when none is asked for: ``canonical`` for glTF (24 named joints any viewer
    shows alike) and HumanML3D's joint arrays (made from the canonical joints), ``source`` for BVH and AMC (the
    captured file itself).

    Examples
    --------
    >>> [default_rig(f) for f in FORMATS]
    ['source', 'source', 'canonical', 'canonical']
    """
    return "canonical" if format == "glb" or format in CANONICAL_ONLY else "source"
