"""Build ``mocapviz/data/sample.tar.xz``, the small real-data sample shipped inside the package.

Usage::

    python scripts/make_sample.py [--source FOLDER] [--output FILE]

``--source`` is the folder holding the shared archives (default: where ``mocapviz.io.datasets`` finds them).
The sample holds real files with unchanged bytes:

- ``sample/hdm05-cut/``: two actors x all 11 classes x one clip each (22 AMC clips), the two actors' ASF files
  and ``labels.tsv`` restricted to those rows. Per actor and class the shortest clip is taken (ties: lowest
  take); the two actors with the fewest frames in total over their 11 clips are kept.
- ``sample/cmu-asfamc/``: ``amc/mjackson/131_01.amc`` and the shortest ``amc/martialwalk/135_*.amc``, their
  ASF files and the matching rows of ``labels.tsv``.
- ``sample/LICENSE.md`` (licences and attributions) and ``sample/README.md`` (files and frame counts).

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

TOP = "sample"
MAX_BYTES = 5 * 1024 * 1024
CMU_CLIPS = ("amc/mjackson/131_01.amc",)
CMU_SHORTEST_OF = "amc/martialwalk/135_*.amc"


def main(argv: list[str] | None = None) -> None:
    """Parse the command line, build the sample archive and print a summary."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--source", type=Path, help="folder holding hdm05-cut.tar.xz and cmu-asfamc.tar.xz")
    parser.add_argument("--output", type=Path, default=REPO_ROOT / "mocapviz" / "data" / "sample.tar.xz")
    args = parser.parse_args(argv)
    source = args.source or _local_data_folder()
    with tempfile.TemporaryDirectory() as scratch:
        members, readme_rows = _collect(source, Path(scratch))
        members[f"{TOP}/README.md"] = _readme(readme_rows).encode()
        members[f"{TOP}/LICENSE.md"] = _licence().encode()
        _write_tar(members, args.output)
    size = args.output.stat().st_size
    print(f"{args.output}: {len(members)} files, {size:,} bytes, sha256 {pooch.file_hash(str(args.output))}")
    if size > MAX_BYTES:
        sys.exit(f"{args.output} is {size:,} bytes, over the {MAX_BYTES:,} byte limit")


def _local_data_folder() -> Path:
    """The folder of the shared archives, as located by ``mocapviz.io.datasets`` (must be local)."""
    url = urllib.parse.urlparse(data_url())
    if url.scheme != "file":
        sys.exit(f"the archives must be in a local folder, not at {data_url()}: pass --source")
    return Path(urllib.request.url2pathname(url.path))


def _collect(source: Path, scratch: Path) -> tuple[dict[str, bytes], list[tuple[str, int, int]]]:
    """Unpack both archives into ``scratch`` and pick the sample's files.

    Returns
    -------
    members : dict of str to bytes
        Archive member name -> file content.
    readme_rows : list of (member name, frames, fps)
        The motion files, for README.md.
    """
    members: dict[str, bytes] = {}
    readme_rows: list[tuple[str, int, int]] = []
    for name, choose in (("hdm05-cut", _choose_hdm05), ("cmu-asfamc", _choose_cmu)):
        root = _unpack(source, name, scratch)
        table = pd.read_csv(root / "labels.tsv", sep="\t", dtype=str, keep_default_na=False)
        files = choose(table, root)
        members.update(_dataset_members(name, root, table, files))
        readme_rows += [(f"{name}/{f}", _amc_frames(root / f), int(fps)) for f, fps in _fps_of(table, files)]
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


def _choose_hdm05(table: pd.DataFrame, root: Path) -> list[str]:
    """22 clips: the shortest clip per (actor, class) of the two complete actors with the fewest frames."""
    table = table.assign(frames=table["frames"].astype(int), take=table["take"].astype(int))
    shortest = table.sort_values(["frames", "take", "file"]).groupby(["actor", "class"]).head(1)
    n_classes = table["class"].nunique()
    per_actor = shortest.groupby("actor").agg(n=("class", "size"), frames=("frames", "sum")).reset_index()
    complete = per_actor[per_actor["n"] == n_classes].sort_values(["frames", "actor"])
    if len(complete) < 2:
        sys.exit(f"fewer than two HDM05 actors have all {n_classes} classes")
    actors = complete["actor"].head(2).tolist()
    chosen = shortest[shortest["actor"].isin(actors)]
    asf = [f"asf/HDM_{actor}.asf" for actor in actors]
    return sorted(asf) + sorted(chosen["file"])


def _choose_cmu(table: pd.DataFrame, root: Path) -> list[str]:
    """``131_01`` and the shortest martialwalk trial, with their ASF files."""
    candidates = sorted(root.glob(CMU_SHORTEST_OF))
    shortest = min(candidates, key=lambda p: (_amc_frames(p), p.name))
    clips = [*CMU_CLIPS, shortest.relative_to(root).as_posix()]
    rows = table[table["file"].isin(clips)]
    return sorted(set(rows["asf"])) + sorted(clips)


def _dataset_members(name: str, root: Path, table: pd.DataFrame, files: list[str]) -> dict[str, bytes]:
    """The chosen files' bytes plus ``labels.tsv`` cut to their rows (original lines, original order)."""
    members = {f"{TOP}/{name}/{f}": (root / f).read_bytes() for f in files}
    lines = (root / "labels.tsv").read_bytes().splitlines(keepends=True)
    kept = [line for line in lines[1:] if line.split(b"\t", 1)[0].decode() in files]
    if len(kept) != sum(f.endswith(".amc") for f in files):
        sys.exit(f"{name}/labels.tsv does not have exactly one row per chosen clip")
    members[f"{TOP}/{name}/labels.tsv"] = b"".join([lines[0], *kept])
    return members


def _fps_of(table: pd.DataFrame, files: list[str]) -> list[tuple[str, str]]:
    """(file, fps) of the chosen motion files, in the order of ``files``."""
    fps = dict(zip(table["file"], table["fps"], strict=True))
    return [(f, fps[f]) for f in files if f in fps]


def _amc_frames(path: Path) -> int:
    """Number of frames of an AMC file: its lines holding only a frame number."""
    with path.open(encoding="latin-1") as lines:
        return sum(1 for line in lines if line.strip().isdigit())


def _readme(rows: list[tuple[str, int, int]]) -> str:
    """README.md: what the sample is, and each motion file with its frame count."""
    total = sum(frames for _, frames, _ in rows)
    lines = [
        "# mocapviz sample data",
        "",
        "Real motion-capture files, bytes unchanged, cut from the `hdm05-cut` and `cmu-asfamc` archives of",
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


def _licence() -> str:
    """LICENSE.md: the two datasets' licences with their required attribution and citation."""
    lines = ["# Licences of the sample data", ""]
    for name in ("hdm05-cut", "cmu-asfamc"):
        archive = ARCHIVES[name]
        lines += [f"## `{name}/`", "", archive.licence, ""]
    lines += [
        "Provenance: HDM05 cut clips from GitHub zhangchi8620/JointLearning-HDM05 @ b252ad6; CMU trials from",
        "encadyma/motion-out @ 4855c55. Repackaged (flattened folders, one ASF per actor, label tables added);",
        "file contents unchanged.",
        "",
    ]
    return "\n".join(lines)


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
