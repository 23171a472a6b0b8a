"""Motion templates page: a class learned from its labelled examples and its instances found in the whole database
(Müller & Röder 2006; :mod:`mocapviz.relational.templates`).

The user picks a class (a ``label`` shared by at least two documents), optionally the actors whose documents teach
it, the relational set, the quantisation threshold δ, K and an optional limit on the cost. "Learn and search" then,
in a worker thread behind a progress bar: learns the template (:func:`mocapviz.relational.templates.learn_class`, cached per
class, actors and set), computes the database's relational features of the set (once per set) and finds the K best
instances by subsequence DTW (:func:`mocapviz.relational.templates.search_template`). The template is drawn as the paper draws
it (features × time, white 0, black 1, grey don't care; or its averaged values); a chosen hit plays beside one
training example of the template, the two aligned by DTW of their relational features.

The labelling loop (issue 40 item 4; the protocol :mod:`mocapviz.experiments.annotation` measures with a simulated
annotator, its calls the same): "Review round" learns the class's template from its documents and its segment labels
(:meth:`mocapviz.engine.Engine.learn_template`), shows the best hit of each of the first K documents without a class
that nobody reviewed for it yet (:func:`mocapviz.experiments.annotation.review_page`), which the user accepts or
rejects (✓ / ✗ on the table or the gallery: segment labels), then learns again. After each round the rounds' table
shows each round's template's quality: of its K best hits in documents without a class (one per document), how many
were reviewed and accepted, precision = accepted / reviewed (:func:`reviewed_precision`).
"""

from __future__ import annotations

import asyncio
import functools

import numpy as np
import pandas as pd
import panel as pn

from ...engine import (
    DONT_CARE,
    MAX_COST_RANGE,
    MotionTemplate,
    database_frames,
    dtw,
    feature_names,
    review_page,
    template_distance,
    unlabelled_documents,
)
from ...engine.parameters import default
from ...validation import count, plural
from ...viz.templates import template_image
from ..downloads import table_download
from ..gallery import HitGallery
from ..player import SkeletonPlayer
from ..progress import Task, in_thread
from ..upload import UploadBox, cache_key, example
from ..widgets import MAX_MATCHES, action_button, hit_titles, notes, parameter_box, results_table

RELATIONAL_SETS = ["2006", "2005"]  # the 39 features of Müller & Röder 2006 (the paper's), or the 31 of 2005
DEFAULT_MATCHES = default("search_template", "n_matches")
STEP = 0.01  # of the δ and max cost boxes
VIEWS = {"quantised": True, "averaged values": False}
HIT_TITLES = hit_titles("rank", "doc_id", "name", "label", "start", "end", "start_s", "end_s", "normalised_cost")
IMAGE_WIDTH = 640  # px of the template image; the player (640 px) stands beside it
COST_DECIMALS = 3
LISTED_EXAMPLES = 5  # a summary names the training documents up to this many, else counts them
# a class of a large database is learned from this many of its documents, spread over them (learn_class's
# max_examples): 2 s instead of 16 minutes for a class of 208 Bandai Namco takes, whose template of 16 found 20 of
# the class in 20 hits on every shared archive at 30 Hz, where the template of all 208 found another class
MAX_EXAMPLES = default("learn_template", "max_examples")
# the page's δ; at the paper's (the library's DELTA, 0.1) 5 of 8 class templates (16 examples each) gave all their 20
# hits on every shared archive at 30 Hz at cost 0, in no order; at 0.2, 2 gave 19 or 20 (mean precision at 20: 0.88
# and 0.84; tie_note)
DEFAULT_DELTA = default("search_template", "delta")
SECONDS_DECIMALS = 2


# ============================================================================ computations (worker thread)
def class_options(documents: pd.DataFrame) -> list[str]:
    """The classes a template can be learned from: the ``label`` values of at least two documents, sorted (empty
    when the documents have no ``label`` column)."""
    if "label" not in documents:
        return []
    labels = documents["label"].dropna().astype(str)
    counts = labels[labels != ""].value_counts()
    return sorted(counts.index[counts >= 2])


