"""``mocapviz serve``: the dashboard (:mod:`mocapviz.app`) on a database, or on the embedded demo."""
from __future__ import annotations

import contextlib

from .. import app
from ..app.backend import demo_database
from ..engine import MotionDB
from ..errors import ParameterError
from ..users import roles


def run_serve(args) -> None:
    app.websocket_origins(args.address, args.port, args.allow_origin)  # refused before the sample is ingested
    if args.auth is not None:
        roles(args.auth)  # so is a users file that cannot be read
    elif args.cookie_secret_file is not None:
        raise ParameterError("--cookie-secret-file signs the sign-in cookies of --auth: give --auth FILE too")
    db = args.db if args.db else demo_database()
    MotionDB.open(db)  # a bad path fails before the server starts
    print(f"mocapviz: serving {db}: warming up (the first clicks then answer at once) …", flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        app.serve(db, port=args.port, address=args.address, show=args.show, allow_origin=args.allow_origin,
                  scheduler=args.scheduler, auth=args.auth, cookie_secret_file=args.cookie_secret_file,
                  ready=lambda url: print(f"mocapviz: ready: {url} (Ctrl-C stops)", flush=True))
