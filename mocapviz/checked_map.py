"""Memory-mapped arrays whose contents are verified when they are first read in a process, block by block.

BLOCK_BYTES    the block a checksum covers: 16 MiB of the file (its ``.npy`` header included in the first).
verified_blocks  check blocks of a file against their recorded hashes, each block once per process.
open_checked   a stored ``.npy`` file as a :class:`CheckedMap`: opened at once (nothing read), verified as touched.
CheckedMap     the read-only memory map that verifies the blocks under the rows an index reads before returning them
               (a plain ndarray); any other use of the whole array (a ufunc, a NumPy function, ``reshape``, ``copy``)
               verifies every block first.

Why blocks: a same-size edit or flipped bytes in a frame array must never become an answer, yet opening a
10M-frame database (6.7 GB of arrays) must stay instant and a search that reads one document must not read them
all. xxh3 (``xxhash``) hashes many GB/s, so verifying a block costs about as much as reading it from the page cache;
sha256 of whole files stays for ``mocapviz check``. A mismatch is a :class:`~mocapviz.errors.MotionDBError` naming
the file and the block's byte range.

The record of verified blocks is per process and per file (path, inode, size, modification time), shared by every
array opened on that file; a file replaced under the same name is verified again.
"""

from __future__ import annotations

import contextlib
import os
import threading

import numpy as np
import xxhash

from .errors import MotionDBError

__all__ = ["BLOCK_BYTES", "CheckedMap", "open_checked", "verified_blocks"]

BLOCK_BYTES = 1 << 24
_LOCK = threading.Lock()
_VERIFIED: dict[tuple, np.ndarray] = {}
_INDEXING = threading.local()  # .on while CheckedMap.__getitem__ makes its view (not a whole-array use)  # file identity -> bool per block, True once verified in this process


def verified_blocks(path: str | os.PathLike, expected: dict | None, blocks=None, rebuild: str = "",
                    mapped=None) -> None:
    """Check ``blocks`` of a file (all when None) against the xxh3 hashes recorded when it was written; each block
    is read and hashed once per process, later calls return at once.

    Parameters
    ----------
    path : str or os.PathLike
        The stored file.
    expected : dict or None
        Its fingerprint (:func:`mocapviz.store.fingerprint`): ``size``, ``block`` (bytes per block) and ``xxh3``
        (the hashes). None, or one without ``xxh3`` (a file written before blocks were hashed): nothing to check.
    blocks : array_like of int, optional
        The blocks to check (block i covers bytes ``i * block : (i + 1) * block``).
    rebuild : str
        How to write the file again, for the message.
    mapped : np.memmap, optional
        A memory map of the whole file (opened by :func:`open_checked`): its bytes are hashed, so that a map whose
        file has since been deleted (an older generation, :mod:`mocapviz.db.database`) is still checked.

    Raises
    ------
    MotionDBError
        A block differs ("… bytes A–B (block i of n) differ from what was written: the file is damaged; REBUILD"),
        or the file cannot be read.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from mocapviz.store import fingerprint
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     f = Path(folder) / "a.bin"
    ...     _ = f.write_bytes(bytes(40))
    ...     fp = fingerprint(f)
    ...     _ = f.write_bytes(bytes(39) + b"x")  # same size, one byte changed
    ...     verified_blocks(f, fp)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    mocapviz.errors.MotionDBError: .../a.bin: bytes 0–40 (block 1 of 1) differ from what was written: the file is damaged
    """
    if not expected or "xxh3" not in expected:
        return
    hashes, size = expected["xxh3"], int(expected["block"])
    hint = f"; {rebuild}" if rebuild else ""
    try:
        state = _state(path if mapped is None else mapped, len(hashes))
        todo = np.arange(len(hashes)) if blocks is None else np.unique(np.asarray(blocks, dtype=np.int64))
        todo = todo[(todo >= 0) & (todo < len(hashes))]
        todo = todo[~state[todo]]
        if not len(todo):
            return
        with contextlib.ExitStack() as stack:
            if mapped is None:
                fh = stack.enter_context(open(path, "rb"))
            else:
                whole = memoryview(mapped._mmap)
            for i in todo.tolist():
                if mapped is None:
                    fh.seek(i * size)
                    data = fh.read(size)
                else:
                    data = whole[i * size : (i + 1) * size]
                if xxhash.xxh3_64_hexdigest(data) != hashes[i]:
                    raise MotionDBError(f"{path}: bytes {i * size:,}–{min((i + 1) * size, expected['size']):,} (block "
                                        f"{i + 1} of {len(hashes)}) differ from what was written: the file is "
                                        f"damaged{hint}")  # fmt: skip
                state[i] = True
    except OSError as exc:
        raise MotionDBError(f"{path}: cannot read ({exc.strerror}){hint}") from None


def _state(source, n_blocks: int) -> np.ndarray:
    """The per-process record of verified blocks of a file (a path) or of the file a memory map was opened on."""
    key = getattr(source, "_checked_identity", None)
    if key is None:
        st = os.stat(source)
        key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
    with _LOCK:
        return _VERIFIED.setdefault(key, np.zeros(n_blocks, dtype=bool))


