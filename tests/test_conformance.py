"""The conformance table of docs/conformance.md holds for every file of the ``peer-readers`` archive: files other
tools wrote (BVH, C3D, FBX). Each row says what ``mocapviz.load`` makes of the file (loads, loads with a warning, or
refused, and why), how many joints or markers, frames and rate, and whether ``Motion.canonical()`` maps it to the 24
canonical joints (and if not, why). This test computes every row afresh and compares: the table cannot drift from
the readers. The expected frame counts and rates are also those of the archive's MANIFEST.md (each taken from the
file's own header or its source project's tests, not from mocapviz): ``test_the_table_agrees_with_the_manifest``.

``python tests/test_conformance.py`` prints the rows as computed now (to update the page after a reader changes).
Skipped, with the reason, without ``../shared``.
"""

from __future__ import annotations

import re
import sys
import warnings
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parent.parent / "docs" / "conformance.md"
COLUMNS = ["file", "loads", "joints or markers", "frames", "rate (Hz)", "canonical skeleton"]


def outcome(path: Path) -> dict:
    """One row of the table, computed: what loading ``path`` and mapping it give.

    Cells: ``loads`` is ``yes``, ``yes, warning: <message>`` or ``refused: <message>``; ``canonical skeleton`` is
    ``maps`` or ``no: <message>``; the messages without the file's path.
    """
    from mocapviz import load
    from mocapviz.errors import MocapvizError

    def said(exc_or_warning) -> str:
        text = str(exc_or_warning)
        return text.split(": ", 1)[1] if text.startswith(str(path)) else text

    row = {"file": f"{path.parent.name}/{path.name}"}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            motion = load(path)
        except MocapvizError as exc:
            return row | {"loads": f"refused: {said(exc)}", "joints or markers": "", "frames": "", "rate (Hz)": "",
                          "canonical skeleton": ""}
    noted = [said(w.message) for w in caught if issubclass(w.category, UserWarning)]
    row["loads"] = f"yes, warning: {noted[0]}" if noted else "yes"
    row["joints or markers"] = str(len(motion.joint_names))
    row["frames"] = f"{motion.n_frames:,}"
    row["rate (Hz)"] = f"{motion.fps:g}"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            motion.canonical()
        row["canonical skeleton"] = "maps"
    except MocapvizError as exc:
        row["canonical skeleton"] = f"no: {said(exc)}"
    return row


def page_rows() -> list[dict]:
    """The table of docs/conformance.md, a dict per row (cells stripped, backticks removed)."""
    lines = [line for line in PAGE.read_text(encoding="utf-8").splitlines() if line.startswith("| ")]
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    assert header == COLUMNS, header
    return [dict(zip(header, (c.strip().replace("`", "") for c in line.strip("|").split("|")))) for line in lines[1:]]


def agrees(written: str, computed: str) -> bool:
    """A cell of the page agrees with the computed one: equal to its first line, or the page's words (``…`` ending a
    cut message) the start of that line."""
    computed = computed.splitlines()[0] if computed else computed
    if written.endswith("…"):
        return computed.startswith(written[:-1].rstrip())
    return written == computed


@pytest.fixture(scope="module")
def peer_files(fetch_archive) -> list[Path]:
    folder = fetch_archive("peer-readers")
    return sorted(p for sub in ("bvh", "c3d", "fbx") for p in (folder / sub).iterdir())


def test_the_table_names_every_peer_file_once(peer_files):
    assert [r["file"] for r in page_rows()] == [f"{p.parent.name}/{p.name}" for p in peer_files]


def test_every_row_is_what_the_readers_do(peer_files):
    for path, written in zip(peer_files, page_rows()):
        computed = outcome(path)
        for column in COLUMNS[1:]:
            assert agrees(written[column], computed[column]), (written["file"], column, computed[column])


def test_the_table_agrees_with_the_manifest(peer_files):
    """Every file that loads has a frame count and a rate (or frame time, within 0.1 %) its MANIFEST.md row states
    (the file's header, or its source project's own test expectations); the rate where the row states one."""
    manifest = (peer_files[0].parent.parent / "MANIFEST.md").read_text(encoding="utf-8")
    for row in page_rows():
        if not row["frames"]:
            continue
        name = row["file"].split("/")[1]
        line = next(line for line in manifest.splitlines() if line.startswith(f"| {name} |"))
        numbers = [float(n) for n in re.findall(r"\d+(?:\.\d+)?", line.replace(",", "")) if float(n) > 0]
        assert int(row["frames"].replace(",", "")) in numbers, (name, row["frames"])
        if not re.search(r"Hz|fps|Frame Time", line):  # the sausage twins: "same scene" as the row that says it
            continue
        rate = float(row["rate (Hz)"])  # stated as a rate or as a frame time
        assert any(abs(n - rate) < 1e-3 * rate or abs(1 / n - rate) < 1e-3 * rate for n in numbers), (name, rate)


if __name__ == "__main__":  # the rows as computed now, for the page
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from conftest import _fetch

    folder = _fetch("peer-readers")
    print("| " + " | ".join(COLUMNS) + " |")
    print("|" + "---|" * len(COLUMNS))
    for p in sorted(p for sub in ("bvh", "c3d", "fbx") for p in (folder / sub).iterdir()):
        r = outcome(p)
        cells = [r[c].splitlines()[0] if r[c] else "" for c in COLUMNS[1:]]
        cells = [c if len(c) <= 110 else c[:100].rstrip() + " …" for c in cells]  # a message's start, then …
        print("| " + " | ".join([f"`{r['file']}`", *cells]) + " |")