def default_class(documents: pd.DataFrame) -> str | None:
    """The class the page starts with: of :func:`class_options`, the one with the most documents (ties: the first in
    sorted order); None without classes. On every shared archive at 30 Hz that is a Bandai Namco motion of 444
    takes, whose template is searched in a few seconds, where the first in sorted order, a CMU class of two trials
    (a template of 23 s), took 24-41 s."""
    classes = class_options(documents)
    if not classes:
        return None
    sizes = documents["label"].astype(str).value_counts()
    return max(classes, key=lambda c: (sizes[c], -classes.index(c)))


def opening_class(documents: pd.DataFrame, doc: int) -> str | None:
    """The class the page opens with for a session at document ``doc``: its own class when a template can be
    learned from it (:func:`class_options`), else :func:`default_class`."""
    own = documents.loc[documents["doc_id"] == doc, "label"] if "label" in documents else pd.Series(dtype=object)
    label = str(own.iloc[0]) if len(own) and pd.notna(own.iloc[0]) else None
    return label if label in class_options(documents) else default_class(documents)


def actors_of(documents: pd.DataFrame, label: str) -> list[str]:
    """The ``actor`` values of the documents of class ``label``, sorted (empty without an ``actor`` column)."""
    if "actor" not in documents or "label" not in documents:
        return []
    rows = documents[documents["label"].astype("string").isin([str(label)]).to_numpy(bool)]  # NA: not the class
    return sorted({str(a) for a in rows["actor"].dropna() if str(a)})


def database_features(backend, relational_set: str) -> tuple[np.ndarray, list[str]]:
    """The relational features of every frame of the database, (N, f) bool and the f names, computed once per set
    (:func:`mocapviz.features.relational_features`, each document on its own)."""
    return backend.engine.relational_values(relational_set), feature_names(relational_set)


def _actors_key(actors) -> tuple[str, ...] | None:
    """The actors as a cache key: None (all documents of the class) for none chosen, else sorted and unique."""
    return tuple(sorted({str(a) for a in actors})) if actors else None


def labels_version(backend) -> int:
    """The number of changes of the database's segment labels: a template learned before a change is learned again
    (it learns from the labels too)."""
    return len(backend.engine.label_history())


def learn(backend, label: str, actors, relational_set: str, take=None) -> MotionTemplate:
    """The motion template of class ``label`` (:func:`mocapviz.relational.templates.learn_class`) from at most
    :data:`MAX_EXAMPLES` of its documents, and the session's uploaded ``take`` too when given (an example that is
    no document: ``Engine.learn_template(examples=...)``), cached per (label, actors, set, take).

    Parameters
    ----------
    backend : Backend
    label : str, a ``label`` of the documents.
    actors : sequence of str; empty or None: the class's documents of every actor.
    relational_set : {"2006", "2005"}
    take : Upload, optional, the session's uploaded take, learned from as one more example.

    Returns
    -------
    MotionTemplate, values (K, f) in [0, 1]; ``meta["doc_ids"]`` the training documents (``meta["extra_examples"]``:
    1 with the take).
    """
    key = _actors_key(actors)
    taken = None if take is None else cache_key(take)
    return backend.cached(("templates.template", str(label), key, str(relational_set), taken, labels_version(backend)),
                          lambda: backend.engine.learn_template(str(label), actors=None if key is None else list(key),
                                                                relational_set=str(relational_set),
                                                                examples=None if take is None else [example(take)]))  # fmt: skip


