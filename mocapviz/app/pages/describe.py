"""Describe page: find what a user can only describe (Müller, Röder & Clausen 2005 §6.3, Fig. 10; the language of
docs/descriptions.md, :mod:`mocapviz.relational.description`).

The user writes a scene description in an editor ("lknee: straight bent straight and lfoot: lowered raised lowered
and overlap lknee bent, lfoot raised"), with the words at hand: the shipped named descriptions (their text; a click
adds the name) and the feature vocabulary of the relational set (each part and its two state words; a click adds a
progression of that feature). The text is read as the user types (debounced): a parse error is shown as one line
naming its line and column (:func:`mocapviz.relational.description.parse_description`). "Find" runs
:func:`mocapviz.relational.scene.find` over the Backend's relational indexes of the set (loaded once per set; the
result cached per text, set and K) and lists the hits in the one hit table, with their score (seconds) and the frames
where each part matched; an empty result says which part found nothing. A chosen hit plays in the player, and its
feature-bar timeline shows the description's features over the hit and a margin, the hit shaded and the frames each
progression matched outlined. "Describe this template" fills the editor with the description of a template stored
with the database (:func:`mocapviz.relational.scene.describe`).

The page only calls the library and formats: it evaluates nothing itself.
"""

from __future__ import annotations

import asyncio
import html
import re
from collections import Counter

import holoviews as hv
import pandas as pd
import panel as pn

from ...engine import (
    DELTA,
    Description,
    Event,
    Named,
    Progression,
    database_frames,
    declared_set,
    named_descriptions,
    parse_description,
    template_names,
    vocabulary_of,
    vocabulary_table,
    walk,
)
from ...engine.parameters import default
from ...errors import DescriptionError, MocapvizError
from ...validation import count, one_of, plural
from ...viz.timeline import relational_timeline
from ..downloads import table_download
from ..gallery import HitGallery
from ..player import SkeletonPlayer
from ..progress import Task, in_thread
from ..upload import UploadBox, example, query_name
from ..widgets import MAX_MATCHES, action_button, hit_columns, hit_titles, notes, parameter_box, results_table

RELATIONAL_SETS = ["2005", "2006"]
DEFAULT_MATCHES = default("find", "n_matches")
DEBOUNCE_S = 0.3  # the text is read this long after the last keystroke
MARGIN_S = 0.5  # seconds of the document shown before and after a hit in its timeline
TIMELINE_WIDTH = 760
HIT_TITLES = hit_titles("rank", "doc_id", "name", "label", "start", "end", "start_s", "end_s", "score", "parts")
HIT_DECIMALS = {"start_s": 2, "end_s": 2, "score": 3}
EXAMPLE = """# a left kick (Müller et al. 2005, Fig. 10): edit it, or click a name or a part on the right
lknee: straight bent straight
    and lfoot: lowered raised lowered
    and overlap lknee bent, lfoot raised"""
EMPTY_HINT = "Write a description, e.g. kick_right then punch_left within 2 s."
PLAY_HINT = "Click a hit to play it and to see its features over time."


# ============================================================================ helpers (pure, or over the Backend)
def one_line(text: str) -> str:
    """``text`` on one line (newlines and runs of spaces become one space)."""
    return " ".join(str(text).split())


