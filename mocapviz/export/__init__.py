"""The export layer: what a search found, as files (issue 27; docs/export.md).

- ``formats.py``: the formats and rigs an export offers (light: the engine's parameter table reads them).
- ``stretch.py``: one stretch of one document: its source file cut on its own rig (BVH lines, AMC blocks with the
  ASF, a BVH on the ASF rig) or the database's frames on the canonical rig (BVH, glTF binary, HumanML3D's joint
  arrays).
- ``joint_arrays.py``: HumanML3D's (T, 22, 3) arrays of stretches and the manifest that names their sources.
- ``hits.py``: every row of a hit table: into a folder (``export_hits``) or one zip archive in memory
  (``hits_zip``).

The writers of the formats live in :mod:`mocapviz.io` (``bvh_writer``, ``amc_writer``, ``gltf_writer``,
``humanml3d``), the rotations that pose the canonical rig in :mod:`mocapviz.motion.rig`. The names below are imported
when first used, so that reading :data:`FORMATS` imports neither pandas nor the writers.
"""
from .._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "FORMATS": ".formats", "RIGS": ".formats", "default_rig": ".formats",
    "export_hits": ".hits", "hit_files": ".hits", "hits_zip": ".hits", "read_hits": ".hits", "zipped": ".hits",
    "export_stretch": ".stretch", "source_frames": ".stretch", "stretch_files": ".stretch",
    "MANIFEST": ".joint_arrays",
})  # fmt: skip

__all__ = ["FORMATS", "MANIFEST", "RIGS", "default_rig", "export_hits", "export_stretch", "hit_files", "hits_zip",
           "read_hits", "source_frames", "stretch_files", "zipped"]
