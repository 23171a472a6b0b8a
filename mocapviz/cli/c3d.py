"""``mocapviz c3d markers FILE``: a C3D file's marker labels, the share of frames each one misses, and the marker set
they match (or what the closest set lacks)."""
from __future__ import annotations

from dataclasses import replace

import pandas as pd

from .. import io as readers
from ..engine import marker_gaps, match_set
from .output import printed


def run_markers(args) -> None:
    """Print the file's markers (the label as read, prefix cut; with ``--mapping`` the name it is mapped to), the
    percentage of gap frames of each, and the set they match: ``set: plug-in gait, lower body, no head markers`` or
    ``set: none: closest cmu, which lacks ...``."""
    mapping = readers.read_marker_mapping(args.marker_mapping) if args.marker_mapping else None
    motion = readers.load(args.file)  # the labels as the file has them; renamed below, as read_c3d renames them
    names = readers.relabel(motion.joint_names, mapping, args.file) if mapping else motion.joint_names
    mapped = replace(motion, joint_names=names)
    columns = {"label": list(motion.joint_names), **({"marker": list(names)} if mapping else {}),
               "gaps %": (100 * marker_gaps(mapped).to_numpy()).round(1)}  # fmt: skip
    print(f"{args.file}: {motion.n_joints} markers, {motion.n_frames} frames at {motion.fps:g} fps, first frame "
          f"{motion.labels['first_frame']}")  # fmt: skip
    print(printed(pd.DataFrame(columns)))
    print(f"set: {match_set(mapped).describe()}")