def search_template(backend, template: MotionTemplate, delta: float, n_matches: int,
                    max_cost: float | None) -> pd.DataFrame:  # fmt: skip
    """The instances of ``template`` in the whole database: :func:`mocapviz.relational.templates.search_template`
    over the Backend's relational features of the template's set, within the page's bounds.

    Parameters
    ----------
    backend : Backend
    template : MotionTemplate of a relational set (``meta["relational_set"]``).
    delta : float, quantisation threshold in DELTA_RANGE, 0 < δ < 0.5.
    n_matches : int, K, 1..MAX_MATCHES.
    max_cost : float in [0, 1] or None: keep only hits of at most this normalised cost.

    Returns
    -------
    pd.DataFrame, the hit table, best first (start, end: frames of the document, half-open; start_s, end_s), with
    cost (DTW cost, sum of the per-frame mean mismatch) and normalised_cost (cost per template frame, in [0, 1]).
    """
    n_matches = count(n_matches, "K", 1, MAX_MATCHES)
    if max_cost is not None:
        max_cost = MAX_COST_RANGE.check(max_cost, "the max cost (a mean mismatch per frame)")
    return backend.engine.search_template(template, n_matches=n_matches, delta=delta, max_cost=max_cost)


def learn_and_search(backend, label: str, actors, relational_set: str, delta: float, n_matches: int,
                     max_cost: float | None, take=None) -> tuple[MotionTemplate, pd.DataFrame]:  # fmt: skip
    """:func:`learn` (with the uploaded ``take`` as an example when given) then :func:`search_template` (the page's
    button); the hits cached per all the arguments."""
    template = learn(backend, label, actors, relational_set, take)
    key = ("templates.hits", str(label), _actors_key(actors), str(relational_set), delta, n_matches, max_cost,
           None if take is None else cache_key(take), labels_version(backend))
    return template, backend.cached(key, lambda: search_template(backend, template, delta, n_matches, max_cost))


def review_round(backend, label: str, relational_set: str, n_matches: int) -> tuple:
    """One round of the labelling loop: the template of ``label`` learned from its documents and segment labels now,
    the page to review (:func:`mocapviz.experiments.annotation.review_page`: the best hit of each of the first
    ``n_matches`` documents without a class and without a review for ``label``), as the annotation experiment
    calls them, and the template's :func:`best_documents`. Returns (template, page, documents)."""
    engine = backend.engine
    template = engine.learn_template(str(label), relational_set=str(relational_set))
    page = review_page(engine, template, unlabelled_documents(backend.db), str(label), int(n_matches))
    return template, page, best_documents(backend, template, n_matches)


def best_documents(backend, template: MotionTemplate, n_matches: int) -> set[int]:
    """The documents without a class of a template's ``n_matches`` best hits, one hit per document (searched once
    per round: the reviews change, the template's hits do not)."""
    unlabelled = unlabelled_documents(backend.db)
    found = backend.engine.search_template(template, n_matches=4 * int(n_matches))  # enough for n documents
    return set(found.loc[found["doc_id"].isin(unlabelled), "doc_id"].drop_duplicates().head(n_matches).astype(int))


def reviewed_precision(backend, label: str, docs: set[int]) -> dict:
    """The quality of a round's template by the reviews so far: of ``docs`` (its :func:`best_documents`), the
    ones reviewed for ``label`` (an accepted or a rejected hit of it) and the ones accepted.

    Returns
    -------
    dict: ``hits``, ``reviewed``, ``accepted`` (counts of documents), ``precision`` (accepted / reviewed; NaN when
    none is reviewed).
    """
    labels = backend.engine.segment_labels(label=label)
    accepted = docs & set(labels.loc[labels["source"] == "accepted hit", "doc_id"].astype(int))
    reviewed = docs & set(labels.loc[labels["source"].isin(["accepted hit", "rejected hit"]), "doc_id"].astype(int))
    return {"hits": len(docs), "reviewed": len(reviewed), "accepted": len(accepted),
            "precision": len(accepted) / len(reviewed) if reviewed else float("nan")}


def rounds_table(rounds: list[dict]) -> str:
    """The rounds of the loop as a Markdown table: round, examples learned from, the template's hits (documents),
    reviewed, accepted and precision (:func:`reviewed_precision`)."""
    lines = ["| round | examples | hits | reviewed | accepted | precision |", "|---:|---:|---:|---:|---:|---:|"]
    for r in rounds:
        q = r["quality"]
        precision = "–" if q["reviewed"] == 0 else f"{q['precision']:.2f}"
        lines.append(f"| {r['round']} | {r['examples']} | {q['hits']} | {q['reviewed']} | {q['accepted']} | "
                     f"{precision} |")
    return "\n".join(lines)


