"""``mocapviz export``: what a search found (its ``--csv`` hit table) or one stretch of a document, as motion files
(BVH, AMC or glTF binary), all or nothing (docs/export.md)."""
from __future__ import annotations

import contextlib
import signal
import threading

from ..engine import Engine
from ..errors import ParameterError
from ..validation import frame_span


def run_export(args) -> None:
    if args.frames is not None and args.doc is None:
        raise ParameterError("--frames A:B cuts the document of --doc ID; the stretches of --hits are their rows' "
                             "start:end")  # fmt: skip
    engine = Engine(args.db)
    db = engine.db
    with _terminate_as_exit():  # SIGTERM mid-export: the written files are removed before the process ends
        if args.doc is not None:
            doc = int(db.document(args.doc)["doc_id"])  # an unknown id: an error naming the valid ones
            a, b = frame_span(args.frames, int(db.document(doc)["n_frames"]), f"document {doc}", "--frames", least=1)
            paths = engine.export_stretch(doc, args.out, frames=(a, b), format=args.format, rig=args.rig,
                                          search=args.search)  # fmt: skip
        else:
            paths = engine.export(args.hits, args.out, format=args.format, rig=args.rig, search=args.search)
    for path in paths:
        print(path)
    print(f"{len(paths)} file(s) written to {args.out}")


@contextlib.contextmanager
def _terminate_as_exit():
    """In the block, SIGTERM raises SystemExit (status 143, as the signal's default) in the main thread, so that
    cleanup in ``finally`` clauses and context managers runs; the previous handler afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def leave(signum, frame):
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, leave)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
