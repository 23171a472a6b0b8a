"""The real motion-capture archives mocapviz is tested and benchmarked on, fetched on demand.

Four ``.tar.xz`` archives (see ``ARCHIVES``) are looked up under one base location, checked against their
sha256 and unpacked once into a local cache:

- base location: the environment variable ``MOCAPVIZ_DATA_URL``, an ``http(s)://`` URL, a ``file://`` URL or
  a plain folder path; unset, the first existing folder among ``<repo root>/../shared/data`` and
  ``/work/shared/data``.
- cache: the environment variable ``MOCAPVIZ_HOME``, else ``pooch.os_cache("mocapviz")``. Archive ``NAME``
  is stored as ``<cache>/NAME.tar.xz`` and unpacked into ``<cache>/NAME/``.

``sample()`` needs no download: it unpacks the small sample (22 HDM05 clips, 2 CMU trials) shipped inside
the package. Every unpack goes to a temporary folder renamed into place at the end, so an interrupted
unpack never leaves a folder that a later call would take for complete.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import urllib.parse
import urllib.request
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import pandas as pd
import pooch

DATA_URL_ENV = "MOCAPVIZ_DATA_URL"
HOME_ENV = "MOCAPVIZ_HOME"


class DatasetError(RuntimeError):
    """An archive cannot be located, downloaded, verified or unpacked, or its name is unknown."""


@dataclass(frozen=True)
class Archive:
    """One registered archive.

    Attributes
    ----------
    name : str
        Registry name; the file is ``<name>.tar.xz`` and unpacks to a top folder ``<name>/``.
    description : str
        What it holds, in one line.
    files : str
        Its motion files, in words.
    frames : int
        Total number of frames at the native rate.
    fps : int
        Native frame rate in frames per second.
    licence : str
        Licence and the attribution it requires.
    sha256 : str
        Hex sha256 of the archive file.
    """

    name: str
    description: str
    files: str
    frames: int
    fps: int
    licence: str
    sha256: str

    @property
    def filename(self) -> str:
        """File name of the archive under the base location and in the cache."""
        return f"{self.name}.tar.xz"


_BANDAI_LICENCE = "CC BY-NC 4.0 (Bandai Namco Research Inc.) — not for commercial use; do not bundle inside the package"

ARCHIVES: dict[str, Archive] = {
    archive.name: archive
    for archive in (
        Archive(
            name="hdm05-cut",
            description="HDM05 cut clips: one motion-class instance per file, 11 classes, 5 actors (ASF/AMC)",
            files="287 AMC clips + 5 actor ASF (bd bk dg mm tr)",
            frames=70_996,
            fps=120,
            licence=(
                "HDM05: CC BY-SA 3.0; cite Müller, Röder, Clausen, Eberhardt, Krüger, Weber, "
                '"Documentation Mocap Database HDM05", Tech. Rep. CG-2007-2, Universität Bonn, 2007'
            ),
            sha256="701d394aef9dc50912f5a51d7dfc1d61a9a51b72a031f6735a0de934ddb490a5",
        ),
        Archive(
            name="cmu-asfamc",
            description="CMU trials in 5 groups: Michael Jackson, martial arts, modern dance, golf, walk (ASF/AMC)",
            files="32 AMC trials + 5 ASF",
            frames=47_272,
            fps=120,
            licence=(
                "CMU Graphics Lab Motion Capture Database: free for research; may be included in products but "
                'not resold as data; credit "The data used in this project was obtained from mocap.cs.cmu.edu. '
                'The database was created with funding from NSF EIA-0196217."'
            ),
            sha256="b63fc9b0dee98d5817e52acbe3be3c3d8db508c2d6ff9bf95c445a9311230200",
        ),
        Archive(
            name="bandai-namco-1",
            description="Bandai Namco Research motion dataset 1: 17 contents x 15 styles (BVH + JSON labels)",
            files="174 BVH + one .json label each",
            frames=31_914,
            fps=30,
            licence=_BANDAI_LICENCE,
            sha256="e88067e44d25a41792de4eb0d9705f4590cacc9b208e67634544d1a60b4fac6f",
        ),
        Archive(
            name="bandai-namco-2",
            description="Bandai Namco Research motion dataset 2: 10 contents x 7 styles (BVH + JSON labels)",
            files="2,902 BVH + .json each",
            frames=384_931,
            fps=30,
            licence=_BANDAI_LICENCE,
            sha256="15a0229860c01b0d0a3f6585e005e3d9e5341fe786dc6aedfcd5899538ba23d5",
        ),
    )
}


def names() -> list[str]:
    """Names of the registered archives, in registry order."""
    return list(ARCHIVES)


def info() -> pd.DataFrame:
    """The registry as a table.

    Returns
    -------
    pandas.DataFrame
        One row per archive, columns ``name, description, files, frames, fps, licence, sha256, cached``;
        ``cached`` is True when the archive is already unpacked in the cache.
    """
    cache = _cache_dir()
    rows = [
        {
            "name": a.name,
            "description": a.description,
            "files": a.files,
            "frames": a.frames,
            "fps": a.fps,
            "licence": a.licence,
            "sha256": a.sha256,
            "cached": (cache / a.name / a.name).is_dir(),
        }
        for a in ARCHIVES.values()
    ]
    return pd.DataFrame(rows)


def fetch(name: str, progress: bool = False) -> Path:
    """Download (or copy), verify and unpack one archive, once; later calls reuse the cache.

    Parameters
    ----------
    name : str
        A registered name (see :func:`names`).
    progress : bool
        Show a progress bar while downloading over http(s) (needs ``tqdm``); ignored for local folders.

    Returns
    -------
    pathlib.Path
        The archive's unpacked top folder, ``<cache>/<name>/<name>``.

    Raises
    ------
    DatasetError
        Unknown name, base location not found, download failure or sha256 mismatch.
    """
    archive = _archive(name)
    base = data_url()
    cache = _cache_dir()
    registry = pooch.create(path=cache, base_url=base, registry={archive.filename: f"sha256:{archive.sha256}"})
    downloader = _VerifyingDownloader(archive, _downloader(base, progress))
    unpacked = registry.fetch(archive.filename, processor=_AtomicUntar(cache / name), downloader=downloader)
    folder = unpacked / name
    if not folder.is_dir():
        raise DatasetError(f"{archive.filename} has no top folder {name}/ (unpacked into {unpacked})")
    return folder


def sample() -> Path:
    """Unpack the sample shipped inside the package, once, and return its folder.

    The sample holds real files, unchanged: 22 HDM05 clips (two actors x 11 classes) and two CMU trials,
    with their ASF skeletons, ``labels.tsv`` tables, ``LICENSE.md`` and ``README.md``.

    Returns
    -------
    pathlib.Path
        ``<cache>/sample-<12 hex digits of the archive's sha256>/sample``, holding ``hdm05-cut/``,
        ``cmu-asfamc/``, ``LICENSE.md`` and ``README.md``.
    """
    source = resources.files("mocapviz") / "data" / "sample.tar.xz"
    with resources.as_file(source) as archive:
        digest = hashlib.sha256(archive.read_bytes()).hexdigest()
        target = _cache_dir() / f"sample-{digest[:12]}"
        if not target.is_dir():
            _unpack(archive, target, replace=False)
    return target / "sample"


def data_url() -> str:
    """The base location of the archives, as a URL ending in ``/``.

    Returns
    -------
    str
        ``MOCAPVIZ_DATA_URL`` when set (a plain folder path becomes a ``file://`` URL), else the ``file://``
        URL of the first existing default folder.

    Raises
    ------
    DatasetError
        The variable is unset and no default folder exists.
    """
    value = os.environ.get(DATA_URL_ENV, "").strip()
    if not value:
        folder = next((f for f in _default_folders() if f.is_dir()), None)
        if folder is None:
            raise DatasetError(f"mocap archives not found: set {DATA_URL_ENV} to a folder or URL that holds them")
        value = str(folder)
    if "://" not in value:
        value = Path(value).expanduser().resolve().as_uri()
    return value.rstrip("/") + "/"


def _default_folders() -> list[Path]:
    """Folders tried, in order, when ``MOCAPVIZ_DATA_URL`` is unset."""
    repo_root = Path(__file__).resolve().parent.parent
    return [repo_root.parent / "shared" / "data", Path("/work/shared/data")]


def _cache_dir() -> Path:
    """The cache folder: ``MOCAPVIZ_HOME`` or the user cache of the operating system."""
    return Path(os.environ.get(HOME_ENV) or pooch.os_cache("mocapviz")).expanduser().resolve()


def _archive(name: str) -> Archive:
    """The registry entry of ``name``, or a DatasetError listing the known names."""
    try:
        return ARCHIVES[name]
    except KeyError:
        raise DatasetError(f"unknown dataset {name!r}: known are {', '.join(ARCHIVES)}") from None


def _downloader(base: str, progress: bool):
    """A pooch downloader for the scheme of ``base``: a file copy for ``file://``, pooch's own for http(s)."""
    scheme = urllib.parse.urlparse(base).scheme
    if scheme == "file":
        return _copy_local
    if scheme in ("http", "https"):
        return pooch.HTTPDownloader(progressbar=progress)
    raise DatasetError(f"{DATA_URL_ENV}={base!r}: unsupported scheme {scheme!r} (use http, https, file or a folder)")


def _copy_local(url: str, output_file, pooch_obj, check_only: bool = False):
    """pooch downloader for ``file://`` URLs: copy the file (``output_file`` is a path or a binary file)."""
    source = Path(urllib.request.url2pathname(urllib.parse.urlparse(url).path))
    if check_only:
        return source.is_file()
    if not source.is_file():
        raise DatasetError(f"archive not found: {source}")
    if hasattr(output_file, "write"):
        with source.open("rb") as src:
            shutil.copyfileobj(src, output_file)
    else:
        shutil.copyfile(source, output_file)
    return None


class _VerifyingDownloader:
    """Wrap a pooch downloader: turn network errors and a sha256 mismatch into a one-line DatasetError."""

    def __init__(self, archive: Archive, inner):
        self.archive = archive
        self.inner = inner

    def __call__(self, url: str, output_file: str, pooch_obj, check_only: bool = False):
        import requests  # pooch's own dependency, imported lazily like pooch does

        try:
            result = self.inner(url, output_file, pooch_obj, check_only=check_only)
        except requests.exceptions.RequestException as exc:
            raise DatasetError(f"cannot download {url}: {exc}") from None
        if not check_only:
            actual = pooch.file_hash(output_file, alg="sha256")
            if actual != self.archive.sha256:
                raise DatasetError(
                    f"{self.archive.filename} from {url} is corrupt: sha256 {actual}, expected {self.archive.sha256}"
                )
        return result


class _AtomicUntar:
    """pooch processor: unpack the archive into ``target`` through a temporary folder renamed at the end.

    A fresh download or update replaces ``target``; a plain fetch unpacks only when ``target`` is missing.
    Returns ``target``.
    """

    def __init__(self, target: Path):
        self.target = target

    def __call__(self, fname: str, action: str, pooch_obj) -> Path:
        fresh = action in ("download", "update")
        if fresh or not self.target.is_dir():
            _unpack(Path(fname), self.target, replace=fresh)
        return self.target


def _unpack(archive: Path, target: Path, replace: bool) -> None:
    """Unpack ``archive`` into ``target`` atomically.

    The archive is unpacked with ``pooch.Untar`` into a temporary folder beside ``target`` that is renamed to
    ``target`` at the end. With ``replace``, an existing ``target`` is moved aside first; without, a ``target``
    that appeared meanwhile (another process) is kept.
    """
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f".{target.name}-", dir=target.parent) as scratch:
        staging = Path(scratch) / "unpacked"
        pooch.Untar(extract_dir=str(staging))(str(archive), "download", None)
        if replace and target.exists():
            os.replace(target, Path(scratch) / "previous")
        try:
            os.replace(staging, target)
        except OSError:
            if not target.is_dir():
                raise