def parse_status(text: str, relational_set: str = "2005", db=None) -> tuple[bool | None, str]:
    """How the editor's text reads, in one line: (True, what it names) when it parses, (False, the error: "line L,
    column C: reason", as :class:`~mocapviz.errors.DescriptionError` says it) when not, (None, a hint) when empty.
    With ``db``, a text that names a template not stored with it (``template:NAME``) is refused too, naming it:
    Find would fail on it.

    Examples
    --------
    >>> parse_status("rknee: straight bnt straight")  # doctest: +ELLIPSIS
    (False, "line 1, column ...: 'bnt' is not a state of rknee in the 2005 set; did you mean 'bent'?")
    >>> parse_status("rknee: straight bent straight and rfoot: lowered raised lowered")
    (True, 'Reads well in the 2005 set: features rknee_bent, rfoot_raised.')
    >>> from mocapviz import MotionDB
    >>> parse_status("template:nosuch then kick_left", db=MotionDB.sample())
    (False, 'template nosuch is not stored with this database (the stored ones: "stored template" below)')
    """
    if not str(text).strip():
        return None, EMPTY_HINT
    try:
        parsed = parse_description(text, relational_set)
    except MocapvizError as exc:  # DescriptionError: its message starts with the line and column
        return False, one_line(exc)
    features, templates = description_features(parsed), parsed.templates()
    missing = [name for name, stamp in template_stamps(db, text) if stamp is None] if db is not None else []
    if missing:
        return False, (f"{plural(len(missing), 'template', number=False)} {', '.join(missing)} "
                       f"{'is' if len(missing) == 1 else 'are'} not stored with this database (the stored ones: "
                       '"stored template" below)')
    said = [f"features {', '.join(features)}" if features else "",
            f"{plural(len(templates), 'template', number=False)} {', '.join(templates)}" if templates else ""]
    return True, f"Reads well in the {parsed.relational_set} set: " + "; ".join(s for s in said if s) + "."


def reading_set(text: str, chosen: str) -> str:
    """The relational set a text is read with: the one its ``set 2006;`` statement names, else ``chosen`` (also when
    the text cannot be read: its error is shown by :func:`parse_status`).

    Examples
    --------
    >>> reading_set("set 2006; rknee: straight bent straight", "2005"), reading_set("kick_left", "2006")
    ('2006', '2006')
    """
    try:
        return declared_set(text) or chosen
    except MocapvizError:
        return chosen


def description_features(node) -> list[str]:
    """The relational features a description (or one node of its tree) names, in the order written, each once;
    template atoms name none. Linear in the tree however often its names are used (:func:`walk`)."""
    found: list[str] = []
    for n in walk(node.root if isinstance(node, Description) else node):
        if isinstance(n, Event):
            found.extend(p.feature for p in n.progressions)
        elif isinstance(n, Progression):
            found.append(n.feature)
    return list(dict.fromkeys(found))


def _named_bodies(node) -> dict:
    """Name -> tree of every named description used in ``node`` (each visited once: :func:`walk`)."""
    out: dict = {}
    for n in walk(node.root if isinstance(node, Description) else node):
        if isinstance(n, Named):
            out.setdefault(n.name, n.body)
    return out


_PART = re.compile(r"(?P<label>\S+) (?P<start>\d+):(?P<end>\d+)")


def part_spans(parts: str) -> list[tuple[str, int, int]]:
    """The hit table's ``parts`` text (``"kick_left/lknee 36:66, kick_left/lfoot 52:98"``) as (label, start, end)
    tuples, frames of the document, half-open.

    Examples
    --------
    >>> part_spans("kick_left/lknee 36:66, template:squat1Reps-bd-dg 52:98")
    [('kick_left/lknee', 36, 66), ('template:squat1Reps-bd-dg', 52, 98)]
    """
    spans = []
    for item in str(parts).split(", "):
        found = _PART.fullmatch(item.strip())
        if found:
            spans.append((found["label"], int(found["start"]), int(found["end"])))
    return spans


def matched_features(description: Description, parts: str) -> list[tuple[str | None, int, int]]:
    """Each part of a hit (its ``parts`` text) as (feature, start, end): the feature of the description's progression
    that part names (None for a template atom); a part written twice in one named description (``wave``'s two
    ``rhand`` progressions) takes that description's features of the part in turn."""
    words = vocabulary_of(description.relational_set)
    bodies = _named_bodies(description)
    everywhere = description_features(description)
    seen: Counter = Counter()
    out = []
    for label, start, end in part_spans(parts):
        if label.startswith("template:"):
            out.append((None, start, end))
            continue
        name, _, part = label.rpartition("/")
        scope = description_features(bodies[name]) if name in bodies else everywhere
        candidates = [f for f in scope if part in (words.part(f), f)] or \
            [f for f in everywhere if part in (words.part(f), f)]  # fmt: skip
        if not candidates:
            out.append((None, start, end))
            continue
        out.append((candidates[seen[label] % len(candidates)], start, end))
        seen[label] += 1
    return out


