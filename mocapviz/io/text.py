"""Reading mocap text files: bytes, decoding, words and numbers, and fast tokenising of the numeric body
(AMC frames, BVH MOTION lines).

read_bytes    a file's bytes (UTF-8 BOM removed), or a MocapFormatError for an unreadable, empty or binary file.
decode        bytes as UTF-8, else Latin-1 (which decodes any byte).
words         a line split at ASCII white space (space, tab, CR, LF, vertical tab, form feed), as C's isspace().
number        a token as a float when it is a plain decimal number (the syntax the scanner reads), else None.
scan          the numeric body of a file, checked, in one compiled pass.

Python's and numpy's text-to-float converters manage about 4 M numbers/s, which caps a BVH reader at about
30 k frames/s; this compiled scanner reads the whole body in one pass (about 15x faster) and records, per
line, where its numbers are and whether it starts with a name, so that the readers can check the layout of
every line with numpy and report the first bad line by number.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass

import numba
import numpy as np

from ..errors import MocapFormatError

# codes of the first error the kernel finds (it stops there)
_OK, _BAD_NUMBER, _TEXT_AFTER_NUMBER = 0, 1, 2

_SPACE = b" \t\r\n\v\f"  # ASCII white space: what C's isspace() and the scanner take as separators
_POW10 = np.array([10.0**k for k in range(23)])
_FNV_OFFSET = np.uint64(0xCBF29CE484222325)
_FNV_PRIME = np.uint64(0x100000001B3)


_WORD = re.compile(r"[^ \t\r\n\v\f]+")
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_BOMS = {b"\xff\xfe\x00\x00": "UTF-32", b"\x00\x00\xfe\xff": "UTF-32", b"\xff\xfe": "UTF-16", b"\xfe\xff": "UTF-16"}


def read_bytes(path) -> bytes:
    """The bytes of a motion file, without a leading UTF-8 byte-order mark.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    bytes
        Its content.

    Raises
    ------
    MocapFormatError
        The file cannot be read, is empty (or white space only), is UTF-16/32 text, or holds NUL bytes (binary).
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise MocapFormatError(path, f"cannot read file ({exc.strerror or exc})") from None
    for bom, name in _BOMS.items():
        if raw.startswith(bom):
            raise MocapFormatError(path, f"{name} text is not supported; save the file as UTF-8 or ASCII", 1)
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    if not raw.strip():
        raise MocapFormatError(path, "file is empty")
    nul = raw.find(b"\x00")
    if nul >= 0:
        raise MocapFormatError(path, "binary data (a NUL byte), not a text file", raw.count(b"\n", 0, nul) + 1)
    return raw


def decode(raw: bytes) -> str:
    """``raw`` decoded as UTF-8, or as Latin-1 where it is not valid UTF-8 (every byte is a Latin-1 character).

    Parameters
    ----------
    raw : bytes
        A file's bytes (:func:`read_bytes`).

    Returns
    -------
    str

    Examples
    --------
    >>> decode("café".encode("utf-8")), decode(b"caf\\xe9")  # UTF-8, else Latin-1
    ('café', 'café')
    """
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def words(line: str) -> list[str]:
    """``line`` split at runs of ASCII white space (not at the other characters ``str.split()`` takes, such as
    U+00A0, so that a header is split as the numeric scanner splits the body).

    Parameters
    ----------
    line : str
        One line of a file.

    Returns
    -------
    list of str
        Its words.

    Examples
    --------
    >>> words("ROOT\\tHips \\x0b x"), words("a\\u00a0b")
    (['ROOT', 'Hips', 'x'], ['a\\xa0b'])
    """
    return _WORD.findall(line)


def number(token: str) -> float | None:
    """``token`` as a float when it is a decimal number as the scanner reads them (``12``, ``-.5``, ``1e-3``),
    else None: no ``nan``, ``inf``, ``1_000``, hexadecimal or non-ASCII digits. May be infinite (``1e999``).

    Parameters
    ----------
    token : str
        One word of a file.

    Returns
    -------
    float or None

    Examples
    --------
    >>> number("-.5"), number("1e-3"), number("nan"), number("1_000")
    (-0.5, 0.001, None, None)
    """
    return float(token) if _NUMBER.fullmatch(token) else None


def name_hash(name: str) -> np.uint64:
    """64-bit FNV-1a hash of a name's Latin-1 bytes, as the scanner computes it for leading names.

    Parameters
    ----------
    name : str
        A name (Latin-1 characters only).

    Returns
    -------
    np.uint64
    """
    h = int(_FNV_OFFSET)
    for b in name.encode("latin-1"):
        h = ((h ^ b) * int(_FNV_PRIME)) & 0xFFFFFFFFFFFFFFFF
    return np.uint64(h)


