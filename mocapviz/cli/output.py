"""What the commands print and write: tables without their index and with blank missing cells, the ranked hit
table (``--csv FILE``), warping paths (``--paths``)."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..errors import ParameterError
from ..store import atomic_write
from ..validation import plural


def printed(table: pd.DataFrame) -> str:
    """A table as the commands print it, without its index: a missing cell (the label columns of an unlabelled
    document, a take number another archive has none of) blank, never NaN or <NA>."""
    blank = {c: table[c].astype(object).where(table[c].notna(), "") for c in table.columns
             if pd.api.types.is_integer_dtype(table[c]) and table[c].hasnans}  # to_string's na_rep skips Int64
    return table.assign(**blank).to_string(index=False, na_rep="")


def write_csv(table: pd.DataFrame, path: str | None) -> None:
    """``--csv FILE``: the ranked hit table, as printed but whole and without warping paths (atomically)."""
    if path:
        atomic_write(path, table.drop(columns=["path"], errors="ignore").to_csv(index=False).encode())
        print(f"ranked table written to {path}")


def csv_folder(path: str | None) -> None:
    """``--csv FILE`` checked before any work: its folder must exist."""
    if path and not Path(path).parent.is_dir():
        raise ParameterError(f"--csv {path}: no folder {Path(path).parent} to write it in")


def print_paths(table: pd.DataFrame, paths: bool) -> None:
    """``--paths``: each hit's warping path as query frame:frame of its document."""
    if paths:
        for rank, doc, path in zip(table["rank"], table["doc_id"], table["path"]):
            if path is not None:
                print(f"path {rank} (query frame:frame of document {doc}): " + " ".join(f"{i}:{j}" for i, j in path))


def print_ranked(table: pd.DataFrame, n_rows: int, empty: str) -> None:
    """A ranked result table without its path column, or one line saying there is none and what to try; and the
    marker-only documents the search did not look at (attrs ``marker_only_skipped``)."""
    if table.attrs.get("marker_only_skipped"):
        print(f"(not searched: {plural(table.attrs['marker_only_skipped'], 'marker-only document')}, which have no "
              "canonical joints; `mocapviz markers` searches them)")
    if table.empty:
        print(f"no matches ({empty})")
        return
    with pd.option_context("display.width", 160, "display.max_rows", n_rows + 5):
        shown = table.drop(columns=["path"], errors="ignore").dropna(axis=1, how="all")  # label columns of others
        print(printed(shown.round(3)))
