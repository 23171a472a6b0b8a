"""Reconstruction page: a clip of the database rebuilt from six synthetic markers with local linear pose models
(Krüger, Tautges, Weber & Zinke 2010 §5.2, after Chai & Hodgins 2005; the method is :mod:`mocapviz.similarity.reconstruction`).

The test clip's four end effectors, head and root become markers with uniform noise (§5.2: "randomly disturbed
within a range of 1mm"; a fixed seed per clip, as in :mod:`mocapviz.experiments.marker_reconstruction`, so the page's
errors can be recomputed), and every frame is rebuilt from the k nearest poses of a prior that leaves the test clip
out (Table 3's "HDM" column) or, when the database names actors, every clip of the test clip's actor ("HDM-actor").
The original and the reconstruction play side by side; the per-joint and per-frame errors are plotted and the mean
and worst-frame errors (cm per joint, as in Table 3) are shown as text. Results are cached per database and settings.

A clip read from a C3D file can also be rebuilt from REAL markers: its six marker joints as estimated from the
recorded marker clusters (:mod:`mocapviz.motion.markers`), no noise added; the truth is the same take read from its
skeleton file when the database holds it (CMU ``cmu_135_02.c3d`` and ``135_02.amc``: aligned in time and on the floor,
:func:`mocapviz.experiments.markers.real_marker_clip`), else the clip's own 24 marker-derived joints.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import panel as pn

from ...engine import (
    CANONICAL_JOINTS,
    DEFAULT_K,
    MARKERS,
    NOISE_RANGE_CM,
    NUMERIC_SETS,
    PosePrior,
    aligned_takes,
    frame_actors,
    marker_clip,
    real_marker_clip,
    reconstruct,
    reconstruction_errors,
)
from ...errors import ParameterError
from ...validation import plural
from ...viz.reconstruction import error_curves, joint_error_bars
from ..documents import DocumentPicker
from ..player import SkeletonPlayer
from ..progress import Task
from ..widgets import BoundedFloatInput, BoundedIntInput, action_button, clear, notes

SEED = 0  # the markers' noise comes from np.random.default_rng([SEED, doc_id]), as in the experiment
DEFAULT_NOISE_CM = 0.1  # §5.2: +-1 mm
NOISE_STEP_CM = 0.05
PRIORS = {"without the test clip": "clip", "without the test clip's actor": "actor"}
MARKER_SOURCES = {"simulated: the clip's joints ± noise": "simulated", "real: the clip's C3D marker clusters": "real"}


# ============================================================================ computations (no widgets)
def default_k(n_frames: int) -> int:
    """The k offered first: :data:`mocapviz.similarity.reconstruction.DEFAULT_K`, at most a quarter of the database's frames (a
    prior leaving out one clip or one of several actors keeps more than that, so the default always works)."""
    return max(1, min(DEFAULT_K, n_frames // 4))


def prior_mask(db, doc: int, kind: str) -> tuple[np.ndarray, str]:
    """The frames a prior may use and what it leaves out.

    Parameters
    ----------
    db : MotionDB; doc : the test clip's doc_id; kind : "clip" (leave the clip out) or "actor" (leave out every
        clip of its actor: Table 3's HDM-actor / CMU- setting).

    Returns
    -------
    (valid, left_out): np.ndarray [shape=(N,)] bool over the database's frames, and e.g. "actor dg's clips".

    Raises
    ------
    ValueError
        ``kind`` "actor" for a clip without an actor label.
    """
    if kind == "clip":
        valid = np.ones(db.n_frames, dtype=bool)
        valid[db.frames(doc)] = False
        return valid, "the test clip"
    docs = db.documents.set_index("doc_id")
    actor = docs.at[doc, "actor"] if "actor" in docs else None
    if actor is None or pd.isna(actor):
        raise ParameterError(f"Document {doc} has no actor label: choose the prior without the test clip")
    return frame_actors(db) != actor, f"actor {actor}'s clips"


def same_take(db, doc: int) -> int | None:
    """The document of the same take as C3D document ``doc`` read from a skeleton file (AMC, BVH): the one whose
    name ends the C3D's name after an underscore (``cmu_135_02`` -> ``135_02``), or None."""
    docs = db.documents
    name = str(db.document(doc)["name"])
    others = docs[(docs["format"] != "c3d") & docs["name"].map(lambda n: name.endswith("_" + str(n)))]
    return int(others["doc_id"].iloc[0]) if len(others) else None