@numba.njit(cache=True, nogil=True)
def _is_space(c):  # pragma: no cover - numba
    return c == 32 or c == 9 or c == 13 or c == 10 or c == 11 or c == 12


@numba.njit(cache=True, nogil=True)
def _scan_kernel(buf, offset, pow10, values, first_value, n_values, name_start, name_hash, error):  # pragma: no cover
    # error = [code, line, byte offset] of the first bad token; the scan stops there
    n = buf.shape[0]
    i = offset
    line = 0
    nv = 0
    first_value[0] = 0
    at_line_start = True
    while i < n:
        c = buf[i]
        if c == 10:  # newline closes the line
            n_values[line] = nv - first_value[line]
            line += 1
            first_value[line] = nv
            at_line_start = True
            i += 1
            continue
        if _is_space(c):
            i += 1
            continue
        start = i
        if c == 35 and at_line_start:  # '#': comment to end of line
            while i < n and buf[i] != 10:
                i += 1
            continue
        is_num_start = (48 <= c <= 57) or c == 43 or c == 45 or c == 46
        if not is_num_start:
            h = _FNV_OFFSET
            while i < n and not _is_space(buf[i]):
                h = (h ^ np.uint64(buf[i])) * _FNV_PRIME
                i += 1
            if at_line_start:
                name_start[line] = start
                name_hash[line] = h
            else:
                error[0], error[1], error[2] = _TEXT_AFTER_NUMBER, line, start
                return nv, line + 1
            at_line_start = False
            continue
        at_line_start = False
        neg = False
        if c == 43 or c == 45:
            neg = c == 45
            i += 1
        mant = 0
        exp10 = 0
        digits = 0
        while i < n and 48 <= buf[i] <= 57:
            if mant < 100000000000000000:
                mant = mant * 10 + (buf[i] - 48)
            else:
                exp10 += 1
            digits += 1
            i += 1
        if i < n and buf[i] == 46:
            i += 1
            while i < n and 48 <= buf[i] <= 57:
                if mant < 100000000000000000:
                    mant = mant * 10 + (buf[i] - 48)
                    exp10 -= 1
                digits += 1
                i += 1
        ok = digits > 0
        if ok and i < n and (buf[i] == 101 or buf[i] == 69):
            i += 1
            eneg = False
            if i < n and (buf[i] == 43 or buf[i] == 45):
                eneg = buf[i] == 45
                i += 1
            e = 0
            edigits = 0
            while i < n and 48 <= buf[i] <= 57:
                if e < 100000:
                    e = e * 10 + (buf[i] - 48)
                edigits += 1
                i += 1
            ok = edigits > 0
            exp10 += -e if eneg else e
        if not ok or (i < n and not _is_space(buf[i])):
            error[0], error[1], error[2] = _BAD_NUMBER, line, start
            return nv, line + 1
        # one correctly rounded operation on exact doubles gives the same double as Python's float()
        if mant > 9007199254740992 or exp10 > 22 or exp10 < -22:
            v = np.nan  # not exact here (rare: 1.5e-18 and such): scan() converts it with float()
        elif exp10 == 0:
            v = float(mant)
        elif exp10 > 0:
            v = mant * pow10[exp10]
        else:
            v = mant / pow10[-exp10]
        values[nv] = -v if neg else v
        nv += 1
    n_values[line] = nv - first_value[line]
    return nv, line + 1


@numba.njit(cache=True, nogil=True)
def _line_starts(buf, offset, lines):  # pragma: no cover - numba
    # the byte offset of each of ``lines`` (ascending; 0 is the line that starts at ``offset``), in one walk that
    # stops at the last of them (no table of every line's start: 8 bytes a line)
    out = np.empty(lines.shape[0], dtype=np.int64)
    line = 0
    i = offset
    for k in range(lines.shape[0]):
        while line < lines[k]:
            while buf[i] != 10:
                i += 1
            i += 1
            line += 1
        out[k] = i
    return out


