"""The command line the ``mocapviz`` command accepts (:func:`build_parser`): its sub-commands, in the order
``mocapviz --help`` lists them, their options and which handler runs each.

Light: ``mocapviz --help`` imports this module and what it imports (the engine's parameter table, the checks of
:mod:`mocapviz.validation`), neither pandas nor numba (tests/test_startup.py). Each handler is in the module of its
command group, whose imports are at its top; the ``func`` of a sub-parser is a stub here that imports that module
when the command runs (a function-level import within the runners layer).
"""
from __future__ import annotations

import argparse
import functools

from ..engine import FPS_RANGE, NUMERIC_SETS
from ..engine.parameters import PARAMETERS as P
from ..engine.parameters import RULES, add_options, default
from ..errors import ParameterError
from ..users import COOKIE_SECRET_ENV, COOKIE_SECRET_LENGTH, ROLES
from ..validation import parse_integers, parse_names, parse_port, parse_span
from .options import (
    CSV_HELP,
    STRETCH_POOL,
    Parser,
    cluster_options,
    count_check,
    number_check,
    option,
    search_scheduler,
)

MAX_JOBS = 256
"""``ingest --jobs``: worker processes or reader threads at most."""


NUMERIC_SPELLINGS = {"numeric_set": ("--numeric-set", "--features")}  # --features: the option's old name


LABEL_HELP = ("keep the hits that overlap a stretch of this label: a segment label (mocapviz labels) or a document "
              "of that file-name label")


