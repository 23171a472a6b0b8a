"""Every hit of a search as files: one export per row of a hit table, in a folder or in a zip archive.

read_hits     a hit table (DataFrame, or the CSV a search's ``--csv`` wrote) checked against the database.
hit_files     {file name: bytes} of every hit, names sorted by rank, one name per hit (rank, document, frames).
export_hits   those files written into a folder, hit by hit, all or nothing; returns the paths.
hits_zip      those files as the bytes of one zip archive (for a download button; nothing written to disk).
zipped        {file name: bytes} as the bytes of one zip archive.
"""
from __future__ import annotations

import io
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pandas as pd

from ..db.hits import COLUMNS, hit_table
from ..errors import ParameterError
from ..validation import integer_columns
from .joint_arrays import MANIFEST, merged_manifest
from .stretch import stretch_files, write_files

_HINT = ("pass the hit table a search returns, or the CSV that `mocapviz search|query|find|match|knn ... --csv FILE` "
         "writes (columns rank, doc_id, name, start, end, ...: frames within the document, half-open)")
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)  # every member's date in a zip archive: the earliest a zip file can hold


def read_hits(db, hits, what: str = "hits") -> pd.DataFrame:
    """A hit table checked against ``db``: its ``doc_id``, ``start`` and ``end`` columns whole numbers, each row a
    stretch of one of its documents.

    Parameters
    ----------
    db : MotionDB
        The database the hits were found in.
    hits : pandas.DataFrame or str or os.PathLike
        A hit table (:func:`mocapviz.db.hits.hit_table`) or the CSV file of one.
    what : str
        The table, for messages (e.g. ``"--hits hits.csv"``).

    Returns
    -------
    pandas.DataFrame
        The rows in order, ``rank`` (1, 2, ... when the table has none), ``doc_id``, ``start``, ``end`` as integers and
        the table's other columns.

    Raises
    ------
    ParameterError
        An unreadable file, a missing column, a value that is not a whole number, an unknown document or frames
        outside it (the row named, and what to pass).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> read_hits(db, pd.DataFrame({"doc_id": [7], "start": [0], "end": [60]}))[["rank", "doc_id", "end"]].values
    array([[ 1,  7, 60]])
    """
    if not isinstance(hits, pd.DataFrame):
        what = f"{what} {hits}" if what == "hits" else what
        try:
            hits = pd.read_csv(hits)
        except (OSError, ValueError) as exc:
            raise ParameterError(f"{what}: cannot read it as CSV ({getattr(exc, 'strerror', None) or exc}); "
                                 f"{_HINT}") from None
    cols = integer_columns(hits, ["doc_id", "start", "end"], what, _HINT)
    if hits.empty:
        raise ParameterError(f"{what} has no rows: nothing to export")
    try:
        hit_table(db, cols["doc_id"], cols["start"], cols["end"])  # the one check of ids and spans
    except ParameterError as exc:
        raise ParameterError(f"{what}: {exc}") from None
    ranks = integer_columns(hits, ["rank"], what, _HINT)["rank"] if "rank" in hits else range(1, len(hits) + 1)
    return hits.assign(rank=ranks, **cols).reset_index(drop=True)


def hit_files(db, hits, format: str = "bvh", rig: str | None = None, search: str | None = None) -> dict[str, bytes]:
    """The export of every hit (:func:`mocapviz.export.stretch.stretch_files`), file names starting with the rank.

    Parameters
    ----------
    db : MotionDB
        The database.
    hits : pandas.DataFrame or str or os.PathLike
        A hit table or its CSV file (:func:`read_hits`).
    format : {"bvh", "amc", "glb", "humanml3d"}
        The file format.
    rig : {"source", "canonical"}, optional
        The rig (default: canonical for glb and humanml3d, source otherwise).
    search : str, optional
        What found the hits, written into every file (default: the CSV file's name, if one is given).

    Returns
    -------
    dict
        File name -> bytes, in the table's order; the search's own columns of each hit (cost, score, ...) are
        written into its files too. Each hit has its own files (:func:`mocapviz.export.stretch.file_stem`);
        ``humanml3d``: one ``.npy`` per hit, then one ``manifest.csv`` of every hit.

    Raises
    ------
    ParameterError
        As :func:`read_hits`, or two rows of one rank, document and frames (the rows named).
    """
    return {name: data for files in _each_hit(db, hits, format, rig, search) for name, data in files.items()}


def _each_hit(db, hits, format: str, rig: str | None, search: str | None) -> Iterator[dict[str, bytes]]:
    """The files of each row of ``hits`` (:func:`hit_files`), one row at a time, the table checked first."""
    if search is None and not isinstance(hits, pd.DataFrame):
        search = f"hits of {Path(hits).name}"
    table = read_hits(db, hits)
    _one_row_per_hit(table, "hits" if isinstance(hits, pd.DataFrame) else f"hits {hits}")
    own = [c for c in table.columns if c not in COLUMNS and c not in db.label_columns and c != "path"]
    digits = max(3, len(str(int(table["rank"].max()))))
    manifests = []  # humanml3d: each hit's row of the manifest, written once after every array
    for r in table.to_dict("records"):
        files = stretch_files(db, r["doc_id"], r["start"], r["end"], format, rig, rank=r["rank"], search=search,
                              scores={c: r[c] for c in own}, digits=digits)  # fmt: skip
        if MANIFEST in files:
            manifests.append(files.pop(MANIFEST))
        yield files
    if manifests:
        yield {MANIFEST: merged_manifest(manifests)}


