"""The segment-label commands, ``mocapviz labels DB add|list|remove|undo|history|export|import``: the database's
segment labels (who said which stretch of which document is what) and their history, through the engine
(:meth:`mocapviz.engine.Engine.add_label` and its neighbours). ``--author`` defaults to the operating system's user
name; every change is one entry of the label history, written atomically under the labels' lock."""
from __future__ import annotations

import pandas as pd

from ..engine import Engine
from ..errors import ParameterError
from ..validation import plural
from .output import csv_folder, printed, write_csv


def run_labels(args) -> None:
    engine = Engine(args.db)
    _ACTIONS[args.action](engine, args)


def _add(engine: Engine, args) -> None:
    a, b = args.frames
    if a is None or b is None:
        raise ParameterError("--frames: give both ends of the stretch, A:B (B excluded)")
    label_id = engine.add_label(args.doc, frames=(a, b), label=args.label, author=args.author, source=args.source,
                                note=args.note)  # fmt: skip
    print(f"label {label_id}: frames {a}:{b} of document {args.doc} are {args.label!r} "
          f"(change {len(engine.label_history())} of the label history)")


def _list(engine: Engine, args) -> None:
    csv_folder(args.csv)
    table = engine.segment_labels(label=args.label)
    shown = table[["label_id", "doc_id", "name", "start", "end", "start_s", "end_s", "label", "author", "source",
                   "time", "note"]]  # fmt: skip
    print(f"{plural(len(table), 'segment label')} in {engine.db.path}" + (f" of {args.label!r}" if args.label else ""))
    if len(table):
        with pd.option_context("display.width", 200, "display.max_rows", len(table) + 5):
            print(printed(shown.round(3)))
    write_csv(table, args.csv)


def _remove(engine: Engine, args) -> None:
    change = engine.remove_label(args.label_id, author=args.author)
    print(f"label {args.label_id} removed (change {change}; `mocapviz labels {engine.db.path} undo` puts it back)")


def _undo(engine: Engine, args) -> None:
    change = engine.undo_label(args.change, author=args.author)
    done = engine.label_history().iloc[change - 1]
    print(f"change {int(done['undoes'])} undone by change {change} ({done['op']} of label {done['label_id']})")


def _history(engine: Engine, args) -> None:
    table = engine.label_history()
    print(f"{plural(len(table), 'change')} to the segment labels of {engine.db.path}")
    if len(table):
        with pd.option_context("display.width", 200, "display.max_rows", len(table) + 5):
            print(printed(table))


def _export(engine: Engine, args) -> None:
    engine.export_labels(args.out, format=args.label_format, label=args.label)
    print(f"{plural(len(engine.segment_labels(label=args.label)), 'segment label')} written to {args.out} "
          f"({args.label_format})")


def _import(engine: Engine, args) -> None:
    ids = engine.import_labels(args.file, author=args.author)
    print(f"{plural(len(ids), 'segment label')} imported from {args.file}"
          + (f" (label ids {ids[0]}..{ids[-1]})" if ids else ""))


_ACTIONS = {"add": _add, "list": _list, "remove": _remove, "undo": _undo, "history": _history, "export": _export,
            "import": _import}  # fmt: skip