def build_parser() -> argparse.ArgumentParser:
    """The parser of the ``mocapviz`` command: every sub-command, its options (the search options from the engine's
    parameter table) and its handler, a stub below that imports the command's module when the command runs."""
    p = Parser(prog="mocapviz", description="Content-based retrieval in motion-capture databases.")
    sub = p.add_subparsers(dest="command", required=True)

    ing = sub.add_parser("ingest", help="read ASF/AMC, BVH, C3D and FBX files into a MotionDB (creates or appends)")
    ing.add_argument("paths", nargs="+", help="files, folders (searched recursively) or glob patterns")
    ing.add_argument("--out", required=True, help="MotionDB directory")
    option(ing, "--fps", check=number_check(low=FPS_RANGE[0], high=FPS_RANGE[1]),
           help=f"resample every clip to this frame rate ({FPS_RANGE[0]}..{FPS_RANGE[1]:,})")
    ing.add_argument("--labels", help="label table (TSV/CSV with a 'file' column); default: tables beside the data")
    ing.add_argument("--mapping", help="JSON file {canonical joint: joint name} for rigs the rules cannot map")
    ing.add_argument("--asf", help="ASF skeleton for all AMC files (default: found beside each)")
    P["marker_mapping"].add_to(ing)
    P["take"].add_to(ing)
    P["markers_only"].add_to(ing)
    ing.add_argument("--up", choices=["auto", "y", "z"], help="up axis of BVH files (default auto)")
    ing.add_argument("--skip-bad", action="store_true", help="skip unreadable files with a warning")
    cluster_options(ing)
    option(ing, "--jobs", check=count_check(least=1, most=MAX_JOBS), help=f"(1..{MAX_JOBS}) worker processes of the "
           "local cluster (default: one per core), or "
                    "with --no-cluster reader threads (default: the cores, at most 8)")
    ing.add_argument("--quiet", action="store_true", help="no progress bar")
    ing.set_defaults(func=_ingest)

    info = sub.add_parser("info", help="summarise a MotionDB")
    info.add_argument("db")
    info.add_argument("--documents", action="store_true", help="also list every document")
    info.set_defaults(func=_info)

    chk = sub.add_parser("check", help="read every file of a MotionDB and its derived data back and verify its "
                                       "checksum; exit status 0 if all are ok, 1 if any is damaged, 3 if derived data "
                                       "is only stale (older than the documents: the commands that rebuild it are "
                                       "printed)")  # fmt: skip
    chk.add_argument("db")
    chk.set_defaults(func=_check)

    c3 = sub.add_parser("c3d", help="C3D marker files: the labels of one and the marker set they match")
    c3sub = c3.add_subparsers(dest="action", required=True)
    cm = c3sub.add_parser("markers", help="print each marker label (subject prefix cut; with --mapping, the marker "
                          "name it is mapped to), its percentage of gap frames, and the marker set the labels match "
                          "(cmu: CMU/HDM05; plug-in gait: full or lower body, with or without head markers) or, for "
                          "none, the markers the closest set lacks")  # fmt: skip
    cm.add_argument("file", help="a .c3d file")
    P["marker_mapping"].add_to(cm, "--mapping")
    cm.set_defaults(func=_c3d_markers)

    idx = sub.add_parser("index", help="compute relational features and build the inverted indexes of a MotionDB")
    idx.add_argument("db")
    idx.add_argument("--relational-set", "--feature-set", dest="relational_set", default="2005",
                     choices=["2005", "2006"], help="relational set (default 2005; --feature-set: its old name)")
    cluster_options(idx)
    idx.add_argument("--quiet", action="store_true", help="no progress bar")
    idx.set_defaults(func=_index)

    q = sub.add_parser("query", help="query by example: ranked hits of a clip's progression of chosen features")
    q.add_argument("db")
    q.add_argument("--example", required=True, help="a motion file, or a document id of the DB")
    option(q, "--frames", check=parse_span, help="frame span A:B of the example, B excluded (default: all of it)")
    q.add_argument("--features", help="comma-separated relational feature names (default: the clip's suggested "
                   "query, its features and m, as the Relational page poses it: docs/relational.md)")
    P["query_mode"].add_to(q, "--mode")
    q.add_argument("--mismatch", dest="mismatches", type=P["mismatches"].reader("--mismatch"),
                   help="answer in mismatch mode: " + P["mismatches"].help("none: the --mode given"))
    option(q, "--mismatch-at", check=functools.partial(parse_integers, least=0), dest="allowed",
           help=P["allowed"].help() + "; with --mismatch, comma-separated 0-based segments")
    P["relational_set"].add_to(q, "--relational-set", "--feature-set")
    option(q, "-K", "--matches", "--top", check=count_check(least=1), dest="rows", default=20,
           help="hits to print (default 20; --top: its old name)")
    q.add_argument("--csv", help=CSV_HELP)
    add_options(q, "query")  # --exclude-document / --no-exclude-document
    search_scheduler(q)
    q.set_defaults(func=_query)

    fd = sub.add_parser("find", help="the stretches a scene description describes (\"kick_right then punch_left "
                        "within 2 s\"; docs/descriptions.md), through the relational index",
                        description="Find what a scene description describes (Müller et al. 2005 §6.3): progressions "
                        "of the relational features' states (rknee: straight bent straight), joined by 'and' "
                        "(concurrent), 'then ... within T s' and '|'; shipped names (mocapviz find --list) and stored "
                        "templates (template:NAME). Needs the relational index (mocapviz index DB). Columns as every "
                        "result table: start and end within the document, half-open; score = the hit's length in "
                        "seconds (shortest first); parts = where each part matched.")  # fmt: skip
    fd.add_argument("db", nargs="?", help="the MotionDB")
    fd.add_argument("description", nargs="?", help="the description, in quotes")
    fd.add_argument("--file", help="read the description from this file instead")
    P["n_matches"].add_to(fd, default=default("find", "n_matches"))
    fd.add_argument("--relational-set", dest="relational_set", choices=P["relational_set"].choices,
                    help="the set whose words the description uses (default: the one its 'set' statement or its "
                    "templates name, else 2005)")  # fmt: skip
    P["template_cost"].add_to(fd)
    fd.add_argument("--explain", action="store_true", help="print the description as read, the hits of each part "
                    "and where each hit's parts matched")  # fmt: skip
    fd.add_argument("--list", action="store_true", help="list the shipped named descriptions and exit")
    fd.add_argument("--label", type=P["label"].reader("--label"), help=LABEL_HELP)
    fd.add_argument("--csv", help=CSV_HELP)
    fd.add_argument("--template-file", action="append", dest="template_files", metavar="NAME=FILE",
                    help="read template:NAME from this template file (.npz, `mocapviz template learn --out`) instead "
                    "of the one stored as NAME with the database; repeatable. The description itself names stored "
                    "templates only, never a file")  # fmt: skip
    search_scheduler(fd)
    fd.set_defaults(func=_find)

    feat = sub.add_parser("features", help="compute and store the numeric feature sets of a MotionDB (kNN search)")
    feat.add_argument("db")
    option(feat, "--numeric-sets", "--sets", check=functools.partial(parse_names, what="numeric set",
           options=NUMERIC_SETS), dest="numeric_sets", help=f"comma-separated numeric sets (default "
                     f"all: {','.join(NUMERIC_SETS)}; --sets: its old name)")  # fmt: skip
    feat.add_argument("--pca", help="PCA reference for Fp8/16/25 (only with one of them): a saved model (.npz) or a "
                      "MotionDB to fit it on (default: fitted on DB itself)")
    cluster_options(feat)
    feat.add_argument("--quiet", action="store_true", help="no progress bar")
    feat.set_defaults(func=_features)

    kn = sub.add_parser("knn", help="the k nearest frames of one frame of a MotionDB (kd-tree)")
    kn.add_argument("db")
    option(kn, "--frame", check=_doc_frame, required=True, help="DOC:FRAME, a document id and a frame within it")
    add_options(kn, "neighbours", {**NUMERIC_SPELLINGS, "k": ("-k",)})
    kn.add_argument("--quiet", action="store_true", help="no progress bar")
    kn.add_argument("--csv", help=CSV_HELP)
    search_scheduler(kn)
    kn.set_defaults(func=_knn)

    mt = sub.add_parser("match", help="stretches of the DB that move like an example, ranked (lazy neighbourhood "
                        "graph or subsequence DTW)")  # fmt: skip
    mt.add_argument("db")
    mt.add_argument("--example", required=True, help="a motion file, or a document id of the DB (then its own "
                    "document is excluded from the matches)")  # fmt: skip
    option(mt, "--frames", check=parse_span, help="frame span A:B of the example, B excluded (default: all of it)")
    for name in ("k", "radius", "eps"):  # of --method lng only: None when not given (refused with dtw)
        mt.add_argument(*P[name].cli_flags if name != "k" else ("-k",), dest=name, default=None,
                        type=P[name].reader("-k" if name == "k" else P[name].cli_flags[0]),
                        help="--method lng: " + P[name].help(RULES.get(("match", name), default("match", name))))
    add_options(mt, "match", NUMERIC_SPELLINGS)
    mt.add_argument("--csv", help=CSV_HELP)
    search_scheduler(mt)
    mt.set_defaults(func=_match)

    se = sub.add_parser("search", help="the clips (or stretches of long takes) of the DB that move most like an "
                        "example, ranked by DTW on a numeric feature set (exact or fast)")  # fmt: skip
    se.add_argument("db")
    se.add_argument("--example", required=True, help="a motion file, or a document id of the DB")
    option(se, "--frames", check=parse_span, help="frame span A:B of the example, B excluded (default: all of it)")
    se.add_argument("--stretches", action="store_true", help="the K best non-overlapping stretches inside documents "
                    "(subsequence DTW) instead of whole clips")  # fmt: skip
    se.add_argument("--min-length", dest="min_length", type=P["min_length"].reader("--min-length"),
                    help="with --stretches: " + P["min_length"].help())
    add_options(se, "clips", NUMERIC_SPELLINGS)
    add_options(se, "stretches")
    se.add_argument("--label", type=P["label"].reader("--label"), help=LABEL_HELP + " (clips: among every document's "
                    f"best clip; stretches: among the best {STRETCH_POOL} x K)")
    se.add_argument("--csv", help=CSV_HELP)
    search_scheduler(se)
    se.set_defaults(func=_search)

    mk = sub.add_parser("markers", help="the stretches of the DB's marker-only documents (C3D files of no known "
                        "marker set, ingested with --markers-only keep) whose markers move most like an example's, "
                        "among those of the same marker labels and rate, by subsequence DTW on the marker numeric set")
    mk.add_argument("db")
    mk.add_argument("--example", required=True, help="a marker-only document's id (negative, as `mocapviz info "
                    "--documents` lists them) or a C3D file")  # fmt: skip
    option(mk, "--frames", check=parse_span, help="frame span A:B of the example, B excluded (default: all of it)")
    add_options(mk, "marker_stretches")
    mk.add_argument("--csv", help=CSV_HELP)
    mk.set_defaults(func=_markers)

    au = sub.add_parser("audit", help="every pair of stretches that are near-copies (mirrored, re-timed, trimmed, "
                        "retargeted), clusters of copies, and a test split's leakage into train")  # fmt: skip
    au.add_argument("db")
    au.add_argument("--against", help="a second MotionDB: pairs between the two collections only")
    au.add_argument("--split", help="a CSV of doc (id or name) and split (train / val / test): report every test "
                    "stretch with a near-copy in train")  # fmt: skip
    add_options(au, "audit")
    au.add_argument("--csv", help="write every pair to this CSV file")
    au.add_argument("--leakage-csv", help="with --split: write the leakage report to this CSV file")
    au.add_argument("--keep-one", help="write the documents a clean set keeps (one of each cluster) to this CSV file")
    au.add_argument("--quiet", action="store_true", help="no progress bar")
    search_scheduler(au)
    au.set_defaults(func=_audit)

    tp = sub.add_parser("template", help="motion templates (Müller & Röder 2006): learn a class from its labelled "
                        "documents, stored with the DB; find its instances")  # fmt: skip
    tsub = tp.add_subparsers(dest="action", required=True)
    tl = tsub.add_parser("learn", help="learn the template of the documents with a label (of some actors only); "
                         "stored in DB/templates/LABEL[-ACTOR...].npz, replacing one of that name")  # fmt: skip
    tl.add_argument("db")
    tl.add_argument("--label", required=True, help="the class: a value of the documents' label column")
    tl.add_argument("--actors", help="comma-separated actors: learn from their documents only (default all)")
    add_options(tl, "learn_template")
    tl.add_argument("--example", action="append", dest="examples", metavar="FILE", help="a motion file (BVH, ASF + "
                    "AMC, C3D; read as ingest reads it, at the database's rate) learned from as one more example beside "
                    "the label's documents and segments (repeatable; with it, a label nothing has yet is allowed)")
    tl.add_argument("--out", help="also write the template to this file (.npz)")
    tl.set_defaults(func=_template_learn)
    ts = tsub.add_parser("search", help="the stretches of the DB that match a template, best first",
                         description="The K best non-overlapping stretches of the DB's documents that match a "
                         "template (subsequence DTW, its don't-care features left out). Columns: rank, doc_id, name, "
                         "start and end (the stretch's frames within its document, half-open: end is one past the last "
                         "frame, as every result table of mocapviz), frames, start_s, end_s, cost (DTW cost), normalised_cost (cost per template "
                         "frame: the mean disagreement, in [0, 1]) and the document's labels.")  # fmt: skip
    ts.add_argument("db")
    ts.add_argument("template", metavar="FILE_OR_NAME", help="a template file, or the name of one stored in "
                    "DB/templates/ (by `mocapviz template learn`)")  # fmt: skip
    add_options(ts, "search_template")
    ts.add_argument("--csv", help=CSV_HELP)
    search_scheduler(ts)
    ts.set_defaults(func=_template_search)

    lb = sub.add_parser("labels", help="segment labels: label stretches of documents (with author and time), list, "
                        "remove, undo, export and import them; every change kept in the label history")  # fmt: skip
    lb.add_argument("db", help="the MotionDB (its labels live in DB/labels/)")
    lsub = lb.add_subparsers(dest="action", required=True)
    la = lsub.add_parser("add", help="label frames A:B (B excluded) of a document")
    option(la, "--doc", check=count_check(least=0), required=True, metavar="ID", help="the document (a doc id)")
    option(la, "--frames", check=parse_span, required=True, metavar="A:B", help="frames A:B of it, B excluded")
    P["label"].add_to(la, required=True)
    for name in ("author", "source", "note"):
        P[name].add_to(la)
    ll = lsub.add_parser("list", help="the segment labels now, as a hit table")
    P["label"].add_to(ll)
    ll.add_argument("--csv", help="also write them to this CSV file (the hit table's columns, then label_id, label, "
                    "author, source, time, note)")  # fmt: skip
    lr = lsub.add_parser("remove", help="remove a segment label (a change of the history: undo puts it back)")
    option(lr, "label_id", check=count_check(least=1), metavar="ID", help="the label's id (labels list)")
    P["author"].add_to(lr)
    lu = lsub.add_parser("undo", help="undo the author's last change to the segment labels (or --change N), by a new "
                         "change that puts the label back exactly as it was")  # fmt: skip
    option(lu, "--change", check=count_check(least=1), metavar="N", help="the change to undo (labels history)")
    P["author"].add_to(lu)
    lh = lsub.add_parser("history", help="every change to the segment labels, in order")
    le = lsub.add_parser("export", help="write the segment labels to a file: CSV or BABEL-style JSON")
    P["label_format"].add_to(le)
    P["label"].add_to(le)
    le.add_argument("--out", required=True, help="the file to write (atomically)")
    li = lsub.add_parser("import", help="add the labels of a CSV or BABEL-style JSON file (.json), documents matched "
                         "by name, source 'imported'; all or none")  # fmt: skip
    li.add_argument("file", help="the CSV or .json file")
    P["author"].add_to(li)
    for action in (la, ll, lr, lu, lh, le, li):
        action.set_defaults(func=_labels)

    ex = sub.add_parser("export", help="write the stretches a search found (--hits, its --csv file) or one stretch "
                        "of a document (--doc) as motion files: BVH, AMC, glTF binary or HumanML3D joint arrays, one per hit")  # fmt: skip
    ex.add_argument("db")
    what = ex.add_mutually_exclusive_group(required=True)
    what.add_argument("--hits", metavar="HITS.csv", help="the hit table a search wrote with --csv FILE (columns rank, "
                      "doc_id, start, end: frames within the document, half-open)")  # fmt: skip
    option(what, "--doc", check=count_check(least=0), metavar="ID", help="one document (a doc id)")
    option(ex, "--frames", check=parse_span, metavar="A:B", help="with --doc: frames A:B of it (B excluded; "
           "default: all)")  # fmt: skip
    ex.add_argument("--format", required=True, choices=P["export_format"].choices, help=P["export_format"].doc)
    ex.add_argument("--rig", choices=P["rig"].choices, help=P["rig"].help())
    ex.add_argument("--out", required=True, help="output folder (created if missing; an existing one keeps its other "
                    "files). Written all or nothing: on any failure, the folder as it was")  # fmt: skip
    ex.add_argument("--search", help="what found the hits, written into every file (default: the hits file's name)")
    ex.set_defaults(func=_export)

    rp = sub.add_parser("reproduce", help="re-run the papers' experiments on the shared data; write CSV tables and "
                        "PNG/HTML figures")  # fmt: skip
    rp.add_argument("names", nargs="+", metavar="NAME", help="experiment function name(s) (index_statistics, "
                    "query_statistics, relational_query, alignment, knn_timings, rank_correlations, "
                    "similarity_matrices, lng_accuracy, numerical_search, reconstruction, base_poses, "
                    "retrieval_quality, template_quality, descriptions, annotation, audit) or 'all'")
    rp.add_argument("--out", required=True, help="output folder; each experiment writes OUT/NAME/")
    rp.add_argument("--full", action="store_true", help="the papers' sizes (slow; every shared archive as the "
                    "large database)")  # fmt: skip
    rp.add_argument("--quiet", action="store_true", help="no progress bars")
    rp.set_defaults(func=_reproduce)

    sv = sub.add_parser("serve", help="the dashboard in the browser: browse, query by example, kNN, matching, "
                        "correlations, index statistics, reconstruction")
    sv.add_argument("db", nargs="?", help="MotionDB folder (default: the embedded demo at 30 Hz, ingested once)")
    option(sv, "--port", check=parse_port, default=5006, help="port (1..65535, default 5006)")
    sv.add_argument("--address", default="127.0.0.1",
                    help="interface to listen on (default 127.0.0.1: this machine only; anything else exposes the "
                    "database to the network, needs --allow-origin and prints a warning)")
    sv.add_argument("--allow-origin", action="append", metavar="HOST:PORT", help="an address browsers open the "
                    "dashboard at besides 127.0.0.1, localhost, [::1] and --address at --port, e.g. "
                    "myhost.example.org:5006 (repeatable; needed with an --address other than loopback; never '*'). "
                    "Any other Host header, or WebSocket Origin (a WebSocket needs one), gets a 403")
    sv.add_argument("--show", action="store_true", help="open the dashboard in a web browser")
    sv.add_argument("--auth", metavar="FILE", help="ask for a user name and password (the users of FILE: mocapviz "
                    "users); every page, static file and WebSocket needs a signed-in user, whose role says what they "
                    "may do (docs/dashboard.md)")  # fmt: skip
    sv.add_argument("--cookie-secret-file", metavar="FILE", help="with --auth: sign the login cookies with the secret "
                    f"in FILE (at least {COOKIE_SECRET_LENGTH} characters; or the environment variable "
                    f"{COOKIE_SECRET_ENV}), so that users stay signed in when the server restarts (default: a new "
                    "secret each start)")  # fmt: skip
    search_scheduler(sv)
    sv.set_defaults(func=_serve)

    us = sub.add_parser("users", help="the users of `mocapviz serve --auth FILE`: add, list, remove, set a role or a "
                        "password (stored as salted scrypt hashes, never in clear)")  # fmt: skip
    us.add_argument("file", help="the users file (created by add; mode 0600)")
    usub = us.add_subparsers(dest="action", required=True)
    ua = usub.add_parser("add", help="add a user; the password is read twice from the terminal (or two lines of "
                         "standard input when it is not a terminal), never from the command line")  # fmt: skip
    ua.add_argument("name", help="the user name (letters, digits, . _ @ -; at most 64)")
    ua.add_argument("--role", required=True, choices=ROLES, help="read: search and download; annotate: also label "
                    "segments; admin: also add takes")  # fmt: skip
    ul = usub.add_parser("list", help="the users and their roles (never a hash)")
    ur = usub.add_parser("remove", help="remove a user (its sessions end when their browsers close; none starts again)")
    ur.add_argument("name")
    uo = usub.add_parser("role", help="give a user another role (from its next session)")
    uo.add_argument("name")
    uo.add_argument("role", choices=ROLES)
    up = usub.add_parser("password", help="set a user's password (read as for add)")
    up.add_argument("name")
    for action in (ua, ul, ur, uo, up):
        action.set_defaults(func=_users)

    ds = sub.add_parser("datasets", help="list the registered motion-capture datasets (the shared archives and the "
                        "embedded sample and demo) with sizes, licences and sources, or fetch one")
    ds.add_argument("action", choices=["list", "fetch"])
    ds.add_argument("name", nargs="?", help="for fetch: a shared archive (see list), or 'sample' or 'demo' (embedded)")
    ds.set_defaults(func=_datasets)
    return p