def hits_view(hits: pd.DataFrame) -> pd.DataFrame:
    """The hits table as shown: the columns of HIT_TITLES (the titles of every page), seconds to 0.01, the cost
    to 0.001 (as text)."""
    shown = hits[[c for c in HIT_TITLES if c in hits]].copy()
    for c in ("start_s", "end_s"):
        shown[c] = shown[c].map(lambda v: f"{v:.{SECONDS_DECIMALS}f}")
    shown["normalised_cost"] = shown["normalised_cost"].map(lambda v: f"{v:.{COST_DECIMALS}f}")
    return shown


def tie_note(hits: pd.DataFrame, delta: float) -> str:
    """What the count line adds when two or more hits share the cost 0 (shown as 0.000): their order says nothing.

    Each such hit agrees with every entry the template cares for at ``delta``; a template of a class whose takes
    share most of their features (many styles of one motion) cares for little else. A larger δ cares for more of its
    entries and ranks the hits: on every shared archive at 30 Hz, of 8 class templates (16 examples each), 5 gave
    all their 20 hits at cost 0 at δ = 0.1, and 2 gave 19 or 20 at δ = 0.2."""
    ties = int((hits["normalised_cost"] < 0.5 * 10.0**-COST_DECIMALS).sum()) if len(hits) else 0
    if ties < 2:
        return ""
    return (f" — {ties} of them at cost 0.000, which match every entry the template cares for at δ = {delta:g}: "
            f"their order says nothing; a larger δ cares for more entries and ranks them")


def dont_care_share(template: MotionTemplate, delta: float) -> float:
    """The share of the template's (K, f) entries that are "don't care" at ``delta``, in [0, 1]."""
    return float((template.quantised(delta) == DONT_CARE).mean())


def template_summary(template: MotionTemplate, delta: float) -> str:
    """One line: the class, its examples (their documents when at most :data:`LISTED_EXAMPLES`, else their count),
    iterations, frames × features and the don't-care share."""
    k, f = template.values.shape
    docs = template.meta.get("doc_ids", [])
    actors = template.meta.get("actors")
    n, rounds = template.n_examples, template.iterations
    which = (f"{plural(len(docs), 'document', number=False)} {', '.join(map(str, docs))}"
             if len(docs) <= LISTED_EXAMPLES else plural(len(docs), "document"))
    who = "actors " + ", ".join(actors) if actors else "every actor"
    of = template.meta.get("class_documents", n)
    return (f"**{template.label}**: learned from {n:,}{f' of its {of:,}' if of > n else ''} "
            f"{plural(n, 'example', number=False)} ({which}; {who}) in {plural(rounds, 'iteration')}; "
            f"{plural(k, 'frame')} × {f} features of set "
            f"{template.meta.get('relational_set', '?')}, {dont_care_share(template, delta):.1%} don't care at "
            f"δ = {delta:g}")


def image_legend(template: MotionTemplate, delta: float, quantised: bool) -> str:
    """The line under the template image: what its shades mean."""
    if quantised:
        return (f"Quantised at δ = {delta:g}: white 0, black 1, grey don't care "
                f"({dont_care_share(template, delta):.1%} of the entries).")
    return f"Averaged values of the {template.n_examples} aligned examples, from white 0 to black 1 (not quantised)."


def training_example(template: MotionTemplate, hit_doc: int) -> int:
    """The training document shown beside a hit: the first of ``template.meta["doc_ids"]`` other than the hit's own
    document (a hit inside a training example is shown beside another one), or the hit's document when it is the
    only example."""
    docs = [int(d) for d in template.meta["doc_ids"]]
    others = [d for d in docs if d != int(hit_doc)]
    return (others or docs)[0]


