"""The audit of a collection measured on real data with planted copies (issue 41 item 3): copies of real clips made
with each transform a near-copy goes through are appended to a copy of the database, the audit
(:meth:`Engine.audit <mocapviz.engine.Engine.audit>`, :mod:`mocapviz.similarity.audit`) runs on it, and each planted
copy is looked for among its pairs.

The copies (:func:`plant_copies`; every one a derived clip, none a recorded take): a clip of 3-6 s of a real
document (drawn with the seed among the documents at least 3 s long, each document once as long as there are
enough), copied by one kind of transform:

- ``mirrored``: its left/right mirror image (:func:`~mocapviz.motion.skeleton.mirror`);
- ``stretched``: time-scaled by a factor 1 ± 10-20 % (resampled to fps / factor, then labelled at the database's
  rate again: a re-timed take);
- ``trimmed``: a middle part of 60-80 % of it;
- ``noise``: Gaussian marker noise of 0.5-1 cm (3D standard deviation) on every joint and frame;
- ``retargeted``: on another actor's bones (:func:`~mocapviz.motion.skeleton.retarget` to the
  :func:`~mocapviz.motion.skeleton.bone_lengths` of a document of another actor, :func:`donor_bones`: a bone the
  donor's rig lacks keeps its length);
- ``resampled``: resampled to another rate and back to the database's: a quarter of it from 120 Hz up (a 120 Hz
  take kept at 30 Hz), else 5/6 of it (30 Hz through 25 Hz: a PAL copy; through 60 Hz a 30 Hz clip would come back
  unchanged);
- ``all``: mirrored, stretched, noisy and retargeted together.

A planted copy is **found** (:func:`planted_quality`) when a pair of the audit joins the copy's document with its
source document and covers at least half of the planted span on both sides (the source's frames [a, b), the
copy's), with the mirrored flag of the pair set for the mirrored kinds (``mirrored``, ``all``). Pairs that involve
a copy but are none of the planted pairs are its false positives.

plant_copies     db, out -> (the database with copies appended, the truth: one row per copy).
donor_bones      the bone lengths of a retargeted copy: another actor's, on the clip's rig.
planted_quality  db, truth, pairs -> recall per kind, false positives among the copies.
audit_quality    db, out, Engine -> plants, audits, measures (attrs: threshold, seconds, pairs).
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..motion.skeleton import SHORTEST_BONE_CM, bone_lengths, mirror, retarget
from ..validation import count

__all__ = ["KINDS", "audit_quality", "donor_bones", "plant_copies", "planted_quality"]

KINDS = ("mirrored", "stretched", "trimmed", "noise", "retargeted", "resampled", "all")
"""The kinds of planted copy, each one transform (``all``: mirrored, stretched, noise and retargeted together)."""
MIRRORED_KINDS = ("mirrored", "all")
"""The kinds whose pair must carry the mirrored flag."""
CLIP_S = (3.0, 6.0)
"""A source clip's length, seconds (drawn uniformly; a shorter document whole)."""
STRETCH = (0.1, 0.2)
"""How far a stretched copy's time factor is from 1 (drawn uniformly, either sign)."""
TRIM = (0.6, 0.8)
"""The share of its clip a trimmed copy keeps."""
NOISE_CM = (0.5, 1.0)
"""The marker noise of a noisy copy: 3D standard deviation per joint and frame, cm."""
MIN_OVERLAP = 0.5
"""The share of the planted span, on both sides, a pair must cover to find its copy."""

TRUTH_COLUMNS = ["kind", "source_doc", "source_start", "source_end", "copy_doc", "copy_start", "copy_end", "mirrored",
                 "factor", "noise_cm", "donor_doc", "rate"]  # fmt: skip