def real_marker_data(db, doc: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, int | None]:
    """Reconstruction test data from the real markers of C3D document ``doc``: (truth (T, 24, 3), markers (T, 6, 3),
    headings (T,), the truth's document or None). The truth is :func:`same_take`'s document aligned to it
    (:func:`~mocapviz.experiments.markers.real_marker_clip`), else the clip's own 24 joints."""
    pair = same_take(db, doc)
    own = db.motion(doc)
    if pair is None:
        return (*real_marker_clip(own, own)[:3], None)
    markers_take, skeleton_take, _ = aligned_takes(own, db.motion(pair))
    return (*real_marker_clip(markers_take, skeleton_take)[:3], pair)


def check_settings(db, doc: int, kind: str, k: int, noise_cm: float, source: str = "simulated") -> str | None:
    """A one-line reason why these settings cannot be reconstructed, or None when they can."""
    if db.fps is None:
        return "The database mixes frame rates; the markers must be at the prior's one rate: resample it first."
    if source == "real" and db.document(doc)["format"] != "c3d":
        return ("Real markers need a clip read from a C3D file (`mocapviz ingest` of .c3d files); this one was read "
                f"from a .{db.document(doc)['format']} file: choose simulated markers or a C3D clip.")
    try:
        valid, left_out = prior_mask(db, doc, kind)
    except ValueError as exc:
        return f"{exc}."
    n = int(valid.sum())
    if n == 0:
        return f"The prior is empty: the database holds nothing but {left_out}. Choose another prior or clip."
    if k is None or k < 1:
        return "k must be a positive whole number of neighbours."
    if k > n:
        return f"k = {k:,} is larger than the prior ({plural(n, 'frame')} without {left_out}): choose k ≤ {n:,}."
    try:
        NOISE_RANGE_CM.check(noise_cm, "the marker noise (± cm)")
    except ParameterError as exc:
        return f"{exc}."
    return None


def prior_for(backend, doc: int, kind: str) -> tuple[PosePrior, str]:
    """The cached PosePrior of a test clip (one per left-out clip or actor, its kd-trees reused) and what it
    leaves out; every prior of the database shares the body-frame poses and feature values."""
    valid, left_out = prior_mask(backend.db, doc, kind)
    full = backend.cached(("recon-prior",), backend.engine.pose_prior)
    key = ("recon-prior", kind, left_out if kind == "actor" else doc)
    return backend.cached(key, lambda: full.restrict(valid)), left_out


def run_reconstruction(backend, doc: int, kind: str, numeric_set: str, k: int, noise_cm: float,
                       source: str = "simulated") -> dict:
    """Reconstruct a clip from six markers, cached per database and settings: ``source`` "simulated" (its joints
    with uniform noise of ± ``noise_cm``) or "real" (a C3D clip's marker joints, :func:`real_marker_data`; the
    same take's document left out of the prior too).

    Returns
    -------
    dict: ``truth``, ``estimate`` (T, 24, 3) cm; ``errors`` (:func:`mocapviz.similarity.reconstruction.reconstruction_errors`);
    ``prior_frames`` (int), ``left_out`` (str), ``truth_doc`` (the truth's document), ``seconds`` (the first
    computation's wall time).
    """
    def compute() -> dict:
        t0 = time.perf_counter()
        prior, left_out = prior_for(backend, doc, kind)
        truth_doc = doc
        if source == "real":
            truth, markers, headings, pair = real_marker_data(backend.db, doc)
            if pair is not None:  # the same take read from its skeleton file: out of the prior as well
                truth_doc = pair
                valid = prior.valid.copy()
                valid[backend.db.frames(pair)] = False
                prior, left_out = prior.restrict(valid), f"{left_out} and the same take's document {pair}"
        else:
            truth, markers, headings = marker_clip(backend.db, doc, noise_cm, SEED)
        estimate = reconstruct(markers, headings, prior, numeric_set=numeric_set, k=k)
        return {"truth": truth, "estimate": estimate, "errors": reconstruction_errors(truth, estimate),
                "prior_frames": prior.n_valid, "left_out": left_out, "truth_doc": truth_doc,
                "seconds": time.perf_counter() - t0}

    noise = 0.0 if source == "real" else float(noise_cm)
    return backend.cached(("reconstruction", doc, kind, numeric_set, int(k), noise, source), compute)


