"""Speed benchmarks of mocapviz, each beside a baseline, on the real shared archives.

Run ``python -m benchmarks`` (``make bench``), or ``python -m benchmarks --quick`` for a smoke run on small
subsets. Tables are printed as markdown; the same rows are written as CSV under ``benchmarks/results/``.

bench_io    readers (parse + forward kinematics, ASF/AMC and BVH) and ``MotionDB.ingest``.
"""
