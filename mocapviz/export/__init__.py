"""The export layer: what a search found, as files (issue 27; docs/export.md).

- ``stretch.py``: one stretch of one document: its source file cut on its own rig (BVH lines, AMC blocks with the
  ASF, a BVH on the ASF rig) or the database's frames on the canonical rig (BVH, glTF binary).
- ``hits.py``: every row of a hit table: into a folder (``export_hits``) or one zip archive in memory
  (``hits_zip``).

The writers of the formats live in :mod:`mocapviz.io` (``bvh_writer``, ``amc_writer``, ``gltf_writer``), the rotations
that pose the canonical rig in :mod:`mocapviz.motion.rig`.
"""
from .hits import export_hits, hit_files, hits_zip, read_hits, zipped
from .stretch import FORMATS, RIGS, export_stretch, source_frames, stretch_files

__all__ = ["FORMATS", "RIGS", "export_hits", "export_stretch", "hit_files", "hits_zip", "read_hits", "source_frames",
           "stretch_files", "zipped"]