def hit_window(start: int, end: int, n_frames: int, fps: float, margin_s: float = MARGIN_S) -> tuple[int, int]:
    """The frames shown around a hit start:end (half-open): ``margin_s`` seconds either side, within the document.

    Examples
    --------
    >>> hit_window(30, 90, 100, 120.0)
    (0, 100)
    >>> hit_window(300, 360, 1000, 120.0)
    (240, 420)
    """
    margin = round(margin_s * fps)
    return max(0, int(start) - margin), min(int(n_frames), int(end) + margin)


def insert_name(text: str, name: str) -> str:
    """``text`` with ``name`` added at its end (after a space when the text does not end in white space).

    Examples
    --------
    >>> insert_name("kick_right then ", "punch_left")
    'kick_right then punch_left'
    >>> insert_name("", "jump")
    'jump'
    """
    text = str(text or "")
    return f"{text}{name}" if not text or text[-1].isspace() else f"{text} {name}"


def insert_progression(text: str, part: str, zero: str, one: str) -> str:
    """``text`` with a progression ``part: zero one zero`` added: alone in an empty editor, else joined by ``and`` on
    a new line.

    Examples
    --------
    >>> insert_progression("", "rknee", "straight", "bent")
    'rknee: straight bent straight'
    >>> insert_progression("rfoot: lowered raised lowered", "rknee", "straight", "bent")
    'rfoot: lowered raised lowered\\n    and rknee: straight bent straight'
    """
    progression = f"{part}: {zero} {one} {zero}"
    text = str(text or "").rstrip()
    return progression if not text else f"{text}\n    and {progression}"


def names_view(relational_set: str) -> pd.DataFrame:
    """The shipped named descriptions of a set as shown: name and text (on one line), or why a name cannot be used
    with the set."""
    rows = []
    for name, tree in named_descriptions(relational_set).items():
        text = f"(not in the {relational_set} set: {tree.reason})" if isinstance(tree, DescriptionError) else str(tree)
        rows.append({"name": name, "description": one_line(text)})
    return pd.DataFrame(rows, columns=["name", "description"])


def vocabulary_view(relational_set: str) -> pd.DataFrame:
    """The feature vocabulary of a set as shown: part, its two state words, feature, group."""
    return vocabulary_table(relational_set)[["part", "state_0", "state_1", "feature", "group"]]


def template_stamps(db, text: str) -> tuple:
    """(name, modification time) of each template the text names, for the result cache: a template stored again
    gives a new key. Only the database's stored templates are looked at (``DB/templates/NAME.npz``); a name that is
    not a stored template's (a path a user typed) is never opened or probed: None, and find says it is unknown.
    Reading the text's syntax may raise its DescriptionError."""
    from ...engine import is_template_name, template_path

    stamps = []
    for name in template_names(text):
        path = template_path(db, name) if is_template_name(name) else None
        stamps.append((name, path.stat().st_mtime_ns if path is not None and path.is_file() else None))
    return tuple(stamps)


