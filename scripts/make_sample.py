"""Build the real-data sets shipped inside the package: ``mocapviz/data/sample.tar.xz`` (the small sample of the
Examples and tests) and ``mocapviz/data/demo.tar.xz`` (what ``make demo`` serves).

Usage::

    python scripts/make_sample.py [sample|demo] [--source FOLDER] [--output FILE]

``--source`` is the folder holding the shared archives (default: where ``mocapviz.io.datasets`` finds them).
Both hold real files with unchanged bytes, each dataset in its own folder with ``labels.tsv`` restricted to the
files kept, plus ``LICENSE.md`` (licences and attributions) and ``README.md`` (files and frame counts):

- ``sample``: ``hdm05-cut/`` two actors x all 11 classes x one clip each (22 AMC clips) and their ASF files;
  ``cmu-asfamc/`` ``amc/mjackson/131_01.amc`` and the shortest ``amc/martialwalk/135_*.amc`` with their ASF files.
- ``demo``: ``hdm05-cut/`` four actors x 11 classes (44 clips); ``cmu-asfamc/`` eight martial-arts trials,
  ``135_03``, ``135_04`` and ``135_06`` to ``135_11`` (front, round and side kicks, lunge punches, two kata; left out
  so that the archive stays under 6 MB: ``135_02``, a longer Empi, and ``135_05``, a block); ``c3d-markers/`` two C3D
  takes whose licences allow it (CMU ``85_02``, a jump
  twist, and the HDM05 locomotion scene ``HDM_bd_01-02_01``), with a ``labels.tsv`` written here from the CMU
  trial's description (the scene take stays unlabelled, as many takes of a real database are). The GPL
  ``peer-readers`` files and the BSD gait-lab files are never included.

Per actor and class the shortest HDM05 clip is taken (ties: lowest take); the actors with the fewest frames in
total over their 11 clips are kept.

Bandai Namco data is never included: its licence forbids bundling it. The tar is deterministic (sorted
names, mtime 0, uid/gid 0, fixed modes) and xz preset 9, so a rebuild from the same archives gives the same
bytes.
"""

from __future__ import annotations

import argparse
import io
import os
import sys
import tarfile
import tempfile
import urllib.parse
import urllib.request
from pathlib import Path

import pandas as pd
import pooch

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT))

from mocapviz.io.datasets import ARCHIVES, data_url

MAX_BYTES = {"sample": 5 * 1024 * 1024, "demo": 6_000_000}  # no tracked file over 6 MB; the package's data < 10 MB
CMU_CLIPS = ("amc/mjackson/131_01.amc",)
CMU_SHORTEST_OF = "amc/martialwalk/135_*.amc"
DEMO_CMU_CLIPS = tuple(f"amc/martialwalk/135_{trial:02d}.amc" for trial in (3, 4, 6, 7, 8, 9, 10, 11))  # not 02, 05
DEMO_C3D = {"cmu_85_02.c3d": "JumpTwist", "HDM_bd_01-02_01_120.c3d": None}  # file -> description (label); None: no row
ACTORS = {"sample": 2, "demo": 4}


