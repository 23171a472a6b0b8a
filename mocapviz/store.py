"""Everything mocapviz writes to disk goes through here, so that a reader never sees a half-written file.

atomic_write   bytes -> ``target``, atomically (see :func:`atomic_file`).
atomic_file    a unique temporary path beside a target to write to; fsync'ed and renamed onto the target when the
               block succeeds, removed when it fails (two writers never share a temporary file; a killed writer
               leaves the previous file intact, plus at most a ``.<name>.*.tmp`` that the next write ignores).
temporary_file the unique temporary path alone, and commit (fsync + rename), for a rename that must happen
commit         under a lock (numeric features swap data and header together).
temporary_folder  a new, empty folder with a unique name beside a target, removed when the block ends.
atomic_folder  the same for a folder (a reproduced experiment, an unpacked archive).
leftovers      the temporaries of a target that earlier (killed) writers left behind.
fsync_folder   a rename in a folder made durable.
locked         an advisory lock (``fcntl.flock`` on ``<folder>/.lock``): exclusive for writers of a MotionDB or of its
               derived data, shared for readers that must pair files written together.
stamp          the header fields every stored format carries (format, version, written_by).
check_format   the one format / version check of a stored header.
load_or_build  a derived artefact from disk when it is current, else built (and, by the builder, stored).
fingerprint    size, sha256 and per-block xxh3 of a stored file, kept in its manifest or header.
verify         a stored file against its fingerprint: the size always (fast), the sha256 on request.
digest         sha256 of named arrays (names, dtypes, shapes and bytes), for files that are read whole.

Temporary names are ``.<target name>.<8 random hex digits><suffix>``, the target's name shortened so that the
whole name fits the file system's limit (NAME_MAX, 255 bytes on ext4, XFS, Btrfs, tmpfs, APFS), measured in bytes
of the file-system encoding. Files and folders are created with the modes the user's umask gives (``0o666`` /
``0o777`` masked: 0644 / 0755 under umask 022), as ``open`` and ``mkdir`` would, never ``mkstemp``'s private 0600.

Formats stored: the MotionDB manifest (``mocapviz.MotionDB``), relational indexes (``mocapviz.InvertedIndex``),
numeric-feature headers (``mocapviz.numeric-features``) and PCA models (``mocapviz.PCAModel``).
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import secrets
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

from .errors import MotionDBError

T = TypeVar("T")
LOCK_FILE = ".lock"
NAME_MAX = 255  # bytes of a file name, where the file system does not say (os.pathconf)


def atomic_write(target: str | os.PathLike, data: bytes) -> None:
    """Replace ``target`` by ``data`` atomically (:func:`atomic_file`).

    Parameters
    ----------
    target : str or os.PathLike
        The file to write (created or replaced).
    data : bytes
        Its new content.

    Raises
    ------
    OSError
        The folder does not exist or is not writable (the temporary file is removed).
    """
    with atomic_file(target) as tmp:
        tmp.write_bytes(data)


@contextlib.contextmanager
def atomic_file(target: str | os.PathLike) -> Iterator[Path]:
    """A new, empty temporary file beside ``target`` for the block to write; when the block returns it is
    committed onto ``target`` (:func:`commit`), when the block raises it is removed and ``target`` is untouched.

    Parameters
    ----------
    target : str or os.PathLike
        The file to write (created or replaced); its folder must exist.

    Yields
    ------
    pathlib.Path
        The temporary file (write it by path: ``np.save``, ``to_parquet``, ``open_memmap``, ...).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     with atomic_file(Path(folder) / "table.csv") as tmp:
    ...         _ = tmp.write_text("a,b\\n1,2\\n")  # the target does not exist until the block returns
    ...     print(sorted(p.name for p in Path(folder).iterdir()))
    ['table.csv']
    """
    with temporary_file(target) as tmp:
        yield tmp
        commit(tmp, target)


@contextlib.contextmanager
def temporary_file(target: str | os.PathLike) -> Iterator[Path]:
    """A new, empty file beside ``target`` with a unique name (``.<target name>.<random>.tmp``, within NAME_MAX),
    mode ``0o666`` under the umask, removed when the block ends unless the block has committed it (:func:`commit`).
    For writers that must rename under a lock.

    Parameters
    ----------
    target : str or os.PathLike
        The file the temporary one will replace.

    Yields
    ------
    pathlib.Path
        The temporary file.
    """
    tmp = _created(Path(target), ".tmp", lambda p: os.close(os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)))
    try:
        yield tmp
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()


def commit(tmp: str | os.PathLike, target: str | os.PathLike) -> None:
    """Make the written file ``tmp`` durable (fsync) and rename it onto ``target`` (the folder entry fsync'ed).

    Parameters
    ----------
    tmp : str or os.PathLike
        The written temporary file (:func:`temporary_file`), in the folder of ``target``.
    target : str or os.PathLike
        The file it replaces.
    """
    with open(tmp, "rb+") as fh:
        os.fsync(fh.fileno())
    os.replace(tmp, target)
    fsync_folder(Path(target).parent)


@contextlib.contextmanager
def temporary_folder(target: str | os.PathLike, suffix: str = ".tmp") -> Iterator[Path]:
    """A new, empty folder beside ``target`` with a unique name (``.<target name>.<random><suffix>``, within
    NAME_MAX), mode ``0o777`` under the umask, removed with its content when the block ends unless the block has
    renamed it.

    Parameters
    ----------
    target : str or os.PathLike
        What the folder is for; its parent folder must exist.
    suffix : str
        The end of the name (:func:`leftovers` finds them by it).

    Yields
    ------
    pathlib.Path
        The folder.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     with temporary_folder(Path(folder) / ("x" * 300)) as tmp:
    ...         print(len(os.fsencode(tmp.name)) <= NAME_MAX, tmp.name.endswith(".tmp"))
    ...     print(os.listdir(folder))
    True True
    []
    """
    tmp = _created(Path(target), suffix, lambda p: os.mkdir(p, 0o777))
    try:
        yield tmp
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def leftovers(target: str | os.PathLike, suffix: str = ".tmp") -> list[Path]:
    """The temporaries of ``target`` with ``suffix`` that exist beside it now (:func:`temporary_file`,
    :func:`temporary_folder`): a running writer's, or what a killed writer left behind.

    Parameters
    ----------
    target : str or os.PathLike
        The file or folder they were made for.
    suffix : str
        Their suffix.

    Returns
    -------
    list of pathlib.Path
        Sorted.
    """
    target = Path(target)
    start = _temporary_prefix(target, suffix)
    try:
        names = os.listdir(target.parent)
    except OSError:
        return []
    return sorted(target.parent / n for n in names if n.startswith(start) and n.endswith(suffix)
                  and len(n) == len(start) + _RANDOM_DIGITS + len(suffix))


_RANDOM_DIGITS = 8


def _temporary_prefix(target: Path, suffix: str) -> str:
    """``.<target name>.``, the name cut (whole characters) so that the prefix, the random digits and ``suffix``
    fit the file system's NAME_MAX in bytes."""
    try:
        limit = os.pathconf(target.parent, "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = NAME_MAX
    room = min(limit, NAME_MAX) - len(os.fsencode(f"..{suffix}")) - _RANDOM_DIGITS
    name = target.name
    while len(os.fsencode(name)) > room:
        name = name[:-1]
    return f".{name}."


def _created(target: Path, suffix: str, create: Callable[[Path], object]) -> Path:
    """A path beside ``target`` named ``<_temporary_prefix><random><suffix>`` that ``create`` made (it must fail
    with FileExistsError when the path exists: ``O_EXCL``, ``mkdir``)."""
    prefix = _temporary_prefix(target, suffix)
    for _ in range(100):
        path = target.parent / f"{prefix}{secrets.token_hex(_RANDOM_DIGITS // 2)}{suffix}"
        try:
            create(path)
        except FileExistsError:
            continue
        return path
    raise FileExistsError(f"{target.parent}: no unused temporary name {prefix}*{suffix} in 100 tries")


@contextlib.contextmanager
def atomic_folder(target: str | os.PathLike, replace: bool = True) -> Iterator[Path]:
    """A new, empty temporary folder beside ``target`` (named and moded as :func:`temporary_folder`) for the block
    to fill; renamed to ``target`` when the block returns, removed when it raises.

    An existing ``target`` is replaced only once the new folder is complete (moved aside, then deleted). With
    ``replace=False`` a ``target`` that exists by then (another process finished first) is kept and the new
    folder discarded.

    Parameters
    ----------
    target : str or os.PathLike
        The folder to create or replace.
    replace : bool
        Replace an existing ``target`` (default), or keep it.

    Yields
    ------
    pathlib.Path
        The temporary folder to fill.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = _created(target, ".tmp", lambda p: os.mkdir(p, 0o777))
    old = None
    try:
        yield tmp
        if target.exists():
            if not replace:
                return
            old = _created(target, ".old", lambda p: os.mkdir(p, 0o700))
            os.replace(target, old / "previous")
        try:
            os.replace(tmp, target)
        except OSError:  # another process's folder took the name between the check and the rename
            if replace or not target.exists():
                raise
            return
        fsync_folder(target.parent)
    finally:
        for leftover in (tmp, old):
            if leftover is not None and leftover.exists():
                shutil.rmtree(leftover, ignore_errors=True)


@contextlib.contextmanager
def locked(folder: str | os.PathLike, shared: bool = False, wait: bool = True, what: str = "",
           name: str = LOCK_FILE) -> Iterator[None]:
    """Hold the advisory lock of ``folder`` (``flock`` on ``<folder>/.lock``) for the block.

    Parameters
    ----------
    folder : str or os.PathLike
        The folder the lock protects (a MotionDB, its ``features/`` or ``index/`` folder); must exist.
    shared : bool
        A reader's shared lock (many at once) instead of a writer's exclusive one.
    wait : bool
        Wait for another holder to finish (default), or fail at once.
    what : str
        What the folder is, for the error message (default: the folder's path).
    name : str
        The lock file's name in ``folder``: another than ``.lock`` for a lock of one file in a folder of other
        things (the users file of ``mocapviz serve --auth``: ``.<its name>.lock``).

    Yields
    ------
    None
        The lock is held while the block runs.

    Raises
    ------
    MotionDBError
        ``wait=False`` and another process holds the lock.
    """
    folder = Path(folder)
    with open(folder / name, "a") as fh:
        mode = fcntl.LOCK_SH if shared else fcntl.LOCK_EX
        try:
            fcntl.flock(fh, mode if wait else mode | fcntl.LOCK_NB)
        except BlockingIOError:
            raise MotionDBError(f"{what or folder}: another process is writing to it; try again when it has finished") from None
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def stamp(format_name: str, version: int) -> dict:
    """The header fields of a stored format: ``{"format", "version", "written_by": "mocapviz X.Y.Z"}``.

    Parameters
    ----------
    format_name : str
        E.g. ``"mocapviz.MotionDB"``.
    version : int
        The format's version.

    Returns
    -------
    dict

    Examples
    --------
    >>> sorted(stamp("mocapviz.MotionDB", 1))
    ['format', 'version', 'written_by']
    """
    from ._version import __version__

    return {"format": format_name, "version": int(version), "written_by": f"mocapviz {__version__}"}


def check_format(header, format_name: str, version: int, where: str | os.PathLike, rebuild: str = "") -> dict:
    """``header`` (a dict read from a stored file) when it is ``format_name`` at ``version``, else MotionDBError.

    Parameters
    ----------
    header : object
        The stored header (anything: a damaged file may hold a list or a string).
    format_name : str
        The format this mocapviz reads.
    version : int
        The version this mocapviz reads.
    where : str or os.PathLike
        The file (or folder) for the message.
    rebuild : str
        How to write it again, e.g. "rebuild it with `mocapviz index DB`" (appended to the message).

    Returns
    -------
    dict
        ``header``, unchanged.

    Raises
    ------
    MotionDBError
        Not a dict, another format, or another version.
    """
    found_format = header.get("format") if isinstance(header, dict) else None
    found_version = header.get("version") if isinstance(header, dict) else None
    if found_format == format_name and found_version == version:
        return header
    found = f"{found_format} version {found_version}" if found_format else "no mocapviz format header"
    hint = f"; {rebuild}" if rebuild else ""
    raise MotionDBError(f"{where}: not a {format_name} version {version} file ({found} found){hint}")


def load_or_build(load: Callable[[], T], build: Callable[[], T]) -> T:
    """``load()``, or ``build()`` when the artefact is missing, stale or unreadable (``load`` raised
    MotionDBError): derived data can always be computed again from its MotionDB.

    Parameters
    ----------
    load : callable
        ``load() -> T``, raising MotionDBError when the stored artefact cannot be used.
    build : callable
        ``build() -> T`` (storing it, if it should be stored).

    Returns
    -------
    T
        What ``load`` or ``build`` returned.
    """
    try:
        return load()
    except MotionDBError:
        return build()


def fingerprint(path: str | os.PathLike) -> dict:
    """``{"size", "sha256", "block", "xxh3"}`` of a file, read once in blocks (any size): its sha256 for a full check
    (``mocapviz check``) and the xxh3 of each block for the check on first read (:mod:`mocapviz.checked_map`).

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    dict
        ``size`` (int, bytes), ``sha256`` (str, 64 hex digits), ``block`` (int, bytes per block) and ``xxh3`` (list
        of str, 16 hex digits per block).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     f = Path(folder) / "a.bin"
    ...     _ = f.write_bytes(b"abc")
    ...     fp = fingerprint(f)
    >>> fp["size"], fp["sha256"][:12], len(fp["xxh3"])
    (3, 'ba7816bf8f01', 1)
    """
    import xxhash

    from .checked_map import BLOCK_BYTES

    sha, blocks = hashlib.sha256(), []
    with open(path, "rb") as fh:
        while chunk := fh.read(BLOCK_BYTES):
            sha.update(chunk)
            blocks.append(xxhash.xxh3_64_hexdigest(chunk))
    return {"size": os.path.getsize(path), "sha256": sha.hexdigest(), "block": BLOCK_BYTES, "xxh3": blocks}


def digest(arrays: dict) -> str:
    """sha256 over ``{name: np.ndarray}`` in name order: each name, dtype, shape and the C-ordered bytes.

    Parameters
    ----------
    arrays : dict
        Name -> np.ndarray.

    Returns
    -------
    str
        64 hex digits.

    Examples
    --------
    >>> import numpy as np
    >>> digest({"a": np.arange(3)}) == digest({"a": np.arange(3)}) != digest({"a": np.arange(3.0)})
    True
    """
    import numpy as np

    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def verify(path: str | os.PathLike, expected: dict | None, full: bool = False, rebuild: str = "") -> None:
    """Check a stored file against its :func:`fingerprint`: its size always, its sha256 when ``full``.

    ``expected`` None (a file written before fingerprints were kept) passes.

    Parameters
    ----------
    path : str or os.PathLike
        The stored file.
    expected : dict or None
        Its :func:`fingerprint` as recorded when it was written.
    full : bool
        Also check the sha256 (reads the whole file).
    rebuild : str
        How to write it again, for the message.

    Raises
    ------
    MotionDBError
        Naming the file and what differs ("… changed since it was written (size / sha256): …; REBUILD"), or a
        missing file.
    """
    if expected is None:
        return
    hint = f"; {rebuild}" if rebuild else ""
    try:
        size = os.path.getsize(path)
    except OSError as exc:
        raise MotionDBError(f"{path}: missing or unreadable ({exc.strerror}){hint}") from None
    if size != expected.get("size"):
        raise MotionDBError(f"{path}: {size:,} bytes, {expected.get('size'):,} when written: the file is damaged{hint}")
    if full and fingerprint(path)["sha256"] != expected.get("sha256"):
        raise MotionDBError(f"{path}: its sha256 differs from the one recorded when it was written: the file is "
                            f"damaged{hint}")


def fsync_folder(folder: str | os.PathLike) -> None:
    """Make a rename in ``folder`` durable (fsync of the folder; a no-op where folders cannot be opened).

    Parameters
    ----------
    folder : str or os.PathLike
        The folder whose entries changed.
    """
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
