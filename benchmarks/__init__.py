"""Speed benchmarks of mocapviz, each beside a baseline, on the real shared archives.

Run ``python -m benchmarks`` (``make bench``), or ``python -m benchmarks --quick`` for a smoke run on small
subsets. Tables are printed as markdown; the same rows are written as CSV under ``benchmarks/results/``.

common            what they share: machine description, markdown tables, the cached benchmark MotionDB.
bench_io          readers (parse + forward kinematics, ASF/AMC and BVH) and ``MotionDB.ingest``.
bench_relational  relational features, inverted-index build and queries (Müller et al. 2005, Tables 2-3).
bench_knn         kNN search per feature set and fat-graph base poses (Krüger et al. 2010, Table 1, §5.3).
bench_startup     wall time of ``import mocapviz``, ``mocapviz --help`` and one search from a fresh process.
bench_descriptions  scene descriptions (issue 25): ``find`` through the 2005 indexes vs the frame-wise scan.
bench_engine      every use case through ``mocapviz.engine.Engine(db)`` beside the library function it wraps: the
                  engine's added milliseconds per query, its construction and first queries (issue 38).
"""