def main(argv: list[str] | None = None) -> None:
    """Parse the command line, build the sample archive and print a summary."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("which", nargs="?", choices=sorted(MAX_BYTES), default="sample")
    parser.add_argument("--source", type=Path, help="folder holding the shared .tar.xz archives")
    parser.add_argument("--output", type=Path, help="default: mocapviz/data/<which>.tar.xz")
    args = parser.parse_args(argv)
    source = args.source or _local_data_folder()
    output = args.output or REPO_ROOT / "mocapviz" / "data" / f"{args.which}.tar.xz"
    with tempfile.TemporaryDirectory() as scratch:
        members, readme_rows = _collect(args.which, source, Path(scratch))
        members[f"{args.which}/README.md"] = _readme(args.which, readme_rows).encode()
        members[f"{args.which}/LICENSE.md"] = _licence(args.which).encode()
        _write_tar(members, output)
    size = output.stat().st_size
    print(f"{output}: {len(members)} files, {size:,} bytes, sha256 {pooch.file_hash(str(output))}")
    if size > MAX_BYTES[args.which]:
        sys.exit(f"{output} is {size:,} bytes, over the {MAX_BYTES[args.which]:,} byte limit")


def _local_data_folder() -> Path:
    """The folder of the shared archives, as located by ``mocapviz.io.datasets`` (must be local)."""
    url = urllib.parse.urlparse(data_url())
    if url.scheme != "file":
        sys.exit(f"the archives must be in a local folder, not at {data_url()}: pass --source")
    return Path(urllib.request.url2pathname(url.path))


def _collect(which: str, source: Path, scratch: Path) -> tuple[dict[str, bytes], list[tuple[str, int, int]]]:
    """Unpack the archives into ``scratch`` and pick the files of ``which`` (sample or demo).

    Returns
    -------
    members : dict of str to bytes
        Archive member name -> file content.
    readme_rows : list of (member name, frames, fps)
        The motion files, for README.md.
    """
    members: dict[str, bytes] = {}
    readme_rows: list[tuple[str, int, int]] = []
    choose_cmu = _choose_cmu if which == "sample" else _choose_demo_cmu
    for name, choose in (("hdm05-cut", _choose_hdm05), ("cmu-asfamc", choose_cmu)):
        root = _unpack(source, name, scratch)
        table = pd.read_csv(root / "labels.tsv", sep="\t", dtype=str, keep_default_na=False)
        files = choose(table, root) if choose is choose_cmu else choose(table, ACTORS[which])
        members.update(_dataset_members(which, name, root, table, files))
        readme_rows += [(f"{name}/{f}", _amc_frames(root / f), int(fps)) for f, fps in _fps_of(table, files)]
    if which == "demo":
        root = _unpack(source, "c3d-markers", scratch)
        for file in DEMO_C3D:
            members[f"{which}/c3d-markers/{file}"] = (root / file).read_bytes()
            readme_rows.append((f"c3d-markers/{file}", *_c3d_frames(root / file)))
        rows = "".join(f"{file}\t{description}\n" for file, description in DEMO_C3D.items() if description)
        members[f"{which}/c3d-markers/labels.tsv"] = f"file\tdescription\n{rows}".encode()
    return members, readme_rows


def _unpack(source: Path, name: str, scratch: Path) -> Path:
    """Check the sha256 of ``<source>/<name>.tar.xz``, unpack it into ``scratch`` and return its top folder."""
    archive = ARCHIVES[name]
    path = source / archive.filename
    actual = pooch.file_hash(str(path))
    if actual != archive.sha256:
        sys.exit(f"{path}: sha256 {actual}, expected {archive.sha256}")
    with tarfile.open(path, "r:xz") as tar:
        tar.extractall(scratch, filter="data")
    return scratch / name


def _choose_hdm05(table: pd.DataFrame, n_actors: int) -> list[str]:
    """The shortest clip per (actor, class) of the ``n_actors`` complete actors with the fewest frames."""
    table = table.assign(frames=table["frames"].astype(int), take=table["take"].astype(int))
    shortest = table.sort_values(["frames", "take", "file"]).groupby(["actor", "class"]).head(1)
    n_classes = table["class"].nunique()
    per_actor = shortest.groupby("actor").agg(n=("class", "size"), frames=("frames", "sum")).reset_index()
    complete = per_actor[per_actor["n"] == n_classes].sort_values(["frames", "actor"])
    if len(complete) < n_actors:
        sys.exit(f"fewer than {n_actors} HDM05 actors have all {n_classes} classes")
    actors = complete["actor"].head(n_actors).tolist()
    chosen = shortest[shortest["actor"].isin(actors)]
    asf = [f"asf/HDM_{actor}.asf" for actor in actors]
    return sorted(asf) + sorted(chosen["file"])


def _choose_cmu(table: pd.DataFrame, root: Path) -> list[str]:
    """``131_01`` and the shortest martialwalk trial, with their ASF files."""
    candidates = sorted(root.glob(CMU_SHORTEST_OF))
    shortest = min(candidates, key=lambda p: (_amc_frames(p), p.name))
    return _with_asf(table, [*CMU_CLIPS, shortest.relative_to(root).as_posix()])


def _choose_demo_cmu(table: pd.DataFrame, root: Path) -> list[str]:
    """The demo's CMU trials (:data:`DEMO_CMU_CLIPS`) with their ASF files."""
    return _with_asf(table, list(DEMO_CMU_CLIPS))


def _with_asf(table: pd.DataFrame, clips: list[str]) -> list[str]:
    """The ASF files of CMU ``clips`` (from ``labels.tsv``), then the clips, each sorted."""
    rows = table[table["file"].isin(clips)]
    if len(rows) != len(clips):
        sys.exit(f"cmu-asfamc/labels.tsv lacks some of {', '.join(clips)}")
    return sorted(set(rows["asf"])) + sorted(clips)


def _dataset_members(top: str, name: str, root: Path, table: pd.DataFrame, files: list[str]) -> dict[str, bytes]:
    """The chosen files' bytes plus ``labels.tsv`` cut to their rows (original lines, original order), under
    ``<top>/<name>/``."""
    members = {f"{top}/{name}/{f}": (root / f).read_bytes() for f in files}
    lines = (root / "labels.tsv").read_bytes().splitlines(keepends=True)
    kept = [line for line in lines[1:] if line.split(b"\t", 1)[0].decode() in files]
    if len(kept) != sum(f.endswith(".amc") for f in files):
        sys.exit(f"{name}/labels.tsv does not have exactly one row per chosen clip")
    members[f"{top}/{name}/labels.tsv"] = b"".join([lines[0], *kept])
    return members


