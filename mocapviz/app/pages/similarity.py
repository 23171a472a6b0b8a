"""Similarity search page: numeric similarity searches of Krüger, Tautges, Weber & Zinke 2010 on the session's clip.

0. Search (:class:`mocapviz.similarity.search.SimilaritySearch`): the whole clips, or the stretches of documents, that move
   most like the current span by DTW, exact or fast; a chosen result plays beside the query, aligned by its DTW
   warping path.
1. Nearest neighbours of the current frame (§3.3): the k nearest database frames by a numeric feature set (kd-tree
   of :meth:`Engine.neighbours`), as a table and drawn together in the body frame as in Fig. 1.
2. Global motion matching of the current span with the lazy neighbourhood graph (§4.1): the K best matches; a
   chosen match plays beside the query, step by step along its warping path.
3. The similarity matrices of Fig. 3: the span against the documents of the best matches, with the cells the graph
   computed and its warping paths (behind its own button: it costs a full distance matrix).

The example (document, frame, span) is the one chosen on the Database page (:class:`~mocapviz.app.state.Selection`).
Every result is computed in a worker thread behind a progress bar and cached per database (``Backend.cached``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import panel as pn

from ...engine import NUMERIC_SETS, database_frames, graph_k, scaled_k, shortest_match, similarity_matrices
from ...engine.parameters import default, parameter
from ...errors import ParameterError
from ...validation import count, plural
from ...viz.matching import similarity_layout
from ...viz.palette import OTHERS, SIDE_NAMES, SIDES, legend
from ...viz.skeleton import neighbour_poses, png_bytes
from ..documents import UPLOADED, DocumentPicker
from ..downloads import table_download
from ..gallery import HitGallery
from ..player import SkeletonPlayer
from ..progress import Task
from ..upload import Upload, UploadBox, cache_key, example, query_clip, query_fps, query_frames, query_name
from ..widgets import (
    MAX_MATCHES,
    BoundedIntInput,
    action_button,
    hit_columns,
    hit_titles,
    notes,
    parameter_box,
    results_table,
)

SEARCH_SETS = [s for s in NUMERIC_SETS if not s.startswith("Fp")]  # the numeric sets offered: Fp need a PCA model
MAX_NEIGHBOURS = 256  # Fig. 1 draws 256 neighbours; more make an unreadable figure and a slow render
MAX_MATRIX_CELLS = 600_000  # query frames x small-database frames of the Fig. 3 matrices
# the graph matches at most the span's first this many seconds (graph_span): its k-NN of every query frame is most of
# its time (some CMU takes, alone in their part of the feature space, cost 16 ms a frame). On every shared archive at
# 30 Hz (k = 1,143), 20 takes of at least 10 s: their first 10 s took 0.29 s median, 1.63 s p95, 1.72 s at most;
# their first 4 s 0.13, 0.60 and 0.63 s (benchmarks/bench_dashboard.py, REPORT section 12 of 2026-11-27)
LNG_MAX_SECONDS = 4.0
MATRIX_K_AT_30HZ = 32  # neighbours per query frame on Fig. 3's small database (similarity_matrices' default)
MATRIX_DOCS = 3  # documents of the best matches forming the small database of Fig. 3
SEARCH_KINDS = {"whole clips": "clips", "stretches": "stretches"}
# the tables' columns, under the titles every page gives them (widgets.HIT_TITLES)
KNN_TITLES = hit_titles("rank", "doc_id", "name", "label", "start", "start_s", "distance")
KNN_DECIMALS = {"start_s": 3, "distance": 2}
SEARCH_TITLES = hit_titles("rank", "doc_id", "name", "label", "start", "end", "frames", "start_s", "end_s", "cost",
                           "normalised_cost")  # fmt: skip
SEARCH_DECIMALS = {"start_s": 2, "end_s": 2, "cost": 1, "normalised_cost": 3}
MATCH_TITLES = hit_titles("rank", "doc_id", "name", "label", "start", "end", "frames", "start_s", "end_s", "cost",
                          "cost_per_frame")  # fmt: skip
MATCH_DECIMALS = {"start_s": 2, "end_s": 2, "cost": 1, "cost_per_frame": 2}


# ============================================================================ computations (worker thread)
def nearest_frames(backend, name: str, doc: int, frame: int, k: int, exclude_own: bool,
                   per_document: bool = False) -> pd.DataFrame:  # fmt: skip
    """The k nearest database frames of one frame (Krüger et al. 2010 §3.3).

    Parameters
    ----------
    backend : Backend
    name : str, numeric set (distances in its units, cm for F15E).
    doc, frame : the query frame, ``frame`` counted within document ``doc`` (or within an uploaded take, an
        :class:`~mocapviz.app.upload.Upload`: nothing to exclude).
    k : int, 1 <= k <= min(MAX_NEIGHBOURS, indexed frames).
    exclude_own : bool, leave out the frames of the query's own document.
    per_document : bool, one row per document: its nearest of the k neighbours.

    Returns
    -------
    pd.DataFrame, :func:`mocapviz.similarity.knn.describe_frames`: the hit table of one-frame hits (start = the
    frame within its document, end = start + 1) with ``distance``, nearest first; ``attrs["neighbours"]`` the
    neighbours found (more than the rows when ``per_document``).
    """
    n = query_frames(backend, doc)  # an uploaded take's, or a document's (the one "no such document" error)
    if not 0 <= frame < n:
        raise ParameterError(f"frame {frame} is outside {query_name(backend, doc)} (frames 0..{n - 1})")
    k = count(k, "k", 1, min(MAX_NEIGHBOURS, backend.db.n_frames))
    table = backend.engine.neighbours(example(doc), frame, k=k, numeric_set=name, exclude_document=exclude_own,
                                      per_document=per_document)  # fmt: skip
    table.attrs["neighbours"] = table.attrs["found"]
    return table


def neighbours_png(backend, doc: int, frame: int, neighbours: pd.DataFrame) -> bytes:
    """Fig. 1 of Krüger et al. 2010 as PNG bytes: the pose of ``frame`` of document ``doc`` (bones by side, as the
    player draws them) and, faint grey, the poses of the one-frame hits ``neighbours`` (:func:`nearest_frames`), drawn
    together in the body frame (:func:`mocapviz.viz.skeleton.neighbour_poses`)."""
    db = backend.db
    rows = [database_frames(db, d, s, e).start for d, s, e in zip(neighbours["doc_id"], neighbours["start"],
                                                                   neighbours["end"])]  # fmt: skip
    query = query_clip(backend, doc, frame, frame + 1)[0]  # a document's frame, or an uploaded take's
    return png_bytes(neighbour_poses(query, db.positions[np.asarray(rows, dtype=np.int64)]))


def match_span(backend, name: str, doc: int, span: tuple[int, int], k: int, n_matches: int,
               exclude_own: bool) -> pd.DataFrame:
    """The K best matches of a span in the database by the lazy neighbourhood graph (Krüger et al. 2010 §4.1):
    :func:`mocapviz.similarity.motion_matching.match_motion` over the Backend's features and kd-tree.

    Parameters
    ----------
    backend : Backend
    name : str, numeric set.
    doc : int, span : (start, end) frames of document ``doc``, half-open, at least 2 (the library checks it).
    k : int, neighbours per query frame (1 <= k <= indexed frames).
    n_matches : int, matches wanted (K, at most MAX_MATCHES).
    exclude_own : bool, no match inside the query's own document.

    Returns
    -------
    pd.DataFrame, the hit table, best first, with cost, cost_per_frame and path ((L, 2) int64 of (query frame
    within the span, frame within the match's document)); each match at least half the span long (the library's
    ``min_length``, as the DTW search's stretches).
    """
    k = count(k, "k", 1, backend.db.n_frames)
    n_matches = count(n_matches, "K", 1, MAX_MATCHES)
    return backend.engine.match(example(doc), frames=span, numeric_set=name, method="lng", n_matches=n_matches, k=k,
                                exclude_document=exclude_own, paths=True)


def search_span(backend, name: str, doc: int, span: tuple[int, int], kind: str, mode: str, n_matches: int,
                exclude_own: bool) -> pd.DataFrame:  # fmt: skip
    """The documents (``kind="clips"``) or stretches (``"stretches"``) that move most like the span, by DTW on a
    numeric set (:class:`mocapviz.similarity.search.SimilaritySearch`, one per numeric set in the Backend).

    Parameters
    ----------
    backend : Backend
    name : str, numeric set.
    doc, span : the query: frames start:end (half-open) of document ``doc``.
    kind : {"clips", "stretches"}
    mode : {"exact", "fast"} (or "brute").
    n_matches : int, results wanted (1..MAX_MATCHES).
    exclude_own : bool, leave out the query's own document.

    Returns
    -------
    pd.DataFrame, the search's hit table as it is (rank, doc_id, name, start, end, frames, start_s, end_s, cost,
    normalised_cost, labels, path ((L, 2) (query frame within the span, frame within the result's document))).
    ``attrs``: the search's (ms, aligned, ...).
    """
    n_matches = count(n_matches, "K", 1, MAX_MATCHES)
    if kind not in SEARCH_KINDS.values():
        raise ParameterError(f"kind must be one of {', '.join(SEARCH_KINDS.values())}; got {kind!r}")
    run = backend.engine.clips if kind == "clips" else backend.engine.stretches
    return run(example(doc), frames=span, numeric_set=name, n_matches=n_matches, mode=mode, exclude_document=exclude_own,
               paths=True)


def graph_span(span, fps: float) -> tuple[int, int]:
    """The part of a span (start, end; frames, half-open) that the page's lazy neighbourhood graph matches: its first
    :data:`LNG_MAX_SECONDS` seconds at ``fps`` (all of a shorter span).

    Examples
    --------
    >>> graph_span((30, 1000), 30.0), graph_span((30, 100), 30.0), graph_span((0, 1000), 120.0)
    ((30, 150), (30, 100), (0, 480))
    """
    start, end = int(span[0]), int(span[1])
    return start, min(end, start + round(LNG_MAX_SECONDS * fps))


def match_alignment(path: np.ndarray, match_start: int) -> np.ndarray:
    """A match's warping path as the player's alignment of (query span clip, match clip).

    Parameters
    ----------
    path : np.ndarray [shape=(L, 2)], int, (query frame within the span, frame within the match's document) per step.
    match_start : int, the match's first frame within its document (the hit's ``start``).

    Returns
    -------
    np.ndarray [shape=(L, 2)], int64: per step the frame of the query clip and of the match clip (which starts at
    ``match_start``).
    """
    return np.asarray(path, dtype=np.int64) - np.array([0, match_start], dtype=np.int64)


def matrix_docs(matches: pd.DataFrame, most: int = MATRIX_DOCS) -> list[int]:
    """The documents of the best matches, best first, each once, at most ``most``: Fig. 3's small database."""
    return [int(d) for d in pd.unique(matches["doc_id"])[:most]]


def similarity_result(backend, name: str, doc: int, span: tuple[int, int], k: int, database_docs: list[int]) -> dict:
    """Fig. 3 of Krüger et al. 2010 for the span ((start, end) of ``doc``, half-open) against ``database_docs``:
    the distance matrix by ``name``, the cells the graph computed, its paths, and subsequence DTW on Dpc1
    (:func:`similarity_matrices`).

    Raises
    ------
    ParameterError
        No document to compare with, or a matrix of more than MAX_MATRIX_CELLS cells (shorten the span).
    """
    _document_only(doc, "the similarity matrix")
    start, end = int(span[0]), int(span[1])  # the span match_span checked
    if not database_docs:
        raise ParameterError("no match to compare with: the span matched nothing")
    n = sum(backend.db.frames(d).stop - backend.db.frames(d).start for d in database_docs)
    if (end - start) * n > MAX_MATRIX_CELLS:
        raise ParameterError(f"the matrix would have {end - start} x {n:,} cells (at most {MAX_MATRIX_CELLS:,}); "
                             f"choose a span of at most {plural(MAX_MATRIX_CELLS // n, 'frame')}")
    return similarity_matrices(backend.db, doc, (start, end), database_docs, numeric_sets=(name,), k=k)


# ============================================================================ the page
class SimilarityPage(pn.viewable.Viewer):
    """kNN of the current frame (Fig. 1), LNG matching of the current span with aligned playback, and Fig. 3."""

    def __init__(self, backend, selection):
        super().__init__()
        self.backend, self.selection = backend, selection
        self.query = pn.pane.Markdown("", css_classes=["mv-similarity-query"], margin=(0, 10))
        self.clip = DocumentPicker(backend, "query clip", selection.doc, selection, width=420,
                                   css_classes=["mv-similarity-doc"])
        self.clip.param.watch(self._on_clip, "value")
        self.upload = UploadBox(backend, selection, "mv-similarity-upload")
        self.numeric_set = pn.widgets.Select(label="numeric set", options=SEARCH_SETS,
                                             value=default("clips", "numeric_set"), width=160)
        self.exclude_own = pn.widgets.Checkbox(label="exclude the query's own document", width=260,
                                               value=default("clips", "exclude_document"),
                                               align="end", css_classes=["mv-exclude-own"])
        self._build_search()
        self._build_knn()
        self._build_match()
        self._build_matrix()
        selection.param.watch(lambda *events: self.activate(), ["doc", "frame", "span", "upload", "use_upload",
                                                                "upload_span"])
        self.activate()

    def _build_search(self) -> None:
        self.search_kind = pn.widgets.RadioButtonGroup(options=list(SEARCH_KINDS), value="whole clips", width=220,
                                                       align="end", css_classes=["mv-search-kind"])
        self.search_mode = pn.widgets.RadioButtonGroup(options=[m for m in parameter("mode").choices if m != "brute"],
                                                       value=default("clips", "mode"), width=140, align="end",
                                                       css_classes=["mv-search-mode"])  # fmt: skip
        self.search_k = parameter_box("K results", "n_matches", "clips", most=MAX_MATCHES, width=130,
                                      css_classes=["mv-search-k"])
        self.search_button = action_button("Search", "mv-search-run", self._run_search)
        self.search_task = Task()
        self.search_count = pn.pane.Markdown("", css_classes=["mv-search-count"], margin=(0, 10))
        self.search_table = results_table(pd.DataFrame(columns=list(SEARCH_TITLES)), "mv-search-table",
                                          SEARCH_TITLES, page_size=10, selectable=True)  # fmt: skip
        self.search_table.param.watch(self._on_search_select, "selection")
        self.search_download = table_download(self.backend, self.search_table, lambda: self._found_by("search"),
                                              "mv-search-download")  # fmt: skip
        self.search_gallery = HitGallery(self.backend, self.search_table, "mv-search-gallery", self.selection)
        self.results = None
        self.search_playing = pn.pane.Markdown(SEARCH_PLAY_HINT, margin=(0, 10), css_classes=["mv-search-playing"])
        self.search_player = SkeletonPlayer(size=(760, 380))
        self.search_player_box = pn.Column(self.search_player, visible=False, css_classes=["mv-search-player"])

    def _build_knn(self) -> None:
        most = min(MAX_NEIGHBOURS, self.backend.db.n_frames)
        self.knn_k = parameter_box("k neighbours", "k", "neighbours", most=most, value=min(default("neighbours", "k"), most),
                                   width=150, css_classes=["mv-knn-k"])
        self.knn_per_document = pn.widgets.Checkbox(label="one row per document", value=False, width=180,
                                                    align="end", css_classes=["mv-knn-per-document"])
        self.knn_button = action_button("Search", "mv-knn-search", self._search)
        self.knn_task = Task()
        self.knn_count = pn.pane.Markdown("", css_classes=["mv-knn-count"], margin=(0, 10))
        self.knn_table = results_table(pd.DataFrame(columns=list(KNN_TITLES)), "mv-knn-table", KNN_TITLES)
        self.knn_poses = pn.pane.PNG(None, width=480, height=420, css_classes=["mv-knn-poses"])
        self.knn_legend = pn.pane.HTML(legend(SIDES, SIDE_NAMES, "query's bones") + " · neighbours: "
                                       f'<span style="color: {OTHERS}">■</span> grey', margin=(0, 10),
                                       styles={"font-size": "0.85em"}, css_classes=["mv-knn-legend"])

    def _build_match(self) -> None:
        n = self.backend.db.n_frames
        self.match_k = parameter_box("k neighbours per frame", "k", "match", most=n, value=graph_k(n, self.backend.fps),
                                     width=220, css_classes=["mv-match-k"])
        self.match_count_k = parameter_box("K matches", "n_matches", "match", most=MAX_MATCHES, width=130,
                                           css_classes=["mv-match-kk"])
        self.match_button = action_button("Match", "mv-match-run", self._match)
        self.match_task = Task()
        self.match_count = pn.pane.Markdown("", css_classes=["mv-match-count"], margin=(0, 10))
        self.match_table = results_table(pd.DataFrame(columns=list(MATCH_TITLES)), "mv-match-table", MATCH_TITLES,
                                         page_size=10, selectable=True)
        self.match_table.param.watch(self._on_match_select, "selection")
        self.match_download = table_download(self.backend, self.match_table, lambda: self._found_by("match"),
                                             "mv-match-download")  # fmt: skip
        self.match_gallery = HitGallery(self.backend, self.match_table, "mv-match-gallery", self.selection)
        self.matches = self.match_key = None  # the matches shown in the table and the matching that found them
        self.playing = pn.pane.Markdown(MATCH_PLAY_HINT, margin=(0, 10), css_classes=["mv-match-playing"])
        self.player = SkeletonPlayer(size=(760, 380))
        self.player_box = pn.Column(self.player, visible=False, css_classes=["mv-match-player"])

    def _build_matrix(self) -> None:
        n = self.backend.db.n_frames
        self.matrix_k = BoundedIntInput("k neighbours per frame, small database", min(scaled_k(
            MATRIX_K_AT_30HZ, self.backend.fps), n), 1, n, width=300, css_classes=["mv-matrix-k"])
        self.matrix_button = action_button("Similarity matrix", "mv-matrix-run", self._matrix, width=160)
        self.matrix_task = Task()
        self.matrix = pn.pane.HoloViews(None, sizing_mode="stretch_width", css_classes=["mv-similarity-matrix"])

    def __panel__(self):
        search = pn.Column("### Search: the clips or stretches that move most like the span (DTW)",
                           pn.pane.Markdown(SEARCH_LEGEND, margin=(0, 10)),
                           pn.Row(self.search_kind, self.search_mode, self.search_k, self.search_button),
                           notes(self.search_k), _scoped(self.search_task, "mv-search-task"), self.search_count,
                           self.search_gallery, self.search_download.panel(),
                           self.search_playing, self.search_player_box, sizing_mode="stretch_width")
        knn = pn.Column("### Nearest neighbours of the frame (Krüger et al. 2010 §3.3, Fig. 1)",
                        pn.Row(self.knn_k, self.knn_per_document, self.knn_button), notes(self.knn_k),
                        _scoped(self.knn_task, "mv-knn-task"),
                        pn.Row(pn.Column(self.knn_count, self.knn_table, sizing_mode="stretch_width"),
                               pn.Column(self.knn_poses, self.knn_legend), sizing_mode="stretch_width"),
                        sizing_mode="stretch_width")
        match = pn.Column("### Motion matching of the span (lazy neighbourhood graph, §4.1)",
                          pn.Row(self.match_k, self.match_count_k, self.match_button),
                          notes(self.match_k, self.match_count_k), _scoped(self.match_task, "mv-match-task"),
                          self.match_count, self.match_gallery, self.match_download.panel(),
                          self.playing, self.player_box, sizing_mode="stretch_width")
        matrix = pn.Column("### Similarity matrix of the span against the best matches' documents (Fig. 3)",
                           pn.pane.Markdown(MATRIX_LEGEND, margin=(0, 10)), pn.Row(self.matrix_k, self.matrix_button),
                           notes(self.matrix_k), _scoped(self.matrix_task, "mv-matrix-task"), self.matrix,
                           sizing_mode="stretch_width")
        return pn.Column(pn.Row(self.clip, self.upload), pn.Row(self.numeric_set, self.exclude_own), self.query,
                         search, knn, match, matrix,
                         sizing_mode="stretch_width")

    def activate(self) -> None:
        """Show the Database page's current example (called when the tab is shown and when the example changes)."""
        query, (start, end), frame = self.selection.query()
        fps = query_fps(self.backend, query)
        self.clip.value = UPLOADED if isinstance(query, Upload) else query
        self.query.object = (f"**Query**: {query_name(self.backend, query, named=True)}, frame {frame} ({frame / fps:.2f} s); "
                             f"span {_frames(start, end)} ({plural(end - start, 'frame')}, "
                             f"{start / fps:.2f}–{end / fps:.2f} s). "
                             "Choose the frame and span on the Database page (a document's) or the Relational query "
                             "page.")

    def _on_clip(self, event) -> None:
        """A query clip chosen in the picker: the uploaded take, or a document, all of it."""
        s = self.selection
        if event.new == UPLOADED:
            s.use_upload = True
        elif s.query()[0] != event.new:
            n = int(self.backend.db.document(int(event.new))["n_frames"])
            s.param.update(doc=int(event.new), frame=0, span=(0, n), use_upload=False)

    async def first_answer(self) -> None:
        """The page's answer when it is first shown: the DTW search of the session's span with the page's defaults
        (the other sections wait for their buttons)."""
        await self._run_search()

    def _found_by(self, which: str) -> str:
        """The search of the hits shown in a table ("search" or "match"), in words (written into exported files)."""
        doc, (start, end) = getattr(self, f"{which}_query", None) or (None, (0, 0))
        how = ("similarity search (DTW)" if which == "search" else "motion matching (lazy neighbourhood graph)")
        what = "nothing" if doc is None else query_name(self.backend, doc)
        return f"{how} on {self.numeric_set.value}: {what} frames {start}:{end}"

    # ------------------------------------------------------------------ DTW search
    def _search_key(self) -> tuple:
        """(numeric set, document, span, kind, mode, K, exclude own) of the search the widgets ask for."""
        query, span, _ = self.selection.query()
        return (self.numeric_set.value, query, span, SEARCH_KINDS[self.search_kind.value],
                self.search_mode.value, self.search_k.value, self.exclude_own.value)

    async def _run_search(self, event=None) -> None:
        key = self._search_key()
        found = await self.search_task.run("Searching", self.backend.cached, ("similarity.search", *_keyed(key)),
                                           lambda: search_span(self.backend, *key), busy=self.search_button,
                                           stale=(self.search_count, self.search_table, self.search_player_box,
                                                  self.search_playing))
        if found is None:
            self.results = None
            return
        name, doc, span, kind, mode, n_matches, own = key
        self.results, self.search_query = found, (doc, span)
        self.search_gallery.show_hits(hit_columns(found, SEARCH_TITLES, SEARCH_DECIMALS))
        self.search_player_box.visible, self.search_playing.object = False, SEARCH_PLAY_HINT
        what = ("clip", "clips") if kind == "clips" else ("stretch", "stretches")
        ms = found.attrs.get("ms")
        self.search_count.object = (f"**{plural(len(found), *what)}** like {query_name(self.backend, doc)} frames {_frames(*span)} by {name}, "
                                    f"{mode} DTW (K = {n_matches})" + (", its own document excluded" if own and not isinstance(doc, Upload) else "")
                                    + (f"; search {ms:.0f} ms, {plural(found.attrs.get('aligned', 0), 'alignment')}"
                                       if ms is not None else ""))  # fmt: skip

    def _on_search_select(self, event) -> None:
        if not event.new or self.results is None:
            return
        row = self.results.iloc[event.new[0]]
        doc, span = self.search_query
        self._play(self.search_player, self.search_player_box, doc, span, row, f"result {row['rank']}")
        self.search_playing.object = (f"Playing the query ({query_name(self.backend, doc)}, frames {_frames(*span)}) beside result "
                                      f"{row['rank']} (document {row['doc_id']}, {row['name']}, frames "
                                      f"{_frames(row['start'], row['end'])}), aligned by its DTW warping path "
                                      f"({plural(len(row['path']), 'step')}).")

    def _play(self, player, box, doc: int, span: tuple[int, int], hit, title: str) -> None:
        """Load the query span (frames start:end of ``doc``) beside the hit ``hit`` (a row of a hit table, with its
        ``path``) into ``player``, played along the hit's warping path."""
        hit_doc = int(hit["doc_id"])
        clips = [query_clip(self.backend, doc, *span), query_clip(self.backend, hit_doc, int(hit["start"]), int(hit["end"]))]
        player.load(clips, titles=[f"query: {query_name(self.backend, doc)}", f"{title}: document {hit_doc}"],
                    fps=query_fps(self.backend, doc), alignment=match_alignment(hit["path"], int(hit["start"])))
        box.visible = True

    # ------------------------------------------------------------------ kNN
    async def _search(self, event=None) -> None:
        """The neighbours table as soon as the kNN is done; the Fig. 1 picture (slower to render) after it."""
        doc, _, frame = self.selection.query()
        name, k, own = self.numeric_set.value, self.knn_k.value, self.exclude_own.value
        each = self.knn_per_document.value
        key = ("similarity.knn", name, cache_key(doc), frame, k, own, each)
        shown = (self.knn_count, self.knn_table, self.knn_poses)
        table = await self.knn_task.run("Searching", self.backend.cached, key,
                                        lambda: nearest_frames(self.backend, name, doc, frame, k, own, each),
                                        busy=self.knn_button, stale=shown)
        if table is None:
            return
        self.knn_table.value = hit_columns(table, KNN_TITLES, KNN_DECIMALS)
        found = table.attrs.get("neighbours", len(table))
        self.knn_count.object = (f"**{plural(found, 'neighbour')}** of {query_name(self.backend, doc)} frame {frame} "
                                 f"by {name}"
                                 + (", its own document excluded" if own and not isinstance(doc, Upload) else "")
                                 + (f"; one row per document: the nearest in each of {len(table)}" if each else ""))
        image = await self.knn_task.run("Drawing the neighbours", self.backend.cached, (*key, "png"),
                                        lambda: neighbours_png(self.backend, doc, frame, table),
                                        busy=self.knn_button, stale=(self.knn_poses,))
        if image is not None:
            self.knn_poses.object = image

    # ------------------------------------------------------------------ LNG
    def _match_key(self) -> tuple:
        """(numeric set, document, span, k, K, exclude own) of the matching the widgets ask for: the span's first
        :data:`LNG_MAX_SECONDS` (:func:`graph_span`)."""
        query, span, _ = self.selection.query()
        return (self.numeric_set.value, query, graph_span(span, query_fps(self.backend, query)), self.match_k.value,
                self.match_count_k.value, self.exclude_own.value)

    def _cached_matches(self, key: tuple) -> pd.DataFrame:
        """The matches of ``key`` (see :meth:`_match_key`), computed once per database."""
        return self.backend.cached(("similarity.lng", *_keyed(key)), lambda: match_span(self.backend, *key))

    async def _match(self, event=None) -> None:
        key, asked = self._match_key(), self.selection.query()[1]
        found = await self.match_task.run("Matching", self._cached_matches, key, busy=self.match_button,
                                          stale=(self.match_count, self.match_table, self.player_box, self.playing,
                                                 self.matrix))
        self.matrix_task.forget()  # the matrix was of the matches this run replaces
        if found is None:
            self.matches = self.match_key = None
            return
        name, doc, span, k, n_matches, own = key
        self.matches, self.match_query, self.match_key = found, (doc, span), key
        self.match_gallery.show_hits(hit_columns(found, MATCH_TITLES, MATCH_DECIMALS))
        self.player_box.visible, self.playing.object, self.matrix.object = False, MATCH_PLAY_HINT, None
        share = found.attrs["min_length"]
        cut = asked != span
        self.match_count.object = (f"**{plural(len(found), 'match', 'matches')}** of {query_name(self.backend, doc)} frames {_frames(*span)} by {name} "
                                   + (f"(the span's first {LNG_MAX_SECONDS:g} s: the graph looks up the k nearest "
                                      "frames of every query frame) " if cut else "")
                                   + f"(k = {k}, K = {n_matches}), each at least {share:g} × the span long "
                                   f"({plural(shortest_match(share, span[1] - span[0]), 'frame')})"
                                   + (", its own document excluded" if own and not isinstance(doc, Upload) else "")
                                   + ("; try a larger k" if found.empty else ""))

    def _on_match_select(self, event) -> None:
        if not event.new or self.matches is None:
            return
        match = self.matches.iloc[event.new[0]]
        doc, span = self.match_query
        self._play(self.player, self.player_box, doc, span, match, f"match {match['rank']}")
        self.playing.object = (f"Playing the query ({query_name(self.backend, doc)}, frames {_frames(*span)}) beside match "
                               f"{match['rank']} (document {match['doc_id']}, {match['name']}, frames "
                               f"{_frames(match['start'], match['end'])}), aligned by its warping path "
                               f"({plural(len(match['path']), 'step')}).")

    # ------------------------------------------------------------------ Fig. 3
    def _similarity(self, key: tuple, k: int):
        """Fig. 3's layout for the matching ``key``: its best matches' documents form the small database, searched
        with ``k`` neighbours per query frame."""
        name, doc, span = key[:3]
        docs = matrix_docs(self._cached_matches(key))
        result = self.backend.cached(("similarity.matrix", name, cache_key(doc), span, k, tuple(docs)),
                                     lambda: similarity_result(self.backend, name, doc, span, k, docs))
        return similarity_layout(result, cols=2, width=560, height=360)

    async def _matrix(self, event=None) -> None:
        key = self.match_key or self._match_key()  # the matches in the table (before a run: the widgets' matching)
        layout = await self.matrix_task.run("Computing the similarity matrix", self._similarity, key,
                                            self.matrix_k.value, busy=self.matrix_button, stale=(self.matrix,))
        if layout is not None:
            self.matrix.object = layout


SEARCH_PLAY_HINT = "Click a result to play it beside the query, aligned by its DTW warping path."
MATCH_PLAY_HINT = "Click a match to play it beside the query, aligned by its warping path."
SEARCH_LEGEND = ("Whole clips: every document aligned with the whole span by DTW, ranked by cost / (span frames + "
                 "document frames). Stretches: the K best non-overlapping stretches of the documents by subsequence "
                 "DTW (raw cost), each at least half the span long. Exact: exactly the brute-force ranking, with "
                 "admissible pruning; fast: exact DTW on candidates only (whole clips: those of least DTW cost on 0.2 s "
                 "block means; stretches: around the span frames' nearest neighbours and the best coarse matches), "
                 "measured recall on the Retrieval quality tab.")
MATRIX_LEGEND = ("The span against the documents of its best matches (at most three, the small database). Grey: "
                 "distances the graph computed (darker = more similar); blue: cells it never computed; red: its "
                 "warping paths; orange: document boundaries. Second panel: subsequence DTW on the point-cloud "
                 "distance Dpc1, computed in full.")


def _keyed(key: tuple) -> tuple:
    """A page's key of a computation as the Backend keeps its answer: an uploaded take by its checksum
    (:func:`~mocapviz.app.upload.cache_key`)."""
    return tuple(cache_key(part) if isinstance(part, Upload) else part for part in key)


def _document_only(query, what: str) -> None:
    """Refuse ``what`` for an uploaded take: it compares the query frame or span with database documents only."""
    if isinstance(query, Upload):
        raise ParameterError(f"{what} takes a document of the database as the query; choose one in the query clip "
                             f"picker ({query.name} is the uploaded take)")


def _frames(start: int, end: int) -> str:
    """A half-open span of frames as the page writes it: "start:end" (end excluded, as in the tables)."""
    return f"{int(start)}:{int(end)}"


def _scoped(task: Task, css_class: str) -> pn.Column:
    """A Task's status line in a column of its own css class, so the page's tasks can be told apart."""
    return pn.Column(task, css_classes=[css_class], sizing_mode="stretch_width", margin=0)
