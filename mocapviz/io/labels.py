"""Class labels of motion files, read from the label tables that travel with the shared archives.

- ``labels.tsv`` (HDM05, CMU): a tab-separated table, one row per motion file, first column ``file`` relative
  to the table's folder. HDM05 columns: file, actor, class, take, frames, fps, split; CMU: file, asf, group,
  cmu_subject, cmu_trial, description, fps.
- Bandai Namco: each ``data/NAME.bvh`` has a ``data/NAME.json`` ``{"content": i, "style": j}`` whose indices
  are 0-based lines of ``cfg/content_label.txt`` and ``cfg/style_label.txt`` beside ``data/``.

:func:`labels_for` finds the labels of one file by itself, whichever the source.
"""

from __future__ import annotations

import csv
import functools
import json
import re
from pathlib import Path

import pandas as pd

from ..errors import LabelTableError

INT_COLUMNS = ("frames", "fps", "take")
MAIN_LABEL_COLUMNS = ("class", "description", "content")
TABLE_NAME = "labels.tsv"
SEARCH_LEVELS = 4
_BANDAI_PREFIX = re.compile(r"^dataset-\d+_")


def read_labels_tsv(path) -> pd.DataFrame:
    """Read a ``labels.tsv`` table.

    Parameters
    ----------
    path : str or os.PathLike
        The table; its ``file`` column holds paths relative to the table's folder.

    Returns
    -------
    pandas.DataFrame
        One row per motion file: every original column as a string (empty cells as ``""``; CMU subject and
        trial keep their leading zeros, e.g. ``"02"``) except ``frames``, ``fps`` and ``take``, which are
        ints where present; plus ``path``, the absolute path of the file as a string.

    Raises
    ------
    ValueError
        The table has no ``file`` column or a non-integer frames/fps/take cell.
    """
    path = Path(path).resolve()
    table = pd.read_csv(path, sep="\t", dtype=str, keep_default_na=False, quoting=csv.QUOTE_NONE)
    if "file" not in table.columns:
        raise LabelTableError(f"{path}: no 'file' column (columns: {', '.join(table.columns)})")
    for column in INT_COLUMNS:
        if column in table.columns:
            table[column] = _int_column(path, table[column])
    table["path"] = [str((path.parent / name).resolve()) for name in table["file"]]
    return table


def bandai_labels(bvh_path) -> dict:
    """Content and style of a Bandai Namco BVH file, from its sibling ``.json``.

    Parameters
    ----------
    bvh_path : str or os.PathLike
        ``<root>/data/NAME.bvh``; the label names are read from ``<root>/cfg/content_label.txt`` and
        ``<root>/cfg/style_label.txt`` (their ``dataset-N_`` prefix is dropped).

    Returns
    -------
    dict
        ``{"content": "bow", "style": "active"}``, or ``{}`` when there is no ``NAME.json``.

    Raises
    ------
    ValueError
        The json is malformed, lacks a key, or holds an index outside its label list; or a label list is missing.
    """
    bvh = Path(bvh_path).resolve()
    meta = bvh.with_suffix(".json")
    if not meta.is_file():
        return {}
    try:
        indices = json.loads(meta.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise LabelTableError(f"{meta}: malformed label json ({exc})") from None
    if not isinstance(indices, dict):
        raise LabelTableError(f"{meta}: label json is not an object")
    cfg = bvh.parent.parent / "cfg"
    return {key: _bandai_name(meta, indices, key, cfg / f"{key}_label.txt") for key in ("content", "style")}


def labels_for(path) -> dict:
    """The labels of one motion file, found automatically.

    Tried in order: a Bandai Namco ``.json`` beside a ``.bvh`` (:func:`bandai_labels`); then the ``labels.tsv``
    tables in the file's folder and up to 4 levels of its ancestors, nearest first, until one has a row whose
    ``file`` resolves to this path. Parsed tables are cached per path and modification time.

    Parameters
    ----------
    path : str or os.PathLike
        A motion file.

    Returns
    -------
    dict
        The row's columns except ``file``/``path`` (frames, fps, take as ints), plus ``label``, the main class:
        HDM05 ``class``, CMU ``description``, Bandai ``content`` (None for a table with none of them).
        ``{}`` when no labels are found.
    """
    path = Path(path).resolve()
    if path.suffix.lower() == ".bvh":
        labels = bandai_labels(path)
        if labels:
            return {**labels, "label": labels["content"]}
    for folder in [path.parent, *path.parent.parents][: SEARCH_LEVELS + 1]:
        table = folder / TABLE_NAME
        if table.is_file():
            row = _table_rows(str(table), table.stat().st_mtime_ns).get(str(path))
            if row is not None:
                return {**row, "label": next((row[c] for c in MAIN_LABEL_COLUMNS if c in row), None)}
    return {}


def _int_column(path: Path, column: pd.Series) -> pd.Series:
    """``column`` as int64, or a ValueError naming the table, column and offending cell."""
    try:
        return column.astype("int64")
    except ValueError:
        bad = next(value for value in column if not value.strip().lstrip("+-").isdigit())
        raise LabelTableError(f"{path}: column {column.name!r} holds a non-integer value {bad!r}") from None


@functools.lru_cache(maxsize=64)
def _table_rows(table: str, mtime_ns: int) -> dict[str, dict]:
    """Rows of a ``labels.tsv`` keyed by absolute file path, without ``file``/``path`` (cached per mtime)."""
    frame = read_labels_tsv(table)
    rows = frame.drop(columns=["file", "path"]).to_dict("records")
    return dict(zip(frame["path"], rows, strict=True))


def _bandai_name(meta: Path, indices: dict, key: str, names_file: Path) -> str:
    """The label name that ``indices[key]`` points to in ``names_file``."""
    if not names_file.is_file():
        raise LabelTableError(f"{meta}: label names {names_file} not found")
    names = _label_names(str(names_file), names_file.stat().st_mtime_ns)
    index = indices.get(key)
    if isinstance(index, bool) or not isinstance(index, int):
        raise LabelTableError(f"{meta}: {key!r} must be an integer index, got {index!r}")
    if not 0 <= index < len(names):
        raise LabelTableError(f"{meta}: {key} index {index} outside 0..{len(names) - 1} of {names_file}")
    return names[index]


@functools.lru_cache(maxsize=16)
def _label_names(names_file: str, mtime_ns: int) -> tuple[str, ...]:
    """Lines of a Bandai Namco label list, without the ``dataset-N_`` prefix (cached per mtime)."""
    lines = Path(names_file).read_text(encoding="utf-8").splitlines()
    return tuple(_BANDAI_PREFIX.sub("", line.strip()) for line in lines)
