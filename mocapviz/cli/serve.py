"""``mocapviz serve``: the dashboard (:mod:`mocapviz.app`) on a database, or on the embedded demo."""
from __future__ import annotations

import contextlib

from .. import app
from ..app.backend import demo_database
from ..engine import MotionDB


def run_serve(args) -> None:
    app.websocket_origins(args.address, args.port, args.allow_origin)  # refused before the sample is ingested
    db = args.db if args.db else demo_database()
    MotionDB.open(db)  # a bad path fails before the server starts
    print(f"mocapviz: serving {db}: warming up (the first clicks then answer at once) …", flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        app.serve(db, port=args.port, address=args.address, show=args.show, allow_origin=args.allow_origin,
                  scheduler=args.scheduler,
                  ready=lambda url: print(f"mocapviz: ready: {url} (Ctrl-C stops)", flush=True))