def plant_copies(db, out, n_per_kind: int = 2, seed: int = 0):
    """A copy of ``db`` at ``out`` with ``n_per_kind`` planted copies of each kind (:data:`KINDS`) appended
    (:meth:`MotionDB.append_motions`): derived clips of real documents, made as the module describes.

    Parameters
    ----------
    db : MotionDB
        A database of one frame rate (not changed), with a document of at least 3 s.
    out : str or os.PathLike
        The new database's folder (must not exist).
    n_per_kind : int
        Copies of each kind.
    seed : int
        Draws the source documents and clips and each transform's parameters.

    Returns
    -------
    planted : MotionDB
        ``db``'s documents (same doc ids), then the copies.
    truth : pandas.DataFrame
        One row per copy (:data:`TRUTH_COLUMNS`): ``kind``, the source's ``source_doc`` and frames
        [``source_start``, ``source_end``), the copy's ``copy_doc`` and frames [``copy_start``, ``copy_end``) (the
        whole copy), ``mirrored``, and the transform's parameters: the time ``factor`` (1 but for stretched and
        all: the copy lasts 1 / factor of its clip), ``noise_cm`` (3D standard deviation, 0 for none),
        ``donor_doc`` (the document whose bone lengths a retargeted copy took, -1 for none), ``rate`` (the rate a
        resampled copy went through, Hz; 0 for none).

    Raises
    ------
    ParameterError
        ``db`` of several frame rates, without a document of 3 s, or ``out`` exists.

    Examples
    --------
    >>> import tempfile
    >>> from mocapviz import MotionDB
    >>> planted, truth = plant_copies(MotionDB.demo(), f"{tempfile.mkdtemp()}/planted.mdb", n_per_kind=1)
    >>> len(planted), list(truth["kind"])
    (61, ['mirrored', 'stretched', 'trimmed', 'noise', 'retargeted', 'resampled', 'all'])
    """
    from ..db.database import MotionDB

    n_per_kind = count(n_per_kind, "n_per_kind")
    fps, out = db.fps, Path(out)
    if fps is None:
        raise ParameterError(f"{db.path}: documents of several frame rates; planted copies need one rate")
    if out.exists():
        raise ParameterError(f"{out}: exists; planted copies go into a new database")
    docs = db.documents
    long = docs.loc[(docs["n_frames"] >= CLIP_S[0] * fps).to_numpy(bool), "doc_id"].to_numpy(np.int64)
    if len(long) == 0:
        raise ParameterError(f"{db.path}: no document of {CLIP_S[0]:g} s to copy")
    rng = np.random.default_rng(seed)
    order = rng.permutation(long)
    actors = docs.set_index("doc_id")["actor"] if "actor" in docs else pd.Series(np.nan, index=docs["doc_id"])
    names = dict(zip(docs["doc_id"], docs["name"]))
    copies, metas, rows = [], [], []
    for i in range(n_per_kind * len(KINDS)):
        kind, doc = KINDS[i % len(KINDS)], int(order[i % len(order)])
        source = db.motion(doc)
        n = min(source.n_frames, round(rng.uniform(*CLIP_S) * fps))
        a = int(rng.integers(0, source.n_frames - n + 1))
        donor = _donor(doc, actors, rng) if kind in ("retargeted", "all") else -1
        copy, row = _copy(kind, source[a:a + n], a, donor, db, rng)
        row |= {"kind": kind, "source_doc": doc, "copy_doc": int(docs["doc_id"].max()) + 1 + i, "copy_start": 0,
                "copy_end": copy.n_frames, "mirrored": kind in MIRRORED_KINDS}  # fmt: skip
        copies.append(copy)
        metas.append({"name": f"{names[doc]}~{kind}{i // len(KINDS)}", "path": "", "source_fps": fps})
        rows.append(row)
    planted = MotionDB.open(shutil.copytree(db.path, out)).append_motions(copies, metas)
    truth = pd.DataFrame(rows, columns=TRUTH_COLUMNS)
    if not np.array_equal(planted.documents["doc_id"].to_numpy()[len(docs):], truth["copy_doc"].to_numpy()):
        raise ParameterError(f"{out}: the copies did not get the doc ids after {db.path}'s")
    return planted, truth


def _donor(doc: int, actors: pd.Series, rng) -> int:
    """A document of another actor than ``doc``'s (any document with an actor when ``doc`` has none; any other
    document when no actor is known)."""
    known = actors.notna()
    others = actors.index[known & (actors != actors.get(doc))] if known.any() else actors.index[actors.index != doc]
    return int(rng.choice(others))


