"""Marker mapping files: a lab's C3D marker labels renamed onto the names of a marker set.

read_marker_mapping   a mapping file -> {label: marker name}.
relabel               marker names renamed by a mapping (what :func:`mocapviz.io.c3d.read_c3d` does with its
                      ``marker_mapping``).

A *mapping file* is a small CSV text file (UTF-8), one marker a line: the label as the C3D file has it (after the
subject prefix is cut: ``Daphnee:ASISr`` is ``ASISr``), a comma, and the name the marker has in a set that
:mod:`mocapviz.motion.markers` recognises (Plug-in Gait's ``RASI``, the CMU/HDM05 set's ``RFWT``)::

    # BTS / Davis protocol labels -> Plug-in Gait
    label,marker
    sacrum,SACR
    r asis,RASI
    r bar 1,RTHI

Lines whose first character (after spaces) is ``#`` and blank lines are skipped; a first line ``label,marker`` is
a header. Spaces around each cell are dropped; a label holding a comma is quoted (``"a,b",LTOE``). One mapping file
serves a lab's files: a label it lists that a file lacks is ignored; a label the file has that it does not list
keeps its name.
"""
from __future__ import annotations

import csv
import io
import os

from ..errors import MocapFormatError, ParameterError

__all__ = ["read_marker_mapping", "relabel"]

_HEADER = ("label", "marker")


def read_marker_mapping(path) -> dict[str, str]:
    """Read a mapping file (module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The mapping file.

    Returns
    -------
    dict
        The file's label -> the marker name it stands for, in the file's order.

    Raises
    ------
    MocapFormatError
        Naming the file and line: unreadable, not UTF-8, a line without exactly two non-empty cells, a label listed
        twice, two labels mapped onto one name.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "lab.csv"
    >>> _ = f.write_text("# lab -> Plug-in Gait\\nlabel,marker\\nr asis, RASI\\n\\"l, asis\\",LASI\\n")
    >>> read_marker_mapping(f)
    {'r asis': 'RASI', 'l, asis': 'LASI'}
    """
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except OSError as exc:
        raise MocapFormatError(path, f"cannot read the mapping file ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise MocapFormatError(path, f"the mapping file is not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    mapping: dict[str, str] = {}
    by_name: dict[str, str] = {}
    first = True
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        cells = [c.strip() for c in next(csv.reader(io.StringIO(line), skipinitialspace=True))]
        header, first = first and tuple(c.lower() for c in cells) == _HEADER, False
        if header:
            continue
        if len(cells) != 2 or not all(cells):
            raise MocapFormatError(path, f"expected 'label,marker' (two non-empty cells), got {line.strip()!r}", number)
        label, name = cells
        if label in mapping:
            raise MocapFormatError(path, f"label {label!r} listed twice ({mapping[label]!r} and {name!r})", number)
        if name in by_name:
            raise MocapFormatError(path, f"labels {by_name[name]!r} and {label!r} both mapped onto {name!r}", number)
        mapping[label], by_name[name] = name, label
    return mapping


def relabel(names, mapping: dict, source=None) -> tuple[str, ...]:
    """Marker names renamed by a mapping.

    Parameters
    ----------
    names : sequence of str
        A clip's marker names.
    mapping : dict
        Label -> marker name (:func:`read_marker_mapping`); labels the clip lacks are ignored.
    source : str, optional
        The clip's file, for the message.

    Returns
    -------
    tuple of str
        ``names``, each one the mapping lists replaced by its marker name.

    Raises
    ------
    ParameterError
        A marker name the mapping gives that another marker of the clip keeps (naming both).

    Examples
    --------
    >>> relabel(("r asis", "l asis", "C7"), {"r asis": "RASI", "l asis": "LASI", "sacrum": "SACR"})
    ('RASI', 'LASI', 'C7')
    """
    renamed = tuple(mapping.get(n, n) for n in names)
    seen: dict[str, str] = {}
    for old, new in zip(names, renamed):
        if new in seen:
            raise ParameterError(f"the marker mapping names two markers of {source or 'the clip'} {new!r}: "
                                 f"{seen[new]!r} and {old!r}")  # fmt: skip
        seen[new] = old
    return renamed