def _one_row_per_hit(table: pd.DataFrame, what: str) -> None:
    """ParameterError naming the first two rows of one rank, document and frames: their files would have one name."""
    key = ["rank", "doc_id", "start", "end"]
    again = table.duplicated(key)
    if not again.any():
        return
    second = int(again.idxmax())
    r = table.loc[second]
    first = int((table[key] == r[key]).all(axis=1).idxmax())
    raise ParameterError(f"{what}: rows {first + 1} and {second + 1} are the same hit (rank {r['rank']}, document "
                         f"{r['doc_id']}, frames {r['start']}:{r['end']}), which would be one file; drop one, or give "
                         "them different ranks")  # fmt: skip


def export_hits(db, hits, out_dir, format: str = "bvh", rig: str | None = None, search: str | None = None
                ) -> list[Path]:
    """Every hit exported into ``out_dir``: one file per hit (an AMC with its ASF), all or nothing.

    Each hit's files are made and written in turn into a hidden folder, which is moved into place once every hit
    is there (:func:`mocapviz.export.stretch.write_files`): a failure at any hit (a source file gone, a full disk)
    leaves no file behind and ``out_dir`` as it was.

    Parameters
    ----------
    db : MotionDB
        The database.
    hits : pandas.DataFrame or str or os.PathLike
        A hit table or its CSV file.
    out_dir : str or os.PathLike
        The folder (created if missing; an existing one keeps its other files, those of the same names are
        replaced).
    format, rig, search
        As :func:`hit_files`.

    Returns
    -------
    list of pathlib.Path
        The files written, in the table's order: as many as its rows (an AMC: two per row; HumanML3D: one per row
        and the manifest last).

    Raises
    ------
    ParameterError
        As :func:`hit_files`; ``out_dir`` is a file.
    SourceFileError
        A hit's source file is gone or changed (``rig="source"``).
    OSError
        Writing failed.

    Examples
    --------
    >>> import tempfile
    >>> from mocapviz import MotionDB
    >>> from mocapviz.db.hits import hit_table
    >>> db = MotionDB.sample()
    >>> hits = hit_table(db, [11, 22], [0, 30], [60, 90], cost=[0.5, 0.7])
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     [p.name for p in export_hits(db, hits, folder, format="glb", search="squats")]
    ['001_doc11_HDM_dg_squat1Reps_033_120_0-60.glb', '002_doc22_HDM_mm_squat1Reps_037_120_30-90.glb']
    """
    return write_files(_each_hit(db, hits, format, rig, search), out_dir)


def hits_zip(db, hits, format: str = "bvh", rig: str | None = None, search: str | None = None) -> bytes:
    """Every hit exported into one zip archive, in memory (no file is written).

    For a download button: Panel's ``FileDownload(callback=lambda: io.BytesIO(hits_zip(db, hits, "glb")),
    filename="hits.zip")``.

    Parameters
    ----------
    db : MotionDB
        The database.
    hits : pandas.DataFrame or str or os.PathLike
        A hit table or its CSV file.
    format, rig, search
        As :func:`hit_files`.

    Returns
    -------
    bytes
        The zip archive (deflated), its members the files of :func:`hit_files` in rank order.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.db.hits import hit_table
    >>> db = MotionDB.sample()
    >>> data = hits_zip(db, hit_table(db, [7], [0], [60]), format="amc")
    >>> zipfile.ZipFile(io.BytesIO(data)).namelist()
    ['001_doc7_HDM_dg_kickLFront1Reps_017_120_0-60.amc', '001_doc7_HDM_dg_kickLFront1Reps_017_120_0-60.asf']
    """
    return zipped(hit_files(db, hits, format, rig, search))


def zipped(files: dict[str, bytes]) -> bytes:
    """Files as one zip archive (deflated), in memory, members in the order given, each dated 1980-01-01 with mode
    0644: the same files give the same bytes.

    Parameters
    ----------
    files : dict
        File name -> bytes (e.g. :func:`hit_files`).

    Returns
    -------
    bytes

    Examples
    --------
    >>> zipfile.ZipFile(io.BytesIO(zipped({"a.bvh": b"1", "b.bvh": b"2"}))).namelist()
    ['a.bvh', 'b.bvh']
    >>> zipped({"a.bvh": b"1"}) == zipped({"a.bvh": b"1"})  # whenever made
    True
    """
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, data in files.items():  # a fixed time and mode: the same files, the same bytes (a member named by
            member = zipfile.ZipInfo(name, date_time=_ZIP_TIME)  # its name alone would carry the time of writing)
            member.compress_type, member.external_attr = zipfile.ZIP_DEFLATED, 0o644 << 16
            archive.writestr(member, data)
    return out.getvalue()