def search(backend, text: str, relational_set: str, n_matches: int) -> pd.DataFrame:
    """The hits of a description: :func:`mocapviz.relational.scene.find` over the Backend's relational indexes of
    ``relational_set`` (and its relational values when the text names templates), cached per (text, set, K,
    templates).

    Parameters
    ----------
    backend : Backend
    text : str, the description.
    relational_set : {"2005", "2006"}
    n_matches : int, K, 1..MAX_MATCHES.

    Returns
    -------
    pandas.DataFrame, the hit table of ``find`` (its ``attrs`` too: ``empty_reason``, ``counts``, ...).
    """

    relational_set = one_of(str(relational_set), "relational set", RELATIONAL_SETS)
    n_matches = count(n_matches, "K", 1, MAX_MATCHES)
    stamps = template_stamps(backend.db, text)
    key = ("describe.find", relational_set, str(text), n_matches, stamps)

    return backend.cached(key, lambda: backend.engine.find(text, n_matches=n_matches, relational_set=relational_set))


def describe_query(backend, query, span, relational_set: str) -> str:
    """The description of a query clip (a document id or an uploaded take, frames ``span`` half-open) in the words
    of ``relational_set``: :func:`mocapviz.relational.scene.describe_clip` of its relational features, what
    "Describe this clip" writes."""
    from ...engine import describe_clip

    relational_set = one_of(str(relational_set), "relational set", RELATIONAL_SETS)
    values, names = backend.engine.clip_relational(example(query), frames=tuple(span), relational_set=relational_set)
    return describe_clip(values, names, label=query_name(backend, query, named=True), delta=DELTA)


def describe_template(backend, name: str, delta: float = DELTA) -> tuple[str, str]:
    """(description text, relational set) of the template stored as ``name`` with the Backend's database
    (:func:`mocapviz.relational.scene.describe`)."""
    from ...engine import describe

    template = backend.engine.template(str(name))
    return describe(template, delta=delta), str(template.meta.get("relational_set") or "2005")


def stored_template_names(backend) -> list[str]:
    """The names of the templates stored with the database (none when they cannot be listed)."""
    from ...engine import stored_templates

    try:
        return list(stored_templates(backend.db)["name"])
    except MocapvizError:
        return []


def hit_timeline(backend, description: Description, hit) -> hv.Overlay | None:
    """The feature bars of the description's features over a hit and :data:`MARGIN_S` either side (the document's
    relational values of the description's set), the hit shaded, the frames each progression matched outlined
    (None when the description names no feature: templates only).

    Parameters
    ----------
    backend : Backend
    description : Description, the one the hit was found for.
    hit : a row of the hit table (doc_id, start, end, parts).
    """
    features = description_features(description)
    if not features:
        return None
    relational_set = description.relational_set
    words = vocabulary_of(relational_set)
    doc, start, end = int(hit["doc_id"]), int(hit["start"]), int(hit["end"])
    fps = backend.fps_of(doc)
    a, b = hit_window(start, end, int(backend.db.document(doc)["n_frames"]), fps)
    values, names = backend.clip_relational(doc, relational_set)
    rows = [f"{words.part(f)} {words.states(f)[1]}" for f in features]
    groups: dict = {}
    for f, row in zip(features, rows):
        groups.setdefault(words.group[f], []).append(row)
    plot = relational_timeline(values[a:b][:, [names.index(f) for f in features]], rows, fps, groups=groups,
                               span=(start - a, end - 1 - a), width=TIMELINE_WIDTH, row_height=26, segments=False)
    boxes, spans = [], []
    for feature, s, e in matched_features(description, hit["parts"]):
        if feature is None:
            spans.append(hv.VSpan((s - a) / fps, (e - a) / fps).opts(color="#888888", alpha=0.15))
            continue
        y = len(features) - 1 - features.index(feature)
        boxes.append(((s - a) / fps, y - 0.48, (e - a) / fps, y + 0.48, feature, s, e))
    outlines = hv.Rectangles(boxes, kdims=["x0", "y0", "x1", "y1"], vdims=["part", "first_frame", "end_frame"])
    outlines = outlines.opts(fill_alpha=0, line_color="black", line_width=2, tools=["hover"])
    title = f"document {doc}, frames {a}:{b} (time from frame {a}) · shaded: the hit · outlined: each part's match"
    return hv.Overlay([plot, outlines, *spans]).opts(title=title)


