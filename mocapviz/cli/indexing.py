"""``mocapviz index``: the relational features of a MotionDB computed and its inverted indexes built, with their
statistics (Müller et al. 2005, Table 1). A module of its own: the statistics import :mod:`mocapviz.experiments`,
which the search commands need not load."""
from __future__ import annotations

import time
from pathlib import Path

from ..db.database import MotionDB
from ..experiments import index_statistics
from ..features import relational_features
from ..relational.index import build
from .options import scheduler_of


def run_index(args) -> None:
    db = MotionDB.open(args.db)
    t0 = time.perf_counter()
    values, _ = relational_features(db, args.relational_set, progress=not args.quiet, scheduler=scheduler_of(args))
    t_features = time.perf_counter() - t0
    build(db, args.relational_set, values=values)
    stats = index_statistics(db, args.relational_set, values=values, t_features=t_features)
    print(f"{db}: {args.relational_set} relational indexes written to {Path(db.path) / 'index'}")
    print(stats.drop(columns=["t_read", "t_total"]).round(3).to_string(index=False))