@dataclass
class Scan:
    """Numbers and per-line layout of a block of text (what :func:`scan` returns); the fields are its attributes.

    Parameters
    ----------
    data : np.ndarray [shape=(B,)], uint8
        The block's bytes.
    values : np.ndarray [shape=(V,)], float64
        Every number, in order.
    first_value, n_values : np.ndarray [shape=(L,)], int32 (int64 for files of 2 GB or more)
        Where each line's numbers are in ``values``.
    name_start : np.ndarray [shape=(L,)], int32 or int64
        Byte offset of a leading name token (-1 if none).
    name_hash : np.ndarray [shape=(L,)], uint64
        :func:`name_hash` of that name (0 if none).
    first_line : int
        1-based number in the file of the block's first line.
    """

    data: np.ndarray
    values: np.ndarray
    first_value: np.ndarray
    n_values: np.ndarray
    name_start: np.ndarray
    name_hash: np.ndarray
    first_line: int

    @property
    def n_lines(self) -> int:
        return self.n_values.shape[0]

    def token(self, line: int) -> str:
        """The leading name of a line of the block.

        Parameters
        ----------
        line : int
            0-based line of the block.

        Returns
        -------
        str
            The name (Latin-1), or '' if the line has none.
        """
        s = e = self.name_start[line]
        if s < 0:
            return ""
        while e < self.data.shape[0] and self.data[e] not in _SPACE:
            e += 1
        return bytes(self.data[s:e]).decode("latin-1")


def scan(data: bytes, path, first_line: int = 1, start: int = 0) -> Scan:
    """Tokenise ``data[start:]`` (the numeric body of a file) and check every number.

    Parameters
    ----------
    data : bytes
        Text, lines separated by ``\\n`` (``\\r``, ``\\t``, ``\\v`` and ``\\f`` are white space).
    path : str
        File name, for error messages.
    first_line : int
        1-based line number in the file of the line that starts at ``data[start]``.
    start : int
        Byte offset where the body starts (``data`` is not copied).

    Returns
    -------
    Scan
        Byte offsets in it (``name_start``) count from the start of ``data``.

    Raises
    ------
    MocapFormatError
        At the first line holding a malformed or non-finite number, or text after a number.
    """
    buf = np.frombuffer(data, dtype=np.uint8)
    n_lines = data.count(b"\n", start) + 1
    # at most one number per two bytes; pages never written to are never resident
    values = np.empty((buf.shape[0] - start) // 2 + 1)
    index = np.int32 if buf.shape[0] < 2**31 - 1 else np.int64  # (offsets and counts fit: 12 bytes a line less)
    first_value = np.zeros(n_lines + 1, dtype=index)
    n_values = np.zeros(n_lines, dtype=index)
    name_start = np.full(n_lines, -1, dtype=index)
    name_hash = np.zeros(n_lines, dtype=np.uint64)
    error = np.zeros(3, dtype=np.int64)
    nv, nl = _scan_kernel(buf, start, _POW10, values, first_value, n_values, name_start, name_hash, error)
    if error[0]:
        s = e = int(error[2])
        while e < buf.shape[0] and buf[e] not in _SPACE:
            e += 1
        tok = bytes(buf[s:e]).decode("latin-1")
        if tok.lstrip("+-").lower() in ("nan", "inf", "infinity"):
            reason = f"non-finite value {tok!r}"
        elif error[0] == _BAD_NUMBER:
            reason = f"malformed number {tok!r}"
        else:
            reason = f"unexpected text {tok!r} after a number"
        raise MocapFormatError(path, reason, line=first_line + int(error[1]))
    slow = np.flatnonzero(np.isnan(values[:nv]))
    if slow.size:
        lines = np.searchsorted(first_value[:nl], slow, side="right") - 1
        for k, line, at in zip(slow, lines, _line_starts(buf, start, lines)):
            end = data.find(b"\n", at)
            tokens = data[at : len(data) if end < 0 else end].split()
            values[k] = float(tokens[k - first_value[line] + (name_start[line] >= 0)])
    result = Scan(
        data=buf,
        values=values[:nv],
        first_value=first_value[:nl],
        n_values=n_values[:nl],
        name_start=name_start[:nl],
        name_hash=name_hash[:nl],
        first_line=first_line,
    )
    check_finite(result.values, result, path)  # numbers too large for a double, e.g. 1e999
    return result


def check_finite(values: np.ndarray, scan_: Scan, path) -> None:
    """Raise MocapFormatError at the line of the first non-finite (overflowing) value, if any.

    Parameters
    ----------
    values : np.ndarray [shape=(V,)]
        Numbers of the block (``scan_.values`` or a part of them from the start).
    scan_ : Scan
        The block they were read from (for the line).
    path : str or os.PathLike
        The file, for the message.

    Raises
    ------
    MocapFormatError
        A value is not finite (e.g. ``1e999``); the message names the file and line.
    """
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        line = int(np.searchsorted(scan_.first_value, bad[0], side="right") - 1)
        raise MocapFormatError(path, "number out of range (not finite)", line=scan_.first_line + line)