def _fps_of(table: pd.DataFrame, files: list[str]) -> list[tuple[str, str]]:
    """(file, fps) of the chosen motion files, in the order of ``files``."""
    fps = dict(zip(table["file"], table["fps"], strict=True))
    return [(f, fps[f]) for f in files if f in fps]


def _amc_frames(path: Path) -> int:
    """Number of frames of an AMC file: its lines holding only a frame number."""
    with path.open(encoding="latin-1") as lines:
        return sum(1 for line in lines if line.strip().isdigit())


def _c3d_frames(path: Path) -> tuple[int, int]:
    """(frames, rate in Hz) of a C3D file's point data, from its header."""
    import ezc3d

    header = ezc3d.c3d(str(path))["header"]["points"]
    return header["last_frame"] - header["first_frame"] + 1, round(header["frame_rate"])


def _readme(which: str, rows: list[tuple[str, int, int]]) -> str:
    """README.md: what the set is, and each motion file with its frame count."""
    total = sum(frames for _, frames, _ in rows)
    sources = "`hdm05-cut` and `cmu-asfamc`" if which == "sample" else "`hdm05-cut`, `cmu-asfamc` and `c3d-markers`"
    lines = [
        f"# mocapviz {which} data",
        "",
        f"Real motion-capture files, bytes unchanged, cut from the {sources} archives of",
        "`mocapviz.io.datasets` by `scripts/make_sample.py`. Each dataset keeps its own folder layout (`asf/`,",
        "`amc/`, `labels.tsv` restricted to the files here). Licences and attributions: `LICENSE.md`.",
        "",
        "| file | frames | fps |",
        "|---|---:|---:|",
        *(f"| {name} | {frames} | {fps} |" for name, frames, fps in rows),
        "",
        f"{len(rows)} motion files, {total} frames in total.",
        "",
    ]
    return "\n".join(lines)


def _licence(which: str) -> str:
    """LICENSE.md: the datasets' licences with their required attribution and citation."""
    lines = [f"# Licences of the {which} data", ""]
    for name in ("hdm05-cut", "cmu-asfamc"):
        archive = ARCHIVES[name]
        lines += [f"## `{name}/`", "", archive.licence, ""]
    if which == "demo":
        lines += [
            "## `c3d-markers/`",
            "",
            "`cmu_85_02.c3d`: CMU, as `cmu-asfamc/` above. `HDM_bd_01-02_01_120.c3d`: HDM05, as `hdm05-cut/` above.",
            "",
        ]
    lines += [
        "Provenance: HDM05 cut clips from GitHub zhangchi8620/JointLearning-HDM05 @ b252ad6; CMU trials from",
        "encadyma/motion-out @ 4855c55. Repackaged (flattened folders, one ASF per actor, label tables added);",
        "file contents unchanged.",
    ]
    if which == "demo":
        lines += [
            "C3D takes: `cmu_85_02.c3d` from numediart/MocapRecovery @ 8b18571 (`data/85_02.c3d`),",
            "`HDM_bd_01-02_01_120.c3d` from Mohaoui-S/Tucker_MoCap @ aeeab9b; bytes unchanged.",
        ]
    return "\n".join([*lines, ""])


def _write_tar(members: dict[str, bytes], output: Path) -> None:
    """Write a deterministic ``.tar.xz`` (sorted names, mtime 0, root owner, fixed modes) atomically."""
    output.parent.mkdir(parents=True, exist_ok=True)
    names = sorted(set(members) | _folders(members))
    tmp = output.with_name(f".{output.name}.tmp")
    with tarfile.open(tmp, "w:xz", preset=9, format=tarfile.USTAR_FORMAT) as tar:
        for name in names:
            info = tarfile.TarInfo(name)
            info.mtime, info.uid, info.gid, info.uname, info.gname = 0, 0, 0, "root", "root"
            if name in members:
                info.mode, info.size = 0o644, len(members[name])
                tar.addfile(info, io.BytesIO(members[name]))
            else:
                info.type, info.mode = tarfile.DIRTYPE, 0o755
                tar.addfile(info)
    os.replace(tmp, output)


def _folders(members: dict[str, bytes]) -> set[str]:
    """Every folder above the members, as tar names."""
    return {parent.as_posix() for name in members for parent in Path(name).parents if parent != Path(".")}


if __name__ == "__main__":
    main()
