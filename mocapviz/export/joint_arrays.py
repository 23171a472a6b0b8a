"""HumanML3D's joint arrays of stretches (format ``humanml3d``): one ``.npy`` of shape (T, 22, 3) per stretch and one
manifest, ``manifest.csv``, naming each array's source document, seconds and frames.

array_files      one stretch -> {"<stem>.npy": bytes, "manifest.csv": bytes} (its manifest of one row).
merged_manifest  the manifests of several stretches as one (rows in order).
MANIFEST         the manifest's file name; MANIFEST_COLUMNS its columns (then the search's own, e.g. cost).

The array is :func:`mocapviz.io.humanml3d.joint_array` of the database's canonical frames of the stretch: 20 fps,
metres, y up, placed as HumanML3D places its ``new_joints`` (floor at y = 0, the first root over the origin, facing
+z). The manifest's ``yaw_deg`` and ``origin_*_m`` undo the placement: database position (cm) =
``100 * (R_y(-yaw) p + origin)``.
"""
from __future__ import annotations

import csv
import io

import numpy as np

MANIFEST = "manifest.csv"
MANIFEST_COLUMNS = ("file", "rank", "doc_id", "name", "start_s", "end_s", "start", "end", "fps", "source_start",
                    "source_end", "source_fps", "frames", "array_fps", "yaw_deg", "origin_x_m", "origin_y_m",
                    "origin_z_m", "source", "sha256", "database", "search")  # fmt: skip
"""``file`` the array; ``start_s`` / ``end_s`` the stretch in seconds of its document (frame ``start`` at
``start / fps``, ``end`` excluded); ``start`` / ``end`` its frames at the database's rate ``fps``; ``source_start`` /
``source_end`` the same seconds in frames of the source file (half-open, at ``source_fps``); ``frames`` the array's T at
``array_fps`` (20); ``yaw_deg`` / ``origin_*_m`` its placement."""


def array_files(motion, stem: str, meta: dict) -> dict[str, bytes]:
    """One stretch as HumanML3D's joint array and its manifest of one row.

    Parameters
    ----------
    motion : Motion
        The stretch's frames on the 24 canonical joints (cm, the database's rate).
    stem : str
        The array's file name without ``.npy``.
    meta : dict
        What :func:`mocapviz.export.stretch.stretch_files` knows of the stretch: ``rank``, ``doc_id``, ``name``,
        ``frames`` (start, end), ``fps``, ``source_frames``, ``source_fps``, ``source``, ``sha256``, ``database``,
        ``search``, ``scores`` (the search's own columns, appended to the manifest's).

    Returns
    -------
    dict
        ``{"<stem>.npy": the array (float32, little-endian, .npy version 1.0), MANIFEST: CSV bytes}``.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> files = array_files(MotionDB.sample().motion(7)[0:60], "kick", {"frames": [0, 60], "fps": 120.0})
    >>> sorted(files), np.load(io.BytesIO(files["kick.npy"])).shape
    (['kick.npy', 'manifest.csv'], (10, 22, 3))
    """
    from ..io.humanml3d import FPS, joint_array

    array, yaw, origin = joint_array(motion)
    data = io.BytesIO()
    np.save(data, array.astype("<f4"), allow_pickle=False)
    start, end = meta["frames"]
    fps = float(meta["fps"])
    a, b = meta.get("source_frames", (start, end))
    row = {"file": f"{stem}.npy", "rank": meta.get("rank"), "doc_id": meta.get("doc_id"), "name": meta.get("name"),
           "start_s": start / fps, "end_s": end / fps, "start": start, "end": end, "fps": fps, "source_start": a,
           "source_end": b, "source_fps": meta.get("source_fps", fps), "frames": len(array), "array_fps": FPS,
           "yaw_deg": float(np.degrees(yaw)), "origin_x_m": float(origin[0]), "origin_y_m": float(origin[1]),
           "origin_z_m": float(origin[2]), "source": meta.get("source"), "sha256": meta.get("sha256"),
           "database": meta.get("database"), "search": meta.get("search"),
           **{k: v for k, v in (meta.get("scores") or {}).items() if k not in MANIFEST_COLUMNS}}  # fmt: skip
    return {f"{stem}.npy": data.getvalue(), MANIFEST: _csv([row], list(row))}


def merged_manifest(parts: list[bytes]) -> bytes:
    """Several manifests (:func:`array_files`') as one: their rows in order, the columns of all of them (the first's
    first).

    Parameters
    ----------
    parts : list of bytes
        CSV manifests.

    Returns
    -------
    bytes
        One CSV manifest (UTF-8, ``\\n`` line ends).

    Examples
    --------
    >>> merged_manifest([b"file,cost\\na.npy,1\\n", b"file,cost\\nb.npy,2\\n"]).decode().splitlines()
    ['file,cost', 'a.npy,1', 'b.npy,2']
    """
    rows, columns = [], {}
    for part in parts:
        reader = csv.DictReader(io.StringIO(part.decode("utf-8")))
        columns.update(dict.fromkeys(reader.fieldnames or ()))
        rows.extend(reader)
    return _csv(rows, list(columns))


def _csv(rows: list[dict], columns: list[str]) -> bytes:
    """Rows as CSV bytes, a header line first, None as an empty cell."""
    out = io.StringIO()
    writer = csv.DictWriter(out, columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows({k: ("" if v is None else v) for k, v in row.items()} for row in rows)
    return out.getvalue().encode("utf-8")