def _copy(kind: str, clip, a: int, donor: int, db, rng) -> tuple:
    """One planted copy of ``clip`` (frames [a, a + len) of its document) and its truth row's span and parameters."""
    fps, n = clip.fps, clip.n_frames
    row = {"source_start": a, "source_end": a + n, "factor": 1.0, "noise_cm": 0.0, "donor_doc": -1, "rate": 0.0}
    if kind == "trimmed":
        keep = round(rng.uniform(*TRIM) * n)
        s = int(rng.integers(1, n - keep))  # both ends cut
        row |= {"source_start": a + s, "source_end": a + s + keep}
        return clip[s:s + keep], row
    if kind == "resampled":
        row["rate"] = fps / 4 if fps >= 120 else fps * 5 / 6
        return clip.resample(row["rate"]).resample(fps), row
    if kind in ("retargeted", "all"):
        row["donor_doc"] = donor
        clip = retarget(clip, donor_bones(bone_lengths(db.motion(donor).positions), bone_lengths(clip.positions)))
    if kind in ("mirrored", "all"):
        clip = mirror(clip)
    if kind in ("stretched", "all"):
        row["factor"] = 1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(*STRETCH)
        clip = replace(clip.resample(fps / row["factor"]), fps=fps)
    if kind in ("noise", "all"):
        row["noise_cm"] = rng.uniform(*NOISE_CM)
        noise = rng.normal(0.0, row["noise_cm"] / np.sqrt(3), clip.positions.shape)
        clip = replace(clip, positions=(clip.positions + noise).astype(np.float32))
    return clip, row


def donor_bones(donor, own) -> np.ndarray:
    """The bone lengths a retargeted copy is given: the donor's, but the clip's ``own`` for a bone the donor's rig
    lacks (2 cm or shorter: e.g. HDM05's clavicles, of no length, against Bandai Namco's 6 cm), which
    :func:`~mocapviz.motion.skeleton.retarget` would otherwise collapse and no retargeting back restores.

    Parameters
    ----------
    donor, own : array_like [shape=(24,)]
        :func:`~mocapviz.motion.skeleton.bone_lengths` of the donor document and of the clip, cm.

    Returns
    -------
    np.ndarray [shape=(24,)], float64
        cm.

    Examples
    --------
    >>> donor_bones([0.0, 10.0, 0.0], [0.0, 12.0, 6.0]).tolist()
    [0.0, 10.0, 6.0]
    """
    donor, own = np.asarray(donor, dtype=np.float64), np.asarray(own, dtype=np.float64)
    return np.where(donor > SHORTEST_BONE_CM, donor, own)


def planted_quality(db_or_engine, truth: pd.DataFrame, pairs: pd.DataFrame) -> pd.DataFrame:
    """Recall of the planted copies among an audit's pairs, per kind, and the pairs involving a copy that are
    none of the planted ones.

    A copy is found when a pair joins its document with its source document (either side first), covers at least
    :data:`MIN_OVERLAP` of the planted span on each side (the source's frames, the copy's), and, for the
    :data:`MIRRORED_KINDS`, is mirrored. A pair that involves a copy's document and finds no copy is a false
    positive of the copy's kind (a pair of two copies counts once overall).

    Parameters
    ----------
    db_or_engine : MotionDB or Engine
        The planted database (the truth's documents are checked against it).
    truth : pandas.DataFrame
        :func:`plant_copies`' truth.
    pairs : pandas.DataFrame
        An audit's pairs (:data:`mocapviz.similarity.audit.PAIR_COLUMNS`) of the planted database.

    Returns
    -------
    pandas.DataFrame
        One row per kind of the truth, then ``overall``: ``kind``, ``planted``, ``found``, ``recall``,
        ``false_positives``, ``cost`` (the mean cost of the pairs that found a copy, cm). ``attrs["copies"]``: the
        truth with ``found``, ``pair`` (the row of ``pairs`` that found it, -1) and ``cost`` (that pair's).

    Examples
    --------
    >>> import pandas as pd
    >>> truth = pd.DataFrame({"kind": ["noise"], "source_doc": [3], "source_start": [10], "source_end": [100],
    ...                       "copy_doc": [9], "copy_start": [0], "copy_end": [90], "mirrored": [False]})
    >>> pairs = pd.DataFrame({"doc_a": [3, 9], "start_a": [20, 0], "end_a": [100, 40], "doc_b": [9, 5],
    ...                       "start_b": [10, 0], "end_b": [90, 40], "mirrored": [False, False], "cost": [2.0, 5.0]})
    >>> planted_quality(None, truth, pairs)[["kind", "recall", "false_positives"]].to_dict("records")
    [{'kind': 'noise', 'recall': 1.0, 'false_positives': 1}, {'kind': 'overall', 'recall': 1.0, 'false_positives': 1}]
    """
    db = getattr(db_or_engine, "db", db_or_engine)
    if db is not None:
        unknown = sorted((set(truth["source_doc"]) | set(truth["copy_doc"])) - set(db.documents["doc_id"].tolist()))
        if unknown:
            raise ParameterError(f"{db.path}: the truth names documents it does not hold: {unknown[:10]}")
    doc_a, doc_b = pairs["doc_a"].to_numpy(np.int64), pairs["doc_b"].to_numpy(np.int64)
    copies = truth.copy()
    copies["found"], copies["pair"], copies["cost"] = False, -1, np.nan
    for i, t in enumerate(truth.itertuples()):
        for flip in (False, True):  # the source as side a, then as side b
            s, c = ("a", "b") if not flip else ("b", "a")
            rows = np.flatnonzero(((doc_a, doc_b)[flip] == t.source_doc) & ((doc_b, doc_a)[flip] == t.copy_doc))
            for r in rows:
                p = pairs.iloc[r]
                ok = _covered(p[f"start_{s}"], p[f"end_{s}"], t.source_start, t.source_end) >= MIN_OVERLAP and \
                    _covered(p[f"start_{c}"], p[f"end_{c}"], t.copy_start, t.copy_end) >= MIN_OVERLAP and \
                    (bool(p["mirrored"]) or t.kind not in MIRRORED_KINDS)  # fmt: skip
                if ok and not copies.at[copies.index[i], "found"]:
                    copies.loc[copies.index[i], ["found", "pair", "cost"]] = [True, int(r), float(p["cost"])]
    found_pairs = set(copies.loc[copies["found"], "pair"].tolist())
    kind_of = dict(zip(truth["copy_doc"], truth["kind"]))
    false = [r for r in range(len(pairs)) if r not in found_pairs and (doc_a[r] in kind_of or doc_b[r] in kind_of)]
    rows = []
    for kind, part in copies.groupby("kind", sort=False):
        docs = set(part["copy_doc"])
        rows.append({"kind": kind, "planted": len(part), "found": int(part["found"].sum()),
                     "false_positives": sum(doc_a[r] in docs or doc_b[r] in docs for r in false),
                     "cost": part["cost"].mean()})  # fmt: skip
    rows.append({"kind": "overall", "planted": len(copies), "found": int(copies["found"].sum()),
                 "false_positives": len(false), "cost": copies["cost"].mean()})  # fmt: skip
    table = pd.DataFrame(rows)
    table.insert(3, "recall", table["found"] / table["planted"])
    table.attrs["copies"] = copies
    return table


