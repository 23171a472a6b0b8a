"""The ``mocapviz`` command.

    mocapviz ingest PATH... --out DB [--fps N] [--labels FILE] [--skip-bad] [--scheduler ADDRESS | [--no-cluster] [--jobs N]]
    mocapviz info DB [--documents]
    mocapviz index DB [--relational-set 2005|2006] [--scheduler ADDRESS | --no-cluster]
    mocapviz query DB --example FILE|DOC_ID [--frames A:B] --features NAMES [--mode M] [--mismatch M [--mismatch-at I,J]]
                      [--relational-set 2005|2006] [-K 20] [--csv FILE]
    mocapviz features DB [--numeric-sets F15E,F30E,...] [--pca FILE|DB] [--scheduler ADDRESS | --no-cluster]
    mocapviz knn DB --frame DOC:FRAME [--numeric-set F15E] [-k 16] [--radius R] [--eps E] [--no-exclude-document]
                    [--per-document] [--csv FILE]
    mocapviz match DB --example FILE|DOC_ID [--frames A:B] [--numeric-set F15E] [-K 10] [-k 256] [--radius R] [--eps E]
                      [--method lng|dtw] [--min-length 0.5] [--paths] [--csv FILE]
    mocapviz search DB --example FILE|DOC_ID [--frames A:B] [--numeric-set F15E] [-K 10] [--mode exact|fast|brute]
                       [--stretches [--min-length 0.5]] [--no-exclude-document] [--csv FILE] [--paths]
    mocapviz find DB "DESCRIPTION" | --file FILE [--template-file NAME=FILE]... [-K 20] [--explain] [--csv FILE]
    mocapviz template learn DB --label CLASS [--actors A,B,...] [--relational-set 2005|2006] [--max-examples 16]
                               [--iterations 10] [--out FILE]
    mocapviz template search DB FILE_OR_NAME [-K 20] [--delta 0.2] [--max-cost C] [--csv FILE] [--prefilter]
    mocapviz labels DB add --doc ID --frames A:B --label NAME [--author NAME] [--source S] [--note TEXT]
    mocapviz labels DB list [--label NAME] [--csv FILE] | remove ID | undo [--change N] | history
    mocapviz labels DB export [--format csv|babel] --out FILE | import FILE [--author NAME]
    mocapviz export DB (--hits HITS.csv | --doc ID [--frames A:B]) --format bvh|amc|glb [--rig source|canonical]
                       --out DIR [--search TEXT]
    mocapviz reproduce NAME|all [--full] --out DIR   (NAME: an experiment, e.g. rank_correlations, reconstruction)
    mocapviz serve [DB] [--port 5006] [--address 127.0.0.1 | --address ADDRESS --allow-origin HOST:PORT...] [--show]
                   [--auth USERS [--cookie-secret-file FILE]]                  (no DB: the embedded demo)
    mocapviz users USERS add NAME --role read|annotate|admin | list | remove NAME | role NAME ROLE | password NAME
    mocapviz datasets list
    mocapviz datasets fetch NAME        (NAME: a shared archive, or ``sample`` / ``demo``, embedded)

``ingest``, ``features`` and ``index`` run their work as Dask tasks: on the scheduler at ``--scheduler ADDRESS``
(``tcp://host:8786``), else on a local cluster started for the command (one single-threaded worker process per
core, or ``ingest --jobs N`` workers; :mod:`mocapviz.parallel`). ``--no-cluster`` runs in this process instead, on
threads (for ``ingest``, ``--jobs N`` of them), as the library functions do by default.

Options follow docs/glossary.md: ``-K`` / ``--matches`` is how many results (hits, clips, stretches) to report,
``-k`` how many neighbours per query frame, ``--relational-set`` / ``--numeric-set(s)`` which features. The older
spellings still work: ``--top`` (query, for ``-K``), ``--feature-set`` (for ``--relational-set``), ``--features``
(knn, match, search: for ``--numeric-set``) and ``--sets`` (features: for ``--numeric-sets``).

Every command that prints hits (``query``, ``knn``, ``match``, ``search``, ``template search``) prints and, with
``--csv FILE``, writes the one hit table of :func:`mocapviz.db.hits.hit_table`: ``start`` and ``end`` within the
document, half-open, ``start_s`` and ``end_s`` at the document's own rate.

``export`` writes what a search found (``--hits``: the CSV of ``--csv FILE``) or one stretch of a document as files,
one per hit, named ``<rank>_doc<id>_<name>_<start>-<end>.<format>``, all or nothing (a failure or SIGTERM leaves
the output folder as it was; :mod:`mocapviz.export`, docs/export.md).

Errors print one line (``mocapviz: error: ...``): a value the argument parser refuses (not a number, out of its
range, an unknown name, a list where one value is allowed) exits with status 2, one the command refuses (checked
against the database or the clip: frames of a document, the query's segments, k neighbours) with status 1. No
value is clamped or ignored: what runs is what the command line says.
"""
from __future__ import annotations

import atexit
import contextlib
import os
import sys
import threading
import warnings

# Only what the parser needs is imported here (``mocapviz --help`` loads neither pandas nor numba): each command's
# module, with its imports at its top, is imported when the command runs (parser.py; tests/test_startup.py,
# benchmarks/bench_startup.py).
from ..errors import MocapvizError
from ..heap import restart_with_trimmable_heap
from .parser import build_parser

__all__ = ["build_parser", "main", "run"]


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"mocapviz: warning: {message}", file=sys.stderr)


def main(argv=None) -> int:
    """Run ``mocapviz ARGV``; return the exit status: 0, 1 (the command refused a value or failed on bad input), 2
    (the argument parser refused the command line; returned, not raised, like every other status) or 3 (``check``:
    derived data stale, nothing damaged)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help (0) or a refused command line (2), its one line already printed
        return int(exc.code or 0)
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            status = args.func(args)
    except (MocapvizError, OSError) as exc:  # bad input; anything else is a bug and shows its traceback
        print(f"mocapviz: error: {exc}", file=sys.stderr)
        return 1
    return status or 0


def run() -> None:
    """The ``mocapviz`` command (the console script, ``python -m mocapviz.cli``): :func:`main` on this process's
    command line, then exit with its status.

    ``mocapviz serve`` first restarts itself with Python's objects on glibc's heap
    (:func:`mocapviz.heap.restart_with_trimmable_heap`; not where the C library is another, nor when ``PYTHONMALLOC``
    is set): its pages' objects, freed when a browser session closes, then leave the server's memory.

    The exit leaves out the interpreter's teardown, which frees a thousand modules (pandas, numba, LLVM) one by one:
    0.1 to 0.25 s, a fifth of a search, that a finished command does not need. What a normal exit does for the
    command is done first: the output flushed, the atexit handlers run. With a thread still running, or output that
    cannot be flushed (a closed pipe), the exit is the normal one.
    """
    if sys.argv[1:2] == ["serve"]:  # a long-running server: what its closed sessions free goes back to the system
        restart_with_trimmable_heap()
    status = main()
    if threading.active_count() > 1:  # a thread's work would be cut short
        sys.exit(status)
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):  # let the normal exit report it
        sys.exit(status)
    atexit._run_exitfuncs()  # logging.shutdown, multiprocessing's children, weakref.finalize (temporary folders)
    with contextlib.suppress(OSError, ValueError):
        sys.stdout.flush()
        sys.stderr.flush()
    os._exit(status)
