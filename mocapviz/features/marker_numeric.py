"""The marker numeric set: per-frame features computed from a document's markers alone, for documents without
canonical joints (marker-only documents, :mod:`mocapviz.db.marker_documents`).

Every numeric set of :mod:`mocapviz.features.numeric` reads the 24 canonical joints; a marker-only document has
none, and its markers differ in number and place from lab to lab. The marker numeric set therefore compares only
documents of one **marker label set** (:func:`marker_label_set`: the same labels, in any order): each frame's
markers, in label order, relative to their centroid and turned about the vertical so that a heading estimated from
the markers points along +x. So a take and a copy of it moved or turned on the floor have the same features.

- **Gaps** are filled per marker by linear interpolation in time, the first and last sample held at the ends (never
  stored: the features are computed when searched). A marker the document never sees sits at the centroid (0).
- **Heading**: the horizontal part of ``h = sum_i w_i (p_i - c)`` with fixed weights ``w_i = i - (M - 1) / 2`` of
  the i-th marker in label order: a direction made of the markers alone, the same rule for every document of the
  set, turning with the body (where ``h`` vanishes, the frame is not turned).

marker_label_set   the sorted labels that make documents comparable, and the order putting a file's markers in it.
marker_features    (T, M, 3) markers -> (T, 3 M) features, cm.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..motion.markers import fill_gaps

__all__ = ["marker_features", "marker_label_set"]


def marker_label_set(names) -> tuple[tuple[str, ...], np.ndarray]:
    """The marker label set of a file's markers and the order that puts its markers in it.

    Parameters
    ----------
    names : sequence of str
        The markers' labels, in the file's order.

    Returns
    -------
    labels : tuple of str
        The labels sorted: documents with equal ``labels`` are comparable.
    order : np.ndarray [shape=(M,)], int
        ``positions[:, order]`` are the markers in ``labels``' order.

    Examples
    --------
    >>> marker_label_set(["RASI", "LASI", "C7"])
    (('C7', 'LASI', 'RASI'), array([2, 1, 0]))
    """
    names = [str(n) for n in names]
    order = np.argsort(names, kind="stable")
    return tuple(names[i] for i in order), order


def marker_features(positions) -> np.ndarray:
    """The marker numeric set of a clip's markers (module docstring).

    Parameters
    ----------
    positions : array_like [shape=(T, M, 3)]
        Marker positions in cm, y up, NaN in gaps, the markers in label order (:func:`marker_label_set`).

    Returns
    -------
    np.ndarray [shape=(T, 3 M)], float32
        Each frame's markers relative to their centroid, turned to the heading, cm; finite.

    Raises
    ------
    ParameterError
        Not (T, M, 3) with T >= 1, M >= 1, or no marker ever seen.

    Examples
    --------
    >>> p = np.array([[[0.0, 100, 0], [10, 100, 0]], [[50, 100, 50], [50, 100, 60]]])  # two markers, turned 90 deg
    >>> (marker_features(p).round(2) + 0.0).tolist()  # (+ 0.0: no -0.0)
    [[-5.0, 0.0, 0.0, 5.0, 0.0, 0.0], [-5.0, 0.0, 0.0, 5.0, 0.0, 0.0]]
    """
    p = np.array(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 3 or not p.shape[0] or not p.shape[1]:
        raise ParameterError(f"marker positions must be (T, M, 3) with T, M >= 1; got shape {p.shape}")
    seen = np.isfinite(p).all(axis=2)  # (T, M)
    if not seen.any():
        raise ParameterError("no marker is seen in any frame: no marker features")
    ever = seen.any(axis=0)
    p = fill_gaps(p, 1.0, p.shape[0]).astype(np.float64)  # every gap filled (ends held): one frame a "second"
    centroid = p[:, ever].mean(axis=1, keepdims=True)
    offsets = np.where(ever[None, :, None], p - centroid, 0.0)
    weights = np.arange(p.shape[1]) - (p.shape[1] - 1) / 2.0
    h = np.einsum("m,tmc->tc", weights, offsets)[:, [0, 2]]  # horizontal: x, z
    norm = np.hypot(h[:, 0], h[:, 1])
    turned = norm > 1e-9 * (1.0 + np.abs(offsets).max())
    cos = np.where(turned, h[:, 0] / np.where(turned, norm, 1.0), 1.0)[:, None]
    sin = np.where(turned, h[:, 1] / np.where(turned, norm, 1.0), 0.0)[:, None]
    out = offsets.copy()
    out[..., 0] = offsets[..., 0] * cos + offsets[..., 2] * sin
    out[..., 2] = offsets[..., 2] * cos - offsets[..., 0] * sin
    return out.reshape(p.shape[0], -1).astype(np.float32)
