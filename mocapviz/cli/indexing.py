"""``mocapviz index``: the relational features of a MotionDB computed and its inverted indexes built, with their
statistics (Müller et al. 2005, Table 1), by :meth:`mocapviz.engine.Engine.build_indexes`; indexes stored before an
ingest are extended with the new documents instead (:func:`mocapviz.engine.update_derived`). A module of its own:
the statistics import :mod:`mocapviz.experiments`, which the search commands need not load."""
from __future__ import annotations

from ..engine import Engine, layout, update_derived
from ..validation import plural
from .options import scheduler_of


def run_index(args) -> None:
    engine = Engine(args.db)
    db = engine.db
    extended = update_derived(db, [args.relational_set], [], progress=not args.quiet, rebuild=False).iloc[0]
    if extended["how"] == "extended":
        print(f"{db}: {args.relational_set} relational indexes in {layout.index_folder(db.path)} extended with the "
              f"{plural(extended['documents'], 'document')} ({plural(extended['frames'], 'frame')}) added since they "
              f"were built, in {extended['seconds']:.1f} s")  # fmt: skip
        return
    stats = engine.build_indexes(args.relational_set, progress=not args.quiet, scheduler=scheduler_of(args))
    print(f"{db}: {args.relational_set} relational indexes written to {layout.index_folder(db.path)}")
    print(stats.drop(columns=["t_read", "t_total"]).round(3).to_string(index=False))