def open_checked(path: str | os.PathLike, expected: dict | None, rebuild: str = "") -> CheckedMap | np.ndarray:
    """A stored ``.npy`` file memory-mapped read-only, its blocks verified when first read (:class:`CheckedMap`).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    expected : dict or None
        Its fingerprint with block hashes (:func:`mocapviz.store.fingerprint`); without them (an older file) the
        plain memory map is returned.
    rebuild : str
        How to write the file again, for the messages.

    Returns
    -------
    CheckedMap or np.memmap
        Nothing has been read but the header.

    Raises
    ------
    OSError, ValueError
        The file is not a readable ``.npy`` file (the caller names it).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from mocapviz.store import fingerprint
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     f = Path(folder) / "a.npy"
    ...     np.save(f, np.arange(12.0).reshape(4, 3))
    ...     arr = open_checked(f, fingerprint(f))
    ...     print(type(arr).__name__, type(arr[1:3]).__name__, arr[1:3].sum())
    CheckedMap ndarray 33.0
    """
    st = os.stat(path)
    arr = np.load(path, mmap_mode="r", allow_pickle=False)
    if not expected or "xxh3" not in expected or not arr.size or arr._mmap is None:
        return arr
    arr._checked_identity = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
    out = arr.view(CheckedMap)
    out._checked = (os.fspath(path), expected, arr.offset, arr.strides[0] if arr.ndim else arr.nbytes, rebuild, arr)
    return out


class CheckedMap(np.ndarray):
    """A read-only memory map of a stored array whose blocks are verified (:func:`verified_blocks`) before any of
    their rows is returned. Indexing returns plain ndarrays (views of the map); whole-array operations (ufuncs,
    NumPy functions, ``reshape``, ``copy``, pickling) verify every block first. Made by :func:`open_checked`.

    ``np.asarray(m)`` and compiled code given ``m`` itself read the bytes unverified: pass ``m[:]`` (verifies every
    block) or index the rows needed.
    """

    _checked = None

    def __array_finalize__(self, obj):
        # a view or copy made other than by __getitem__ (reshape, transpose, copy, astype, ...): verify it all
        if getattr(obj, "_checked", None) is not None and not getattr(_INDEXING, "on", False):
            obj._verify(None)

    def _verify(self, key) -> None:
        """Verify the blocks under the first-axis rows ``self[key]`` reads (every block for ``None``, ``...``, a
        whole-array use)."""
        path, expected, offset, row_bytes, rebuild, mapped = self._checked
        n, block = self.shape[0], int(expected["block"])
        first = key[0] if isinstance(key, tuple) and key else key
        if isinstance(first, (int, np.integer)):
            rows = range(int(first) % n, int(first) % n + 1) if -n <= first < n else range(0)
            first = slice(rows.start, rows.stop)
        if isinstance(first, slice):
            rows = range(*first.indices(n))
            if not len(rows):
                return
            lo, hi = min(rows[0], rows[-1]), max(rows[0], rows[-1]) + 1  # (every block between: a strided read)
            blocks = np.arange((offset + lo * row_bytes) // block, (offset + hi * row_bytes - 1) // block + 1)
        elif first is None or first is Ellipsis or (isinstance(key, tuple) and not key):
            blocks = None
        else:
            rows = np.asarray(first)
            rows = np.flatnonzero(rows) if rows.dtype == bool else rows.astype(np.int64, copy=False).ravel() % n
            starts = offset + rows * row_bytes
            blocks = np.concatenate([starts // block, (starts + row_bytes - 1) // block])
        verified_blocks(path, expected, blocks, rebuild, mapped)

    def __getitem__(self, key):
        if self._checked is None:
            return super().__getitem__(key)
        self._verify(key)
        _INDEXING.on = True
        try:
            out = super().__getitem__(key)
        finally:
            _INDEXING.on = False
        return out.view(np.ndarray) if isinstance(out, np.ndarray) else out

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        inputs = tuple(_plain(x) for x in inputs)
        if "out" in kwargs:
            kwargs["out"] = tuple(_plain(x) for x in kwargs["out"])
        return getattr(ufunc, method)(*inputs, **kwargs)

    def __array_function__(self, func, types, args, kwargs):
        return func(*_plain_all(args), **{k: _plain_all([v])[0] for k, v in kwargs.items()})

    def __reduce__(self):  # pickled (to a worker): the verified values, not the map
        return _plain(self).copy().__reduce__()

    def __repr__(self) -> str:
        return f"CheckedMap({self._checked[0] if self._checked else ''!r}, shape={self.shape}, dtype={self.dtype})"


def _plain(x):
    """``x`` as a plain ndarray (every block verified) when it is a CheckedMap, else ``x``."""
    if isinstance(x, CheckedMap):
        if x._checked is not None:
            x._verify(None)
        return x.view(np.ndarray)
    return x


def _plain_all(values):
    return [[_plain(v) for v in x] if isinstance(x, (list, tuple)) else _plain(x) for x in values]