def example_alignment(backend, template: MotionTemplate, example_doc: int, hit_doc: int, start: int,
                      end: int) -> np.ndarray:  # fmt: skip
    """The DTW alignment of a training example's clip and a hit's clip, by their relational features of the
    template's set and the local cost of learning a template (:func:`mocapviz.relational.templates.template_distance`, the
    mean mismatch over the features).

    Parameters
    ----------
    backend : Backend
    template : MotionTemplate
    example_doc : int, the training document (its whole clip).
    hit_doc, start, end : int, the hit: frames start:end (half-open) of document ``hit_doc``.

    Returns
    -------
    np.ndarray [shape=(L, 2)], int64: per step the frame of the example clip and of the hit clip (from its first
    frame), the player's ``alignment``.
    """
    values, _ = database_features(backend, template.meta.get("relational_set", "2006"))
    rows = backend.db.frames(int(example_doc))
    hit = values[database_frames(backend.db, hit_doc, start, end)]
    _, path = dtw(values[rows].astype(np.float64), hit, distance=template_distance)
    return path


# ============================================================================ the page
class TemplatesPage(pn.viewable.Viewer):
    """Learn a class's motion template, draw it, list its instances in the database, play one beside an example."""

    def __init__(self, backend, selection):
        super().__init__()
        self.backend, self.selection = backend, selection
        docs = backend.documents
        self.classes = class_options(docs)
        self.template, self.hits, self.delta_used = None, None, DEFAULT_DELTA
        self.label = pn.widgets.Select(label="class", options=self.classes, value=opening_class(docs, selection.doc),
                                       width=260,
                                       css_classes=["mv-templates-class"])
        self.actors = pn.widgets.MultiChoice(label="actors to learn from (none = all)", width=240,
                                             visible="actor" in docs, css_classes=["mv-templates-actors"])
        self.relational_set = pn.widgets.RadioButtonGroup(options=RELATIONAL_SETS, value="2006", width=120,
                                                          align="end", css_classes=["mv-templates-set"])
        self.delta = parameter_box("δ (quantisation)", "delta", "search_template", width=130,
                                   css_classes=["mv-templates-delta"])
        self.n_matches = parameter_box("K (results)", "n_matches", "search_template", most=MAX_MATCHES, width=120,
                                       css_classes=["mv-templates-k"])
        self.max_cost = parameter_box("max cost / frame", "max_cost", "search_template", width=210,
                                      css_classes=["mv-templates-max-cost"])
        self.button = action_button("Learn and search", "mv-templates-run", self._run, width=150)
        self.round_button = action_button("Review round", "mv-templates-round", self._round, width=150)
        self.upload = UploadBox(backend, selection, "mv-templates-upload")
        self.with_take = pn.widgets.Checkbox(name="learn from the uploaded take too", value=False,
                                             css_classes=["mv-templates-with-take"])
        self.rounds: list[dict] = []  # the loop's rounds: round, label, examples, documents, quality
        self.rounds_view = pn.pane.Markdown("", css_classes=["mv-templates-rounds"], margin=(0, 10))
        self.task = Task()
        self.summary = pn.pane.Markdown("", css_classes=["mv-templates-summary"], margin=(0, 10))
        self.view = pn.widgets.RadioButtonGroup(options=list(VIEWS), value="quantised", width=220,
                                                css_classes=["mv-templates-view"])
        self.image = pn.pane.HoloViews(None, css_classes=["mv-templates-image"])
        self.legend = pn.pane.Markdown("", width=IMAGE_WIDTH, margin=(0, 10), css_classes=["mv-templates-legend"])
        self.count = pn.pane.Markdown("", css_classes=["mv-templates-count"], margin=(0, 10))
        self.table = results_table(pd.DataFrame(columns=list(HIT_TITLES)), "mv-templates-table", HIT_TITLES,
                                   page_size=10, selectable=True)
        self.playing = pn.pane.Markdown(PLAY_HINT, margin=(0, 10), width=640,
                                        css_classes=["mv-templates-playing"])  # fmt: skip
        self.player = SkeletonPlayer(size=(640, 380))
        self.player_box = pn.Column(self.player, visible=False, css_classes=["mv-templates-player"])
        self.label.param.watch(self._on_class, "value")
        self.view.param.watch(lambda e: self._draw(), "value")
        self.table.param.watch(self._on_select, "selection")
        self.download = table_download(backend, self.table, self._found_by, "mv-templates-download")
        self.gallery = HitGallery(backend, self.table, "mv-templates-gallery")
        if self.gallery.review is not None:
            self.table.param.watch(lambda event: self._show_rounds(), "value")  # a review changed the states
        self._on_class()

    def __panel__(self):
        if not self.classes:
            why = "its documents have no label" if "label" not in self.backend.documents else \
                "no label is shared by two or more of its documents"  # fmt: skip
            return pn.pane.Markdown(f"No motion template can be learned from this database: {why}. Ingest the "
                                    "motions with a label table (`mocapviz ingest FOLDER --labels TABLE`: a TSV/CSV "
                                    "with a 'file' and a 'class' column, two files or more per class; a `labels.tsv`"
                                    " beside the files is read by itself) and open that database.",
                                    css_classes=["mv-templates-none"], margin=(0, 10))
        intro = pn.pane.Markdown(INTRO, margin=(0, 10), sizing_mode="stretch_width")
        inputs = pn.Row(self.label, self.actors, pn.Column("relational set", self.relational_set, margin=(0, 5)),
                        self.delta, self.n_matches, self.max_cost, self.button, self.round_button)
        # the hits table takes the page's width; the template is drawn below it, beside the hit playing
        template = pn.Column(self.view, self.image, self.legend)
        playing = pn.Column(self.playing, self.player_box)
        task = pn.Column(self.task, css_classes=["mv-templates-task"], margin=0, sizing_mode="stretch_width")
        return pn.Column(intro, inputs, pn.Row(self.upload, self.with_take),
                         notes(self.delta, self.n_matches, self.max_cost), task, self.summary,
                         self.count, self.rounds_view, self.gallery, self.download.panel(), pn.Row(template, playing),
                         sizing_mode="stretch_width")

    async def first_answer(self) -> None:
        """The page's answer when it is first shown: the template of the session clip's class (or the default
        class, :func:`opening_class`) learned and searched with the page's defaults; nothing without classes (the
        page says what to do)."""
        if self.classes:
            await self._run()

    def _found_by(self) -> str:
        """The template of the hits shown, in words (written into exported files)."""
        t = self.template
        if t is None:
            return "motion template search"
        return (f"motion template {t.label!r} ({plural(t.n_examples, 'example')}, delta {self.delta_used:g}) searched by "
                "subsequence DTW")

    def _on_class(self, event=None) -> None:
        """Offer the actors of the chosen class only (every choice then has an example to learn from)."""
        options = actors_of(self.backend.documents, self.label.value) if self.label.value else []
        self.actors.param.update(options=options, value=[a for a in self.actors.value if a in options])
        if self.gallery.review is not None:
            self.gallery.review.suggest(self.label.value)

    def _inputs(self) -> tuple:
        """(label, actors, set, δ, K, max cost) the widgets ask for."""
        return (self.label.value, tuple(self.actors.value), self.relational_set.value, self.delta.value,
                self.n_matches.value, self.max_cost.value)

    async def _run(self, event=None) -> None:
        inputs = self._inputs()
        take = self.selection.upload if self.with_take.value else None
        result = await self.task.run("Learning and searching", functools.partial(learn_and_search, take=take),
                                     self.backend, *inputs,
                                     busy=self.button, stale=(self.summary, self.count, self.table, self.image,
                                                              self.legend, self.player_box))  # fmt: skip
        if result is None:
            self.template, self.hits = None, None
            return
        label, _, _, delta, n_matches, max_cost = inputs
        self.template, self.hits, self.delta_used = *result, delta
        self.summary.object = template_summary(self.template, delta)
        self.gallery.show_hits(hits_view(self.hits))
        self.player_box.visible, self.playing.object = False, PLAY_HINT
        n = len(self.hits)
        self.count.object = (f"**{plural(n, 'hit')}** of the {label} template in the whole database "
                             f"(K = {n_matches}" + (f", cost / frame ≤ {max_cost:g}" if max_cost is not None else "")
                             + ")" + ("; try a larger max cost" if self.hits.empty else "")
                             + ("; the uploaded take among its examples" if take is not None else "")
                             + tie_note(self.hits, delta))  # fmt: skip
        await asyncio.sleep(0)  # let the hits and their count reach the browser before the template is drawn
        self._draw()

    async def _round(self, event=None) -> None:
        """A round of the labelling loop (:func:`review_round`): the class's template learned from every label so
        far, the page of documents to review in the table and the gallery, the round added to the rounds' table."""
        label, relational_set, n_matches = self.label.value, self.relational_set.value, self.n_matches.value
        result = await self.task.run("Learning from the labels and finding documents to review", review_round,
                                     self.backend, label, relational_set, n_matches, busy=self.round_button,
                                     stale=(self.summary, self.count, self.table, self.image, self.legend,
                                            self.player_box))  # fmt: skip
        if result is None:
            return
        self.template, self.hits, best = result
        self.delta_used = default("search_template", "delta")
        self.rounds.append({"round": len(self.rounds) + 1, "label": label, "examples": self.template.n_examples,
                            "documents": best})
        self.summary.object = template_summary(self.template, self.delta_used)
        self.gallery.show_hits(hits_view(self.hits))
        n = len(self.hits)
        self.count.object = (f"**Round {len(self.rounds)}**: {plural(n, 'document')} without a class to review for "
                             f"**{label}**, the best hit of each (✓ accepts it, ✗ rejects it; then the next round "
                             "learns from them)" if n else f"**Round {len(self.rounds)}**: no document without a "
                             f"class is left to review for **{label}**")
        self._show_rounds()
        await asyncio.sleep(0)
        self._draw()

    def _show_rounds(self) -> None:
        """The rounds' table, the quality of each round's template by the reviews so far."""
        for r in self.rounds:
            r["quality"] = reviewed_precision(self.backend, r["label"], r["documents"])
        self.rounds_view.object = rounds_table(self.rounds) if self.rounds else ""

    def _draw(self) -> None:
        if self.template is not None:
            quantised = VIEWS[self.view.value]
            image = template_image(self.template, quantised=quantised, delta=self.delta_used, width=IMAGE_WIDTH)
            self.image.object = image.opts(fontsize={"title": 10, "yticks": 7})
            self.legend.object = image_legend(self.template, self.delta_used, quantised)

    async def _on_select(self, event) -> None:
        if not event.new or self.hits is None:
            return
        hit = self.hits.iloc[event.new[0]]
        doc = int(hit["doc_id"])
        example = training_example(self.template, doc)
        start, end = int(hit["start"]), int(hit["end"])
        path = await in_thread(example_alignment, self.backend, self.template, example, doc, start, end)
        positions = self.backend.db.positions
        clips = [positions[self.backend.db.frames(example)],
                 positions[database_frames(self.backend.db, doc, start, end)]]
        self.player.load(clips, titles=[f"example: document {example}", f"hit {hit['rank']}: document {doc}"],
                         fps=self.backend.fps_of(doc), alignment=path)
        self.player_box.visible = True
        name = self.backend.db.document(example)["name"]
        self.playing.object = (f"Playing training example document {example} ({name}) beside hit {hit['rank']} "
                               f"(document {doc}, {hit['name']}, frames {start}:{end}), aligned by "
                               f"DTW of their relational features ({plural(len(path), 'step')}).")


PLAY_HINT = ("Click a hit to play it beside a training example of the template, aligned by DTW of their relational "
             "features.")
INTRO = ("A motion template (Müller & Röder 2006) is learned from the documents of a class: their relational "
         "features are warped onto a common time line by DTW and averaged; quantised with δ, an entry below δ is 0 "
         "(white), above 1 − δ is 1 (black), else \"don't care\" (grey). Its instances are found in every document "
         "by subsequence DTW that ignores the don't-care entries; the cost per template frame is the mean share of "
         "cared-for features that disagree (0 = a perfect match).")
