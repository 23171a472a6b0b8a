"""``mocapviz datasets`` (the registered motion-capture datasets listed, or one fetched) and ``mocapviz reproduce``
(the papers' experiments run again on them)."""
from __future__ import annotations

from ..errors import ParameterError
from ..io import datasets
from ..reproduction import reproduce


def run_datasets(args) -> None:
    if args.action == "list" and args.name:
        raise ParameterError(f"datasets list takes no NAME (got {args.name!r}); `mocapviz datasets fetch NAME` "
                             "fetches one")
    if args.action == "list":
        for row in datasets.info().itertuples(index=False):
            where = "embedded in the package, no download" if row.embedded else "shared archive"
            state = "unpacked in the cache" if row.cached else "not unpacked yet"
            print(f"{row.name}: {row.description}")
            print(f"    {row.files}; {row.frames:,} frames at {row.fps} Hz; {row.size / 1e6:.1f} MB .tar.xz; "
                  f"{where}; {state}")
            print(f"    licence: {row.licence}")
            print(f"    source: {row.source}")
        try:
            located = f"shared archives from {datasets.data_url()}"
        except datasets.DatasetError:
            located = (f"shared archives not found: set {datasets.DATA_URL_ENV} to a folder or URL holding them "
                       "(a source checkout also finds ../shared/data)")
        print(f"{located}; cache {datasets.cache_dir()} ({datasets.HOME_ENV})")
    else:
        if not args.name:
            raise ParameterError(f"datasets fetch needs a NAME: {', '.join([*datasets.names(), *datasets.EMBEDDED])}")
        print(datasets.fetch(args.name, progress=True))


def run_reproduce(args) -> None:
    reproduce(args.names, args.out, full=args.full, progress=not args.quiet)