def _covered(start, end, a, b) -> float:
    """The share of the span [a, b) that [start, end) covers."""
    return max(0, min(end, b) - max(start, a)) / max(1, b - a)


def audit_quality(db, out, make_engine: Callable, *, n_per_kind: int = 2, seed: int = 0, progress: bool = False,
                  **options) -> pd.DataFrame:
    """Plant copies of ``db``'s clips (:func:`plant_copies`), audit the planted database
    (:meth:`Engine.audit <mocapviz.engine.Engine.audit>`) and measure how many it finds (:func:`planted_quality`).

    Parameters
    ----------
    db : MotionDB
        A database of one frame rate (not changed).
    out : str or os.PathLike
        The planted database's folder (must not exist).
    make_engine : callable
        MotionDB -> Engine (``mocapviz.Engine``; the experiments sit below the engine and do not import it).
    n_per_kind, seed : int
        As :func:`plant_copies`.
    progress : bool
        The audit's progress bars.
    **options
        The audit's parameters (``threshold``, ``min_length``, ``max_scale``, ...; its defaults otherwise).

    Returns
    -------
    pandas.DataFrame
        :func:`planted_quality`'s table; attrs ``copies`` (per copy), ``threshold`` (cm, the audit's),
        ``threshold_how``, ``seconds`` (of the audit), ``pairs`` (all of the audit's), ``database`` (the planted
        one's path).

    Examples
    --------
    >>> import tempfile
    >>> from mocapviz import Engine, MotionDB
    >>> table = audit_quality(MotionDB.demo(), f"{tempfile.mkdtemp()}/planted.mdb", Engine, n_per_kind=1)
    >>> list(table["kind"])[-1], table.attrs["threshold"] > 0
    ('overall', True)
    """
    planted, truth = plant_copies(db, out, n_per_kind=n_per_kind, seed=seed)
    with make_engine(planted) as engine:
        began = time.perf_counter()
        pairs = engine.audit(progress=progress, **options)
        seconds = time.perf_counter() - began
    table = planted_quality(planted, truth, pairs)
    table.attrs |= {"threshold": pairs.attrs["threshold"], "threshold_how": pairs.attrs["threshold_how"],
                    "seconds": seconds, "pairs": pairs, "database": str(planted.path)}  # fmt: skip
    return table
