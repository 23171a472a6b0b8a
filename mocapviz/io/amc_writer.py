"""Writing AMC: a stretch of an AMC file, its frame blocks copied.

cut_amc     frames ``start:end`` of an AMC file: its header, ``# ...`` comment lines, then those frames' blocks as
            they are, their frame numbers counted again from 1.
"""
from __future__ import annotations

import re

from ..errors import MocapFormatError
from .asfamc import _header_end

_FRAME_NUMBER = re.compile(rb"[ \t]*[0-9]+[ \t\r]*")


def cut_amc(raw: bytes, start: int, end: int, comments=(), path=None) -> bytes:
    """Frames ``start:end`` of an AMC file.

    The header (every line before the first frame: ``#`` comments, ``:FULLY-SPECIFIED``, ``:DEGREES``) is kept as
    it is, followed by ``comments`` as ``# ...`` lines; then the blocks of frames ``start:end`` (the frame number line
    and its bone lines), each bone line byte for byte, the frame numbers renumbered ``1, 2, ...`` (the AMC readers
    expect consecutive numbers; the comments say which frames of the source they were).

    Parameters
    ----------
    raw : bytes
        The AMC file.
    start, end : int
        Frames, counted from 0 (the file's first frame block), half-open.
    comments : sequence of str
        Lines written as ``# ...`` at the end of the header.
    path : str, optional
        The file, for error messages.

    Returns
    -------
    bytes
        The cut file, with the line ends of the source.

    Raises
    ------
    MocapFormatError
        No frames, or fewer frame blocks than ``end``.

    Examples
    --------
    >>> amc = b":DEGREES\\n1\\nroot 0 0 0 0 0 0\\n2\\nroot 1 0 0 0 0 0\\n3\\nroot 2 0 0 0 0 0\\n"
    >>> print(cut_amc(amc, 1, 3, ["frames 1:3 of x.amc"]).decode())
    :DEGREES
    # frames 1:3 of x.amc
    1
    root 1 0 0 0 0 0
    2
    root 2 0 0 0 0 0
    <BLANKLINE>
    """
    header_end, _, _ = _header_end(raw, path)
    newline = b"\r\n" if b"\r\n" in raw[:header_end + 4096] else b"\n"
    lines = raw[header_end:].split(b"\n")
    marks = [i for i, line in enumerate(lines) if _FRAME_NUMBER.fullmatch(line)]
    if not 0 <= start < end <= len(marks):
        raise MocapFormatError(path, f"frames {start}:{end} are not inside its {len(marks)} frames")
    marks.append(len(lines))
    out = [raw[:header_end]]
    out += [b"# " + " ".join(str(c).split()).encode("utf-8") + newline for c in comments or ()]
    for k in range(start, end):
        block = [line.rstrip(b"\r") for line in lines[marks[k] + 1 : marks[k + 1]]]
        while block and not block[-1].strip():  # blank lines at the end of the file
            block.pop()
        out.append(newline.join([str(k - start + 1).encode(), *block]) + newline)
    return b"".join(out)
