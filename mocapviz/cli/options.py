"""The command line's parser and the options several commands share: one-line errors (:class:`Parser`), an option
checked by :mod:`mocapviz.validation` (:func:`option`), the scheduler options. Light: ``mocapviz --help`` imports it
(neither pandas nor numba; tests/test_startup.py)."""
from __future__ import annotations

import argparse
import functools
import re

from ..errors import ParameterError
from ..parallel import LOCAL  # light: dask itself is imported by dask_client
from ..validation import parse_count, parse_number

STRETCH_POOL = 20  # search --stretches --label: the label is looked for among the best 20 x K stretches
CSV_HELP = ("also write the ranked hit table to this CSV file (columns and frames as docs/glossary.md, Results: start "
            "and end within the document, half-open)")
"""``--csv FILE`` of every command that prints hits."""


class Parser(argparse.ArgumentParser):
    """argparse with mocapviz's one-line errors: ``mocapviz: error: ...`` and where to read the usage, status 2."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # a value such as "-5:10" (--frames) is the option's value, as "-1" is, not an option: its check says why
        # it is refused
        self._negative_number_matcher = re.compile(r"^-\d+$|^-\d*\.\d+$|^-\d*:\d*$")

    def error(self, message: str):
        message = re.sub(r"^argument (\S+): \1(?=[ :])", r"\1", message)  # a check that names the option itself
        self.exit(2, f"mocapviz: error: {message} (see `{self.prog} --help`)\n")


def option(parser: argparse.ArgumentParser, *flags: str, check, **kwargs) -> None:
    """``parser.add_argument(*flags, **kwargs)`` whose value is ``check(text, name)``: a check of
    :mod:`mocapviz.validation` (its range bound with functools.partial) called with the option's names
    ("-K/--matches/--top"); its ParameterError becomes the parser's one-line error (status 2)."""
    name = "/".join(flags)

    def parse(text: str):
        try:
            return check(text, name)
        except ParameterError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parser.add_argument(*flags, type=parse, **kwargs)


count_check = functools.partial(functools.partial, parse_count)  # count_check(least=1) -> check(text, name)
number_check = functools.partial(functools.partial, parse_number)


def scheduler_address(text: str, name: str) -> str:
    """``--scheduler``: a dask.distributed scheduler address (or ``local``): not empty, no spaces."""
    if not text.strip() or any(c.isspace() for c in text):
        raise ParameterError(f"{name} needs a scheduler address such as tcp://host:8786 (or 'local'); got {text!r}")
    return text


def cluster_options(p: argparse.ArgumentParser) -> None:
    """``--scheduler ADDRESS`` and ``--no-cluster`` of the commands that run Dask tasks (ingest, features, index)."""
    option(p, "--scheduler", check=scheduler_address, metavar="ADDRESS", help="run the tasks on this "
           "dask.distributed scheduler "
                  "(e.g. tcp://host:8786; its workers must see the same paths); default: a local cluster, one "
                  "worker process per core")  # fmt: skip
    p.add_argument("--no-cluster", action="store_true", help="no Dask: work in this process (threads)")


def search_scheduler(p: argparse.ArgumentParser) -> None:
    """``--scheduler local|ADDRESS`` of the commands that search through the engine."""
    option(p, "--scheduler", check=scheduler_address, metavar="ADDRESS", help="search the database sharded over "
           "a Dask cluster: 'local' (a local cluster, one worker per core) or a scheduler's address such as "
           "tcp://host:8786 (its workers must see the database's path); the same answer as without (exact "
           "modes); default: this process")  # fmt: skip


def scheduler_of(args):
    """The ``scheduler=`` of the ingest / features / index commands: None (--no-cluster), an address, or local."""
    if args.no_cluster:
        if args.scheduler:
            raise ParameterError("--scheduler and --no-cluster exclude each other")
        return None
    return args.scheduler or LOCAL