def _doc_frame(text: str, name: str) -> tuple[int, int]:
    """``DOC:FRAME``: a document id and a frame within it, both from 0 (whether they exist: the knn handler)."""
    try:
        doc, frame = (int(x) for x in text.split(":"))
    except ValueError:
        raise ParameterError(f"{name} must look like DOC:FRAME (a document id and a frame within it, both from 0), "
                             f"got {text!r}") from None
    if doc < 0 or frame < 0:
        raise ParameterError(f"{name} takes a document id and a frame from 0 (DOC:FRAME), got {text!r}")
    return doc, frame


# The handlers: each imports its command group's module when the command runs.
def _ingest(args):
    from . import database

    return database.run_ingest(args)


def _info(args):
    from . import database

    return database.run_info(args)


def _check(args):
    from . import database

    return database.run_check(args)


def _c3d_markers(args):
    from . import c3d

    return c3d.run_markers(args)


def _index(args):
    from . import indexing

    return indexing.run_index(args)


def _query(args):
    from . import relational

    return relational.run_query(args)


def _find(args):
    from . import relational

    return relational.run_find(args)


def _features(args):
    from . import similarity

    return similarity.run_features(args)


def _knn(args):
    from . import similarity

    return similarity.run_knn(args)


def _match(args):
    from . import similarity

    return similarity.run_match(args)


def _search(args):
    from . import similarity

    return similarity.run_search(args)


def _markers(args):
    from . import similarity

    return similarity.run_markers(args)


def _audit(args):
    from . import audit

    return audit.run_audit(args)


def _template_learn(args):
    from . import templates

    return templates.run_template_learn(args)


def _template_search(args):
    from . import templates

    return templates.run_template_search(args)


def _labels(args):
    from . import labels

    return labels.run_labels(args)


def _export(args):
    from . import export

    return export.run_export(args)


def _reproduce(args):
    from . import datasets

    return datasets.run_reproduce(args)


def _serve(args):
    from . import serve

    return serve.run_serve(args)


def _users(args):
    from . import users

    return users.run_users(args)


def _datasets(args):
    from . import datasets

    return datasets.run_datasets(args)
