"""The real motion-capture archives mocapviz is tested and benchmarked on, fetched on demand.

Six ``.tar.xz`` archives (see ``ARCHIVES``) are looked up under one base location, checked against their
sha256 and unpacked once into a local cache:

- base location: the environment variable ``MOCAPVIZ_DATA_URL``, an ``http(s)://`` URL, a ``file://`` URL or
  a plain folder path; unset, and only when the package runs from a source checkout, the folder
  ``<checkout>/../shared/data``. Nothing else is tried.
- cache: the environment variable ``MOCAPVIZ_HOME``, else ``pooch.os_cache("mocapviz")``. Archive ``NAME``
  is stored as ``<cache>/NAME.tar.xz`` and unpacked into ``<cache>/NAME/``.

The archives repackage public data (``Archive.source``: HDM05, the CMU Graphics Lab database, the Bandai
Namco Research motion dataset), each under its own licence (``Archive.licence``).

``sample()`` (also ``fetch("sample")``) and ``demo()`` (``fetch("demo")``) need no download: they unpack the
small sample (22 HDM05 clips, 2 CMU trials) and the demo (44 HDM05 clips, 8 CMU trials, 2 C3D takes) shipped
inside the package (:data:`EMBEDDED`). Every unpack goes to a temporary folder renamed into place at the
end, so an interrupted unpack never leaves a folder that a later call would take for complete. Besides the
sha256, every member is checked as it is unpacked (tarfile's ``data`` filter and :func:`_refusal`): a member with
an absolute path or ``..`` leading outside the folder, a link pointing outside it, or a device file is refused
with a :class:`DatasetError` naming the archive and the member, and nothing is left behind.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tarfile
import urllib.parse
import urllib.request
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import pandas as pd
import pooch

from ..errors import MocapvizError
from ..store import atomic_folder

DATA_URL_ENV = "MOCAPVIZ_DATA_URL"
HOME_ENV = "MOCAPVIZ_HOME"


class DatasetError(MocapvizError, RuntimeError):
    """An archive cannot be located, downloaded, verified or unpacked, or its name is unknown."""


@dataclass(frozen=True)
class Archive:
    """One registered archive (an entry of ``ARCHIVES``); the fields are its attributes.

    Parameters
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
    size : int
        Size of the archive file in bytes.
    source : str
        Where the data come from originally (public URL) and the repository it was repackaged from.
    """

    name: str
    description: str
    files: str
    frames: int
    fps: int
    licence: str
    sha256: str
    size: int
    source: str

    @property
    def filename(self) -> str:
        """File name of the archive under the base location and in the cache."""
        return f"{self.name}.tar.xz"


_BANDAI_LICENCE = (
    "CC BY-NC 4.0 (Bandai Namco Research Inc.) — not for commercial use; do not bundle inside the package; "
    'cite Kobayashi, Liao, Inoue, Yojima, Takahashi, "Motion Capture Dataset for Practical Use of AI-based Motion '
    'Editing and Stylization", arXiv:2306.08861, 2023'
)
_BANDAI_SOURCE = (
    "https://github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset (@ 74ead3b, where the licence "
    "is CC BY-NC 4.0)"
)

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
            size=13_167_072,
            source=(
                "http://resources.mpi-inf.mpg.de/HDM05/ (cut clips as in github.com/zhangchi8620/JointLearning-HDM05 "
                "@ b252ad6)"
            ),
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
            size=9_012_524,
            source="http://mocap.cs.cmu.edu/ (trials as in github.com/encadyma/motion-out @ 4855c55)",
        ),
        Archive(
            name="bandai-namco-1",
            description="Bandai Namco Research motion dataset 1: 17 contents x 15 styles (BVH + JSON labels)",
            files="174 BVH + one .json label each",
            frames=31_914,
            fps=30,
            licence=_BANDAI_LICENCE,
            sha256="e88067e44d25a41792de4eb0d9705f4590cacc9b208e67634544d1a60b4fac6f",
            size=7_426_268,
            source=_BANDAI_SOURCE,
        ),
        Archive(
            name="bandai-namco-2",
            description="Bandai Namco Research motion dataset 2: 10 contents x 7 styles (BVH + JSON labels)",
            files="2,902 BVH + .json each",
            frames=384_931,
            fps=30,
            licence=_BANDAI_LICENCE,
            sha256="15a0229860c01b0d0a3f6585e005e3d9e5341fe786dc6aedfcd5899538ba23d5",
            size=79_372_188,
            source=_BANDAI_SOURCE,
        ),
        Archive(
            name="c3d-markers",
            description="C3D marker trajectories: 7 CMU trials, 2 HDM05 scene takes, 3 Vicon Plug-in Gait files",
            files="12 C3D + MANIFEST.md (source, markers, rate, frames, gaps of each)",
            frames=22_393,
            fps=120,
            licence=(
                "CMU: free for research, credit mocap.cs.cmu.edu (NSF EIA-0196217); HDM05: CC BY-SA 3.0 (cite "
                "Müller et al., Tech. Rep. CG-2007-2); BTKData gait files: BSD-3-Clause"
            ),
            sha256="6d9cc365a7350daf9499fe95fc6636bd2bcaed809cbe2b276cc6b6b2478d4bfc",
            size=8_958_048,
            source=(
                "github.com/numediart/MocapRecovery @ 8b18571, surenkum/c3d_to_xyz @ 10448e5, "
                "Nisarg-M-Patel/pylayers-py3 @ 80df0cb, Mohaoui-S/Tucker_MoCap @ aeeab9b, "
                "Biomechanical-ToolKit/BTKData @ 6aee093"
            ),
        ),
        Archive(
            name="peer-readers",
            description=(
                "Files other tools wrote, for the readers' conformance tests (docs/conformance.md): 6 BVH, "
                "8 C3D, 6 FBX (CMU 01_01 in BVH and FBX, Vicon, BTS, Kistler, Optotrak, DEC floats, FBX 6.1-7.5)"
            ),
            files="6 BVH, 8 C3D, 6 FBX + MANIFEST.md (source, licence, sha256, frames, what each tests) + licenses/",
            frames=9_108,  # the BVH files' rows; the manifest lists each file's
            fps=120,
            licence=(
                "per file in licenses/: BSD-3-Clause (assimp, IsaacGymEnvs), MIT (AnimatedDrawings, bvhio, PyMO), "
                "MIT or Unlicense (ufbx); the C3D files are GPL-3.0 test data (pyomeca/ezc3d-testFiles): test "
                "input only, never in the package"
            ),
            sha256="781e2fbef69134ec327ad377358a239fe4685815eb73161081d0a4312c228504",
            size=5_261_968,
            source=(
                "github.com/assimp/assimp @ 21bea12f, facebookresearch/AnimatedDrawings @ 74ee7f00, "
                "Wasserwecken/bvhio @ d5bd7a54, omimo/PyMO @ ba24f5f8, pyomeca/ezc3d-testFiles @ e40a8f8e, "
                "isaac-sim/IsaacGymEnvs @ aeed2986, ufbx/ufbx @ fcc5d6ba"
            ),
        ),
    )
}


SAMPLE = "sample"
"""Name of the small sample embedded in the package (see :func:`sample`); not an entry of ``ARCHIVES``."""
DEMO = "demo"
"""Name of the demo embedded in the package (see :func:`demo`); not an entry of ``ARCHIVES``."""


@dataclass(frozen=True)
class Embedded:
    """A dataset shipped inside the package (``mocapviz/data/<name>.tar.xz``, made by ``scripts/make_sample.py``):
    real files, bytes unchanged, cut from the shared archives whose licences allow it (never Bandai Namco's)."""

    name: str
    description: str
    files: str
    frames: int
    licence: str
    source: str


_HDM05_CMU_LICENCE = (
    "HDM05 clips: CC BY-SA 3.0 (cite Müller et al., Tech. Rep. CG-2007-2, Universität Bonn, 2007); CMU trials: "
    "credit mocap.cs.cmu.edu (NSF EIA-0196217); full text in its LICENSE.md"
)
EMBEDDED: dict[str, Embedded] = {
    e.name: e
    for e in (
        Embedded(
            name=SAMPLE,
            description="embedded sample: 22 HDM05 cut clips (actors dg, mm x 11 classes) + 2 CMU trials (ASF/AMC)",
            files="22 HDM05 AMC + 2 CMU AMC + their 4 ASF",
            frames=5_543,
            licence=_HDM05_CMU_LICENCE,
            source="embedded in the package (mocapviz/data/sample.tar.xz), cut from hdm05-cut and cmu-asfamc",
        ),
        Embedded(
            name=DEMO,
            description=(
                "embedded demo: 44 HDM05 cut clips (4 actors x 11 classes), 8 CMU martial-arts trials (kicks, "
                "punches, kata), 2 C3D takes (CMU, HDM05)"
            ),
            files="44 HDM05 AMC + 8 CMU AMC + their 5 ASF + 2 C3D",
            frames=28_643,
            licence=_HDM05_CMU_LICENCE,
            source=(
                "embedded in the package (mocapviz/data/demo.tar.xz), cut from hdm05-cut, cmu-asfamc and c3d-markers"
            ),
        ),
    )
}
"""The embedded datasets by name: :data:`SAMPLE` (the database of every Examples section and most tests) and
:data:`DEMO` (what ``make demo`` serves: every headline feature has something to find in it)."""
DEMO_ORDER = ("hdm05-cut", "cmu-asfamc", "c3d-markers")
"""The demo's folders in the order ``make demo`` and :meth:`mocapviz.MotionDB.demo` ingest them (document ids
follow it: the HDM05 clips first)."""

INFO_COLUMNS = ["name", "description", "files", "frames", "fps", "size", "embedded", "licence", "source", "sha256",
                "cached"]


def names() -> list[str]:
    """Names of the shared archives (``ARCHIVES``), in registry order; the embedded sample is :data:`SAMPLE`.

    Returns
    -------
    list of str
        Names for :func:`fetch`.

    Examples
    --------
    >>> names()
    ['hdm05-cut', 'cmu-asfamc', 'bandai-namco-1', 'bandai-namco-2', 'c3d-markers', 'peer-readers']
    """
    return list(ARCHIVES)


def info() -> pd.DataFrame:
    """Every registered dataset as a table: the shared archives, then the embedded sample.

    Returns
    -------
    pandas.DataFrame
        One row per dataset, columns ``INFO_COLUMNS``: ``name, description, files, frames, fps, size`` (bytes of
        the ``.tar.xz``), ``embedded`` (True for the sample shipped inside the package, False for an archive
        fetched from ``MOCAPVIZ_DATA_URL`` or ``../shared/data``), ``licence``, ``source`` (original public
        source), ``sha256`` and ``cached`` (True when already unpacked in the cache).
    """
    cache = _cache_dir()
    rows = [
        {
            "name": a.name,
            "description": a.description,
            "files": a.files,
            "frames": a.frames,
            "fps": a.fps,
            "size": a.size,
            "embedded": False,
            "licence": a.licence,
            "source": a.source,
            "sha256": a.sha256,
            "cached": (cache / a.name / a.name).is_dir(),
        }
        for a in ARCHIVES.values()
    ]
    for e in EMBEDDED.values():
        with resources.as_file(_embedded_archive(e.name)) as archive:
            digest = hashlib.sha256(archive.read_bytes()).hexdigest()
            rows.append({
                "name": e.name,
                "description": e.description,
                "files": e.files,
                "frames": e.frames,
                "fps": 120,
                "size": archive.stat().st_size,
                "embedded": True,
                "licence": e.licence,
                "source": e.source,
                "sha256": digest,
                "cached": (cache / f"{e.name}-{digest[:12]}" / e.name).is_dir(),
            })
    return pd.DataFrame(rows, columns=INFO_COLUMNS)


def fetch(name: str, progress: bool = False) -> Path:
    """Download (or copy), verify and unpack one archive, once; later calls reuse the cache.

    Parameters
    ----------
    name : str
        A registered name (see :func:`names`), or ``"sample"`` for the embedded sample (:func:`sample`).
    progress : bool
        Show a progress bar while downloading over http(s) (needs ``tqdm``); ignored for local folders.

    Returns
    -------
    pathlib.Path
        The archive's unpacked top folder, ``<cache>/<name>/<name>`` (for ``"sample"``, what :func:`sample`
        returns).

    Raises
    ------
    DatasetError
        Unknown name, base location not found (the message says where the archives come from and how to
        provide them), download failure or sha256 mismatch.
    """
    if name in EMBEDDED:
        return _embedded(name)
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

    Examples
    --------
    >>> folder = sample()
    >>> sorted(p.name for p in folder.iterdir())
    ['LICENSE.md', 'README.md', 'cmu-asfamc', 'hdm05-cut']
    >>> len(list((folder / "hdm05-cut" / "amc").glob("*.amc")))
    22
    """
    return _embedded(SAMPLE)


def demo() -> Path:
    """Unpack the demo shipped inside the package, once, and return its folder.

    The demo holds real files, unchanged, chosen so that each headline feature has something to find: every HDM05
    class from four actors (the shortest clip of each, 44 clips), eight CMU martial-arts trials (front, round and
    side kicks, lunge punches, two kata) and two C3D takes of marker trajectories (CMU subject 85's
    jump twist, the HDM05 locomotion scene 01-02 of actor bd), with their ASF skeletons, ``labels.tsv`` tables,
    ``LICENSE.md`` and ``README.md``.

    Returns
    -------
    pathlib.Path
        ``<cache>/demo-<12 hex digits of the archive's sha256>/demo``, holding the folders of :data:`DEMO_ORDER`,
        ``LICENSE.md`` and ``README.md``.

    Examples
    --------
    >>> folder = demo()
    >>> sorted(p.name for p in folder.iterdir())
    ['LICENSE.md', 'README.md', 'c3d-markers', 'cmu-asfamc', 'hdm05-cut']
    >>> len(list((folder / "hdm05-cut" / "amc").glob("*.amc"))), len(list((folder / "c3d-markers").glob("*.c3d")))
    (44, 2)
    """
    return _embedded(DEMO)


def _embedded(name: str) -> Path:
    """Unpack the embedded dataset ``name`` (a key of :data:`EMBEDDED`) once, into a folder named after its
    sha256, and return its top folder."""
    with resources.as_file(_embedded_archive(name)) as archive:
        digest = hashlib.sha256(archive.read_bytes()).hexdigest()
        target = _cache_dir() / f"{name}-{digest[:12]}"
        if not target.is_dir():
            _unpack(archive, target, replace=False)
    return target / name


def _embedded_archive(name: str):
    """The embedded archive ``name`` inside the package (an importlib.resources Traversable)."""
    return resources.files("mocapviz") / "data" / f"{name}.tar.xz"


def data_url() -> str:
    """The base location of the archives, as a URL ending in ``/``.

    Returns
    -------
    str
        ``MOCAPVIZ_DATA_URL`` when set (a plain folder path becomes a ``file://`` URL), else the ``file://``
        URL of ``../shared/data`` beside the source checkout the package runs from, if it exists.

    Raises
    ------
    DatasetError
        The variable is unset and there is no such folder. The message (two lines) says how to provide the
        archives and where their data come from.
    """
    value = os.environ.get(DATA_URL_ENV, "").strip()
    if not value:
        folder = next((f for f in _default_folders() if f.is_dir()), None)
        if folder is None:
            raise DatasetError(_not_found_message())
        value = str(folder)
    if "://" not in value:
        value = Path(value).expanduser().resolve().as_uri()
    return value.rstrip("/") + "/"


def _default_folders() -> list[Path]:
    """Folders tried, in order, when ``MOCAPVIZ_DATA_URL`` is unset: ``<checkout>/../shared/data`` when the
    package runs from a source checkout (its parent folder holds ``pyproject.toml``), else none."""
    checkout = Path(__file__).resolve().parents[2]  # <checkout>/mocapviz/io/datasets.py
    if not (checkout / "pyproject.toml").is_file():
        return []
    return [checkout.parent / "shared" / "data"]


def _not_found_message() -> str:
    """The error when no base location is known: how to provide the archives, and where they come from."""
    return (
        f"mocap archives not found: set {DATA_URL_ENV} to a folder or http(s) URL holding NAME.tar.xz (names: "
        f"'mocapviz datasets list'; a source checkout also finds ../shared/data); the embedded '{SAMPLE}' needs none.\n"
        "They repackage public data: HDM05 cut clips (resources.mpi-inf.mpg.de/HDM05, CC BY-SA 3.0), the CMU "
        "Graphics Lab database (mocap.cs.cmu.edu) and the Bandai Namco Research motion dataset "
        "(github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset, CC BY-NC 4.0); see docs/files.md, "
        "'Data and licences'."
    )


def cache_dir() -> Path:
    """The cache folder: ``MOCAPVIZ_HOME`` or the user cache of the operating system.

    Returns
    -------
    pathlib.Path
        Absolute; archive ``NAME`` unpacks into ``<cache>/NAME/``.
    """
    return Path(os.environ.get(HOME_ENV) or pooch.os_cache("mocapviz")).expanduser().resolve()


_cache_dir = cache_dir


def _archive(name: str) -> Archive:
    """The registry entry of ``name``, or a DatasetError listing the known names."""
    try:
        return ARCHIVES[name]
    except KeyError:
        raise DatasetError(
            f"unknown dataset {name!r}: known are {', '.join(ARCHIVES)}, and {SAMPLE} and {DEMO} (embedded)"
        ) from None


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
    """pooch processor: unpack the archive into ``target`` through a temporary folder renamed at the end
    (:func:`_unpack`: every member checked).

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
    """Unpack ``archive`` into ``target`` atomically, every member checked (:func:`_extract`).

    The archive is unpacked into a temporary folder beside ``target`` that is renamed to ``target`` at the end.
    With ``replace``, an existing ``target`` is moved aside first; without, a ``target`` that appeared meanwhile
    (another process) is kept. A refused member or an unreadable archive raises a DatasetError and leaves nothing.
    """
    with atomic_folder(target, replace=replace) as staging:
        _extract(Path(archive), staging)


class _UnsafeMember(ValueError):
    """A member :func:`_refusal` refuses (on a Python whose tarfile has no ``data`` filter, the only check)."""


_DATA_FILTER = getattr(tarfile, "data_filter", None)  # Python >= 3.10.12 / 3.11.4 (PEP 706)
_FILTER_ERRORS = (_UnsafeMember, *((tarfile.FilterError,) if hasattr(tarfile, "FilterError") else ()))


def _refusal(member: tarfile.TarInfo, dest: str) -> str | None:
    """Why ``member`` may not be unpacked into the folder ``dest``, or None when it may.

    Refused: an absolute name (which the ``data`` filter would silently make relative), a name whose ``..`` or
    whose path through links already unpacked leads outside ``dest``, a symbolic or hard link to an absolute path
    or to a place outside ``dest``, and anything but files, folders and links (devices, fifos).
    """
    name, link = member.name, member.linkname
    if name.startswith(("/", "\\")) or os.path.isabs(name):
        return "an absolute path"
    root = os.path.realpath(dest)
    where = os.path.realpath(os.path.join(root, name))

    def inside(path: str) -> bool:
        return os.path.commonpath([root, path]) == root

    if not inside(where):
        return "a path leading outside the folder"
    if member.issym() or member.islnk():
        if link.startswith(("/", "\\")) or os.path.isabs(link):
            return f"a link to the absolute path {link!r}"
        base = os.path.dirname(where) if member.issym() else root  # a hard link names a member of the archive
        if not inside(os.path.realpath(os.path.join(base, link))):
            return f"a link to {link!r}, outside the folder"
    elif not (member.isfile() or member.isdir()):
        return "a device, fifo or other special file"
    return None


def _checked_member(member: tarfile.TarInfo, dest: str) -> tarfile.TarInfo:
    """``member`` as tarfile's ``data`` filter passes it (where there is one), after :func:`_refusal`'s checks."""
    reason = _refusal(member, dest)
    if reason is not None:
        raise _UnsafeMember(reason)
    return member if _DATA_FILTER is None else _DATA_FILTER(member, dest)


def _extract(archive: Path, folder: Path) -> None:
    """Unpack every member of ``archive`` into ``folder``, each checked first (:func:`_checked_member`).

    Raises
    ------
    DatasetError
        A member is refused (the message names the archive, the member and why), or the archive cannot be read
        as a tar file.
    """

    def check(member: tarfile.TarInfo, dest: str) -> tarfile.TarInfo:
        try:
            return _checked_member(member, dest)
        except _FILTER_ERRORS as exc:
            raise DatasetError(f"{archive.name}: member {member.name!r} refused: {exc}; nothing was unpacked "
                               f"(from {archive})") from None  # fmt: skip

    try:
        with tarfile.open(archive) as tar:
            if _DATA_FILTER is not None:
                tar.extractall(folder, filter=check)
            else:  # no filter= before Python 3.10.12 / 3.11.4: each member checked just before it is unpacked,
                for member in tar:  # so that the links unpacked before it count
                    tar.extract(check(member, str(folder)), folder)
    except tarfile.TarError as exc:
        raise DatasetError(f"{archive.name}: cannot unpack it ({exc}; from {archive})") from None