def error_tables(errors: dict, variant: str, fps: float) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The errors as the plots' tidy tables: per joint (``joint``, ``variant``, ``error_cm``) and per frame
    (``frame``, ``time_s``, ``variant``, ``error_cm``)."""
    joints = pd.DataFrame({"joint": CANONICAL_JOINTS, "variant": variant, "error_cm": errors["per_joint_cm"]})
    per_frame = errors["per_frame_cm"]
    frames = pd.DataFrame({"frame": np.arange(len(per_frame)), "time_s": np.arange(len(per_frame)) / fps,
                           "variant": variant, "error_cm": per_frame})
    return joints, frames


# ============================================================================ the page
class ReconstructionPage(pn.viewable.Viewer):
    """Choose a test clip, a prior, a numeric set, k and the marker noise; reconstruct; compare."""

    def __init__(self, backend, selection):
        super().__init__()
        self.backend, self.selection = backend, selection
        docs = backend.documents
        has_actors = "actor" in docs and docs["actor"].notna().any()
        self.clip = DocumentPicker(backend, "test clip", selection.doc, width=560, css_classes=["mv-recon-clip"])
        self.prior = pn.widgets.Select(label="prior: the database …", width=230, css_classes=["mv-recon-prior"],
                                       options={n: v for n, v in PRIORS.items() if v == "clip" or has_actors})
        self.numeric_set = pn.widgets.Select(label="numeric set (kNN search)", options=list(NUMERIC_SETS),
                                             value="F15E", width=170, css_classes=["mv-recon-features"])
        self.k = BoundedIntInput("k neighbours per frame", default_k(backend.db.n_frames), 1, backend.db.n_frames,
                                 width=220, css_classes=["mv-recon-k"])
        self.noise = BoundedFloatInput.within("marker noise ± cm", DEFAULT_NOISE_CM, NOISE_RANGE_CM, NOISE_STEP_CM,
                                              width=190, css_classes=["mv-recon-noise"])
        self.source = pn.widgets.RadioButtonGroup(options=MARKER_SOURCES, value="simulated", align="end",
                                                  css_classes=["mv-recon-source"])
        self.run_button = action_button("Reconstruct", "mv-recon-run", self._run, width=140)
        self.message = pn.pane.Alert("", alert_type="warning", visible=False, css_classes=["mv-recon-message"])
        self.task = Task()
        self.summary = pn.pane.Markdown("", css_classes=["mv-recon-summary"])
        self.error_text = pn.pane.Markdown("", css_classes=["mv-recon-error"], styles={"font-size": "1.2em"})
        self.player = SkeletonPlayer(size=(760, 420))
        self.caption = pn.pane.Markdown("", css_classes=["mv-recon-caption"])
        # not linked: the Database page's curves share the time axis's name but show another clip
        self.joints = pn.pane.HoloViews(None, linked_axes=False, css_classes=["mv-recon-joints"])
        self.frames = pn.pane.HoloViews(None, linked_axes=False, css_classes=["mv-recon-frames"])
        self.results = pn.Column(self.error_text, pn.Row(pn.Column(self.player, self.caption), self.frames),
                                 self.joints, visible=False, sizing_mode="stretch_width")
        self._followed = selection.doc
        self.clip.param.watch(lambda e: self._bound_k(), "value")
        self.prior.param.watch(lambda e: self._bound_k(), "value")
        self._bound_k()

    def __panel__(self):
        intro = pn.pane.Markdown(
            f"### Reconstruction from six markers (Krüger et al. 2010 §5.2)\nEvery frame of the test clip is rebuilt "
            f"from its markers ({', '.join(MARKERS)}), with uniform noise, by a local linear model of its k nearest "
            "poses in the prior.", margin=(0, 10))
        options = pn.Row(self.prior, self.numeric_set, self.k, self.noise, self.source, self.run_button)
        return pn.Column(intro, self.clip, options, notes(self.k, self.noise), self.message, self.task, self.summary,
                         self.results, sizing_mode="stretch_width", css_classes=["mv-recon-page"])

    def activate(self) -> None:
        """Follow the clip chosen on the Database page since this page was last shown."""
        if self.selection.doc != self._followed:
            self._followed = self.selection.doc
            self.clip.value = self.selection.doc

    async def first_answer(self) -> None:
        """The page's answer when it is first shown: the session's clip reconstructed with the page's defaults."""
        await self._run()

    def _bound_k(self) -> None:
        """k from 1 to the frames of the chosen prior (the database without the test clip, or its actor)."""
        try:
            valid, _ = prior_mask(self.backend.db, int(self.clip.value), self.prior.value)
        except ParameterError:  # a clip without an actor: Reconstruct says so
            return
        self.k.set_bounds(1, max(1, int(valid.sum())))

    def _settings(self) -> tuple:
        return (int(self.clip.value), self.prior.value, self.numeric_set.value, self.k.value, self.noise.value,
                self.source.value)

    async def _run(self, event=None) -> None:
        doc, kind, numeric_set, k, noise, source = self._settings()
        problem = check_settings(self.backend.db, doc, kind, k, noise, source)
        self.message.object, self.message.visible = problem or "", problem is not None
        if problem:
            clear(self.summary, self.results)
            return
        result = await self.task.run("Reconstructing", run_reconstruction, self.backend, doc, kind, numeric_set, k,
                                     noise, source, busy=self.run_button, stale=(self.summary, self.results))
        if result is not None:
            self._show(result, doc, numeric_set, k, noise, source)

    def _show(self, result: dict, doc: int, numeric_set: str, k: int, noise: float, source: str = "simulated"):
        name, fps = str(self.backend.db.document(doc)["name"]), self.backend.fps_of(doc)
        err = result["errors"]
        truth_name = str(self.backend.db.document(result["truth_doc"])["name"])
        markers = (f"real markers (its C3D marker clusters), against {truth_name}" if source == "real" else
                   f"noise ± {noise:g} cm")
        self.summary.object = (
            f"**{name}** · {plural(len(result['truth']), 'frame')} · prior: {plural(result['prior_frames'], 'frame')} without "
            f"{result['left_out']} · {numeric_set} · k = {k:,} · {markers} · "
            f"computed in {result['seconds']:.1f} s")
        self.error_text.object = (f"**mean error {err['mean_cm']:.2f} cm** per joint · worst frame "
                                  f"{err['max_cm']:.2f} cm · bone length error {err['bone_cm']:.2f} cm")
        self.player.load([result["truth"], result["estimate"]], titles=["original", "reconstruction"], fps=fps)
        self.caption.object = f"left: original · right: reconstruction from {plural(len(MARKERS), 'marker')}"
        joints, frames = error_tables(err, f"without {result['left_out']}", fps)
        # one prior: the summary names it, a legend would only cover bars
        self.joints.object = joint_error_bars(joints, width=1150, height=300).opts(show_legend=False,
                                                                                  backend="bokeh")
        self.frames.object = error_curves(frames, width=560, height=420)
        self.results.visible = True
