"""Similarity search of marker-only documents by their markers (:mod:`mocapviz.db.marker_documents`).

The query is a stretch of a marker-only document (or a marker Motion); the answer is the K best non-overlapping
stretches of the marker-only documents of the same marker label set and frame rate, by subsequence DTW
(:func:`mocapviz.match.subsequence_dtw`, the exact O(m n) alignment: every cell) on the marker numeric set
(:mod:`mocapviz.features.marker_numeric`), as the one hit table (:mod:`mocapviz.db.hits`): document (negative ids),
in-document frames ``start:end`` half-open, seconds, ``cost`` (the accumulated Euclidean frame distances, cm).

The documents of another label set or rate are not compared (their features mean something else); the table's
attrs say how many were left out (``other_markers``, ``other_rate``) and how many were searched (``searched``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..db.hits import hit_table
from ..errors import ParameterError
from ..features.marker_numeric import marker_features, marker_label_set
from ..match.time_warping import subsequence_dtw
from ..motion import Motion
from ..validation import MIN_LENGTH

__all__ = ["marker_stretches"]


def marker_stretches(db, example, frames=None, n_matches: int = 10, min_length: float | None = MIN_LENGTH,
                     exclude_document: bool = True) -> pd.DataFrame:  # fmt: skip
    """The stretches of marker-only documents whose markers move most like the example's.

    Parameters
    ----------
    db : MotionDB
        The database whose marker-only documents (:attr:`MotionDB.marker_documents`) are searched.
    example : int or Motion
        A marker-only document's id (negative), or a marker Motion (no skeleton; NaN in gaps).
    frames : tuple of int (start, end), optional
        The example's frames, half-open (default all).
    n_matches : int
        Stretches wanted (fewer when there are fewer non-overlapping ones).
    min_length : float, optional
        The shortest stretch, a share of the query's frames (None: any length).
    exclude_document : bool
        Leave out the example's own document.

    Returns
    -------
    HitTable
        ``rank, doc_id, name, start, end, frames, start_s, end_s, cost`` and the label columns, best first; attrs
        ``searched``, ``other_markers``, ``other_rate``, ``query_frames``.

    Raises
    ------
    ParameterError
        An example that is no marker-only document nor a marker Motion, frames outside it, a query shorter than 2
        frames or longer than every document searched.
    """
    markers = db.marker_documents
    query_motion, own = _example(markers, example)
    n = query_motion.n_frames
    start, end = (0, n) if frames is None else (int(frames[0]), int(frames[1]))
    if not 0 <= start < end <= n:
        raise ParameterError(f"frames {start}:{end} are not a stretch of the example (0:{n})")
    labels, order = marker_label_set(query_motion.joint_names)
    query = marker_features(query_motion.positions[:, order])[start:end]
    docs = markers.documents
    same = np.array([marker_label_set(m)[0] == labels for m in docs["markers"]], dtype=bool)
    rate = np.isclose(docs["fps"].to_numpy(np.float64), query_motion.fps, rtol=1e-9)
    keep = same & rate & ~((docs["doc_id"] == own).to_numpy() & exclude_document)
    searched = docs[keep]
    attrs = {"searched": int(keep.sum()), "other_markers": int((~same).sum()), "other_rate": int((same & ~rate).sum()),
             "query_frames": end - start}  # fmt: skip
    if searched.empty:
        table = hit_table(markers, [], [], [], cost=np.zeros(0))
    else:
        features = []
        for doc_id in searched["doc_id"]:
            motion = markers.motion(int(doc_id))
            features.append(marker_features(motion.positions[:, marker_label_set(motion.joint_names)[1]]))
        lengths = np.array([len(f) for f in features])
        starts = np.cumsum(lengths) - lengths
        found = subsequence_dtw(query, np.concatenate(features), starts, n_matches, paths=False, min_length=min_length)
        rows = found["doc_id"].to_numpy()
        first = found["start"].to_numpy() - starts[rows]
        table = hit_table(markers, searched["doc_id"].to_numpy()[rows], first,
                          found["end"].to_numpy() - starts[rows] + 1, cost=found["cost"].to_numpy())  # fmt: skip
    table.attrs.update(attrs)
    return table


def _example(markers, example) -> tuple[Motion, int | None]:
    """The example as a marker Motion and its document id (None for a Motion)."""
    if isinstance(example, Motion):
        if (np.asarray(example.parents) != -1).any():
            raise ParameterError(f"{example.source}: a Motion with a skeleton; the marker search takes markers (a "
                                 "marker Motion, as mocapviz.load reads a C3D file)")  # fmt: skip
        return example, None
    if isinstance(example, (int, np.integer)) and not isinstance(example, bool):
        if example >= 0:
            raise ParameterError(f"document {example} has canonical joints: search it with Engine.stretches; marker-"
                                 "only documents have negative ids")  # fmt: skip
        return markers.motion(int(example)), int(example)
    raise ParameterError(f"the example must be a marker-only document's id (negative) or a marker Motion; got "
                         f"{type(example).__name__}")  # fmt: skip