# ============================================================================ the page
class DescribePage(pn.viewable.Viewer):
    """Write a scene description, see it read as you type, find its hits, play one and see its features."""

    def __init__(self, backend, selection):
        super().__init__()
        self.backend, self.selection = backend, selection
        self.hits, self.description = pd.DataFrame(), None
        self.answered = False  # first_answer has started (it loads the indexes itself)
        self._typed = 0  # keystrokes so far (the debounce keeps the last one's check only)
        self.relational_set = pn.widgets.RadioButtonGroup(options=RELATIONAL_SETS, value="2005", width=120,
                                                          css_classes=["mv-describe-set"])
        self.editor = pn.widgets.TextAreaInput(value=EXAMPLE, value_input=EXAMPLE, height=190, width=640,
                                               placeholder="kick_right then punch_left within 2 s",
                                               css_classes=["mv-describe-editor"])  # fmt: skip
        self.status = pn.pane.HTML("", margin=(0, 10), width=640, css_classes=["mv-describe-parse"])
        self.n_matches = parameter_box("K (results)", "n_matches", "find", most=MAX_MATCHES, width=140,
                                       css_classes=["mv-describe-k"])
        self.find = action_button("Find", "mv-describe-find", self._on_find, width=120)
        self.templates = pn.widgets.Select(name="stored template", options=[], width=300,
                                           css_classes=["mv-describe-template"])
        self.describe = action_button("Describe this template", "mv-describe-template-run", self._on_describe,
                                      width=200)
        self.templates_note = pn.pane.Markdown("", margin=(0, 10), width=640, css_classes=["mv-describe-template-note"])
        self.describe_clip = action_button("Describe this clip", "mv-describe-clip-run", self._on_describe_clip,
                                           width=180)
        self.clip_note = pn.pane.Markdown("", margin=(0, 10), width=460, css_classes=["mv-describe-clip-note"])
        self.upload = UploadBox(backend, selection, "mv-describe-upload")
        selection.param.watch(lambda *events: self._show_clip(), ["doc", "span", "upload", "use_upload", "upload_span"])
        self._show_clip()
        self.task = Task()
        self.names = results_table(names_view("2005"), "mv-describe-names", {"name": "name",
                                   "description": "description (click: add the name)"}, page_size=16,
                                   tooltips=True, layout="fit_columns", widths={"name": 110})  # fmt: skip
        self.words = results_table(vocabulary_view("2005"), "mv-describe-vocabulary",
                                   {"part": "part", "state_0": "state 0", "state_1": "state 1", "feature": "feature",
                                    "group": "group"}, page_size=16)  # fmt: skip
        self.count = pn.pane.HTML("", margin=(0, 10), css_classes=["mv-describe-count"])
        self.table = results_table(pd.DataFrame(columns=list(HIT_TITLES)), "mv-describe-hits", HIT_TITLES,
                                   selectable=True, tooltips=True)
        self.timeline = pn.pane.HoloViews(None, css_classes=["mv-describe-timeline"])
        self.caption = pn.pane.HTML(PLAY_HINT, margin=(0, 10), width=520, css_classes=["mv-describe-caption"])
        self.player = SkeletonPlayer(size=(520, 360))
        self.player_box = pn.Column(self.player, visible=False, css_classes=["mv-describe-player"])
        self.editor.param.watch(self._on_typed, "value_input")
        self.editor.param.watch(lambda e: self._check(e.new), "value")
        self.relational_set.param.watch(self._on_set, "value")
        self.names.on_click(self._on_name)
        self.words.on_click(self._on_word)
        self.table.param.watch(self._on_select, "selection")
        self.download = table_download(backend, self.table, lambda: f"scene description: {self.description}",
                                       "mv-describe-download")  # fmt: skip
        self.gallery = HitGallery(backend, self.table, "mv-describe-gallery")
        self._refresh_templates()
        self._check()

    def __panel__(self):
        editor = pn.Column(
            "### Description", pn.Row(pn.pane.Markdown("relational set", margin=(8, 10)), self.relational_set),
            self.editor, self.status, pn.Row(self.n_matches, self.find), notes(self.n_matches),
            pn.Row(self.templates, self.describe), self.templates_note, pn.Row(self.describe_clip, self.clip_note),
            self.upload, self.task, width=660)
        words = pn.Tabs(("Named descriptions", self.names), ("Parts and states", self.words), dynamic=False,
                        sizing_mode="stretch_width", css_classes=["mv-describe-words"])
        results = pn.Column("### Hits", self.count, self.gallery, self.download.panel(), sizing_mode="stretch_width")
        shown = pn.Row(self.timeline, pn.Column(self.caption, self.player_box))
        return pn.Column(pn.Row(editor, pn.Column("### Words", words, sizing_mode="stretch_width"),
                                sizing_mode="stretch_width"), results, shown, sizing_mode="stretch_width")

    def activate(self) -> None:
        """When the tab is shown: list the stored templates again (some may have been stored since) and load the
        relational indexes of the set in the background (Find waits for them)."""
        self._refresh_templates()
        if self.answered and not self.backend.engine.holds("indexes", self.relational_set.value):
            pn.state.execute(self._load_indexes)

    async def first_answer(self) -> None:
        """The page's answer when it is first shown: the indexes loaded, then the example description
        (:data:`EXAMPLE`, the editor's text) found with the page's K."""
        self.answered = True
        if not self.backend.engine.holds("indexes", self.relational_set.value):
            await self._load_indexes()
        await self._on_find()

    async def _load_indexes(self) -> None:
        await self.task.run("Loading the relational indexes", self.backend.engine.indexes, self.relational_set.value,
                            busy=self.find)

    # ------------------------------------------------------------------ the editor
    async def _on_typed(self, event) -> None:
        """Read the text :data:`DEBOUNCE_S` after the last keystroke."""
        self._typed += 1
        mine = self._typed
        await asyncio.sleep(DEBOUNCE_S)
        if mine == self._typed:
            self._check(event.new)

    def _check(self, text: str | None = None) -> None:
        """Show how the text reads. A text that names its set (``set 2006;``) moves the set buttons to it (whose
        change reads it again); a set chosen by the buttons against the text's is reported by the library."""
        text = self._text() if text is None else text
        if (wanted := reading_set(text, self.relational_set.value)) != self.relational_set.value:
            self.relational_set.value = wanted  # -> _on_set -> _check()
            return
        self._show_status(text)

    def _show_status(self, text: str) -> None:
        ok, message = parse_status(text, self.relational_set.value, self.backend.db)
        colour = {True: "#1b5e20", False: "#b00020", None: "#555555"}[ok]
        shown = html.escape(message if ok is not False else f"⚠ {message}")
        self.status.object = f'<span style="color: {colour}">{shown}</span>'

    def _text(self) -> str:
        """The editor's text as typed so far (``value`` follows only when the editor loses focus)."""
        return str(self.editor.value_input or "")

    def _set_text(self, text: str) -> None:
        self.editor.param.update(value=text, value_input=text)

    def _on_set(self, event) -> None:
        self.names.value = names_view(event.new)
        self.words.value = vocabulary_view(event.new)
        self._show_status(self._text())
        if not self.backend.engine.holds("indexes", event.new):
            pn.state.execute(self._load_indexes)

    def _on_name(self, event) -> None:
        name = self.names.value.iloc[int(event.row)]["name"]
        self._set_text(insert_name(self._text(), name))

    def _on_word(self, event) -> None:
        row = self.words.value.iloc[int(event.row)]
        self._set_text(insert_progression(self._text(), row["part"], row["state_0"], row["state_1"]))

    # ------------------------------------------------------------------ templates
    def _refresh_templates(self) -> None:
        names = stored_template_names(self.backend)
        self.templates.options = names
        self.describe.disabled = not names
        self.templates_note.object = "" if names else (
            "*No template is stored with this database: `mocapviz template learn DB --label CLASS` stores one; "
            "then \"Describe this template\" writes its description here.*")

    def _show_clip(self) -> None:
        query, (start, end), _ = self.selection.query()
        self.clip_note.object = (f"the session's query clip: {query_name(self.backend, query, named=True)}, frames "
                                 f"{start}:{end}")

    async def _on_describe_clip(self, event=None) -> None:
        """Write the description of the session's query clip (a document's span, or the uploaded take) in the
        page's relational set."""
        query, span, _ = self.selection.query()
        text = await self.task.run(f"Describing {query_name(self.backend, query)}", describe_query, self.backend,
                                   query, span, self.relational_set.value, busy=[self.describe_clip, self.find])
        if text is not None:
            self._set_text(text)

    async def _on_describe(self, event=None) -> None:
        name = self.templates.value
        if not name:
            return
        result = await self.task.run(f"Describing the template {name}", describe_template, self.backend, name,
                                     busy=[self.describe, self.find])  # fmt: skip
        if result is not None:
            text, relational_set = result
            if relational_set in RELATIONAL_SETS:
                self.relational_set.value = relational_set
            self._set_text(text)

    # ------------------------------------------------------------------ finding
    async def _on_find(self, event=None) -> None:
        text = self._text()
        if text != self.editor.value:
            self.editor.value = text  # -> _check: the set buttons follow a set the text names
        else:
            self._check(text)
        relational_set, n_matches = self.relational_set.value, self.n_matches.value
        hits = await self.task.run("Finding", search, self.backend, text, relational_set, n_matches, busy=self.find,
                                   stale=(self.count, self.table, self.timeline, self.player_box))
        if hits is None:
            self.hits = pd.DataFrame()
            return
        self.hits = hits
        self.description = parse_description(text, hits.attrs.get("relational_set", relational_set))
        self.gallery.show_hits(hit_columns(hits, HIT_TITLES, HIT_DECIMALS))
        n = len(hits)
        if n:
            self.count.object = (f"<b>{plural(n, 'hit')}</b> (K = {n_matches}; score: the hit's length "
                                 "in seconds, shortest first; parts: the frames where each part matched), found in "
                                 f"{hits.attrs.get('ms', 0):.0f} ms")  # fmt: skip
        else:
            reason = html.escape(hits.attrs.get("empty_reason") or "nothing matches")
            self.count.object = f"<b>No hit</b>: {reason}."
        self.timeline.object, self.player_box.visible, self.caption.object = None, False, PLAY_HINT
        await asyncio.sleep(0)
        self.table.param.trigger("value")  # the rows once more, in the page's final layout (as the Relational page)

    async def _on_select(self, event) -> None:
        if not event.new or self.hits.empty:
            return
        hit = self.hits.iloc[int(event.new[0])]
        doc, start, end = int(hit["doc_id"]), int(hit["start"]), int(hit["end"])
        await in_thread(self.backend.clip_relational, doc, self.description.relational_set)  # what the timeline reads
        db = self.backend.db
        self.player.load([db.positions[database_frames(db, doc, start, end)]], titles=[f"hit {int(hit['rank'])}"],
                         fps=self.backend.fps_of(doc))
        self.player_box.visible = True
        self.caption.object = (f"Playing hit {int(hit['rank'])}: <b>{html.escape(str(hit['name']))}</b> (document "
                               f"{doc}), frames {start}:{end} (end excluded, as in the table), {hit['score']:.2f} s"
                               f" · parts: {html.escape(str(hit['parts']))}")
        self.timeline.object = hit_timeline(self.backend, self.description, hit)
