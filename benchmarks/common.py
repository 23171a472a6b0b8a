"""What the benchmarks share: the machine description, CPU-use monitor, markdown tables, and the benchmark
MotionDB built once from the shared real archives and cached.

benchmark_db(spec, quick)   the cached database of a :class:`BenchDB` spec and its build record: the archives
                            ingested at the spec's rate; if they hold fewer frames than ``min_frames``,
                            left/right MIRRORED copies (``mocapviz.motion.skeleton.mirror``) of the documents of
                            ``mirror_archives`` are appended (``MotionDB.append_motions``), round after round (with
                            ``BenchDB.stretches``: mirrored, then time-stretched copies, :func:`add_variants`);
                            from the second round on they repeat frames already present. ``describe_db`` says so.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
ARCHIVES = ("hdm05-cut", "cmu-asfamc", "bandai-namco-1", "bandai-namco-2")
INGEST_THREADS = 2  # threads reading the files (MotionDB.ingest)


# ============================================================================ machine and output
def machine_info() -> dict:
    info = {}
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text()
        models = [ln.split(":", 1)[1].strip() for ln in cpuinfo.splitlines() if ln.startswith("model name")]
        info["cpu"] = models[0] if models else platform.processor() or "?"
        fam = [ln.split(":", 1)[1].strip() for ln in cpuinfo.splitlines() if ln.startswith(("cpu family", "model\t"))]
        if len(fam) >= 2:
            info["cpu"] += f" (family {fam[0]} model {fam[1]})"
        if " hypervisor" in cpuinfo:
            info["cpu"] += ", virtual machine"
    except OSError:
        info["cpu"] = platform.processor() or "?"
    info["cores"] = os.cpu_count()
    try:
        info["usable_cores"] = len(os.sched_getaffinity(0))
    except AttributeError:
        info["usable_cores"] = os.cpu_count()
    try:
        mem = next(ln for ln in Path("/proc/meminfo").read_text().splitlines() if ln.startswith("MemTotal"))
        info["ram_gib"] = round(int(mem.split()[1]) / 2**20, 1)
    except (OSError, StopIteration):
        info["ram_gib"] = None
    info["os"] = platform.platform()
    info["python"] = platform.python_version()
    for pkg in ("numpy", "numba", "scipy", "bvh", "pykdtree", "mocapviz"):
        try:
            info[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            info[pkg] = "not installed"
    try:
        info["commit"] = (
            subprocess.run(
                ["git", "rev-parse", "--short", "HEAD"],
                check=False,
                cwd=Path(__file__).resolve().parent,
                capture_output=True,
                text=True,
                timeout=10,
            ).stdout.strip()
            or "?"
        )
        # read-only: does the working tree of the measured code differ from the commit?
        dirty = subprocess.run(
            ["git", "diff", "--quiet", "HEAD", "--", "mocapviz"],
            check=False,
            cwd=Path(__file__).resolve().parent.parent,
            capture_output=True,
            timeout=10,
        ).returncode
        if dirty == 1:
            info["commit"] += " + uncommitted changes in mocapviz/"
    except (OSError, subprocess.SubprocessError):
        info["commit"] = "?"
    import multiprocessing

    info["start_method"] = multiprocessing.get_start_method()
    info["load_start"] = loadavg()
    return info


def package_version(name: str) -> str:
    """The installed version of a baseline package, or a note saying how to install it."""
    from importlib import metadata

    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return f"not installed (pip install {name} to compare)"


def loadavg() -> str:
    try:
        return " ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "?"


def header(title: str, info: dict, software: tuple[str, ...], notes: list[str]) -> str:
    """The markdown head of a benchmark's output: title; date and commit; CPU; OS with Python and the versions of
    ``software`` (keys of ``info``); the load average at the start (and now) with what other processes used; then
    the benchmark's own ``notes`` (one bullet each)."""
    versions = ", ".join([f"Python {info['python']}"] + [f"{name} {info[name]}" for name in software])
    return "\n".join([
        title, "",
        f"- date: {time.strftime('%Y-%m-%dT%H:%M:%S')}, mocapviz {info['mocapviz']} @ {info['commit']}",
        f"- CPU: {info['cpu']}, {info['cores']} cores ({info['usable_cores']} usable), RAM {info['ram_gib']} GiB",
        f"- {info['os']}; {versions}",
        f"- load average (1/5/15 min) at start: {info['load_start']}, at end: {loadavg()}; {info.get('others', '')}",
        *(f"- {note}" for note in notes),
    ])  # fmt: skip


class CpuMonitor:
    """CPU time the rest of the machine used while the benchmark ran (/proc/stat busy time minus ours)."""

    def __init__(self):
        self.t0, self.stat0, self.ours0 = time.perf_counter(), self._stat(), self._ours()

    @staticmethod
    def _stat() -> tuple[float, float] | None:
        """Busy time (user, nice, system, irq, softirq) and steal time of all CPUs, seconds."""
        try:
            f = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
        except (OSError, ValueError):
            return None
        tick = os.sysconf("SC_CLK_TCK")
        busy = f[0] + f[1] + f[2] + (f[5] + f[6] if len(f) > 6 else 0)
        return busy / tick, (f[7] if len(f) > 7 else 0) / tick

    @staticmethod
    def _ours() -> float:
        t = os.times()
        return t.user + t.system + t.children_user + t.children_system

    def report(self) -> str:
        stat = self._stat()
        if stat is None or self.stat0 is None:
            return "CPU use of other processes: unknown"
        wall = time.perf_counter() - self.t0
        others = max(0.0, (stat[0] - self.stat0[0]) - (self._ours() - self.ours0))
        steal = stat[1] - self.stat0[1]
        text = (
            f"other processes used {others:.0f} CPU-s during the {wall:.0f} s run ({others / wall:.2f} cores on "
            f"average), hypervisor steal {steal:.0f} s"
        )
        if (others + steal) / wall > 0.2:
            text += " — the machine was shared: figures, 2-process ones most, are noisy"
        return text


def fmt(v, digits: int = 2) -> str:
    """A table cell: "—" for None / non-finite, thousands separators for ints and values >= 1000."""
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "—"
    if isinstance(v, (int, np.integer)):
        return f"{v:,}"
    return f"{v:,.0f}" if abs(v) >= 1000 else f"{v:.{digits}f}"


def write_results_csv(path: Path, sections: dict, info: dict, keys=("cpu", "python", "numpy", "commit")) -> None:
    """One CSV of a benchmark's tables: {section name: DataFrame} stacked with a ``section`` column first, plus
    the ``keys`` of the machine description on every row. The results folder keeps its CSVs out of git."""
    import pandas as pd

    path.parent.mkdir(parents=True, exist_ok=True)
    ignore = path.parent / ".gitignore"
    if not ignore.exists():
        ignore.write_text("*.csv\n")
    out = pd.concat([t.assign(section=name) for name, t in sections.items()], ignore_index=True)
    for k in keys:
        out[k] = info[k]
    out.insert(0, "section", out.pop("section"))
    out.to_csv(path, index=False)


def markdown(header: str, align: str, lines) -> str:
    """A markdown table: the header and alignment rows, then one row per list of cell strings."""
    return "\n".join([header, align] + ["| " + " | ".join(cells) + " |" for cells in lines])


def log(msg: str) -> None:
    print(f"[bench] {msg}", file=sys.stderr, flush=True)


def fetch(name: str):
    from mocapviz.io import datasets

    try:
        return datasets.fetch(name), None
    except Exception as exc:  # noqa: BLE001 - any failure: skip the row with a note
        return None, f"{type(exc).__name__}: {exc}"




# ============================================================================ the benchmark database
@dataclass(frozen=True)
class BenchDB:
    """What a benchmark database is built from.

    tag : str                  cache folder name under ``<repo>/.cache/bench/``; change it to rebuild
    fps : float                every document resampled to this rate at ingest
    min_frames : int           mirrored copies are appended until the database holds this many frames
    mirror_archives : tuple    the archives whose documents are mirrored
    archives : tuple           the shared archives ingested
    quick_files : dict         files per archive in a --quick run (0: archive left out), evenly spaced
    stretches : tuple          if given, copies are added by :func:`add_variants` instead of
                               :func:`add_mirrored`: mirrored copies first, then TIME-STRETCHED copies
                               (original and mirrored, slowed down by each factor in turn), no repeats
    quick_min_frames : int     frames to reach in a --quick run (0: no copies added in quick runs)
    chunk_frames : int         derived frames appended per commit (:func:`add_variants`); larger chunks rewrite
                               the growing arrays fewer times (each commit writes a new generation) at more RAM
    """

    tag: str
    fps: float
    min_frames: int = 1_000_000
    mirror_archives: tuple = ARCHIVES
    archives: tuple = ARCHIVES
    quick_files: dict = field(default_factory=lambda: {"hdm05-cut": 40, "cmu-asfamc": 4, "bandai-namco-1": 10,
                                                       "bandai-namco-2": 0})  # fmt: skip
    stretches: tuple = ()
    quick_min_frames: int = 0
    chunk_frames: int = 500_000


def _source_files(spec: BenchDB, quick: bool) -> tuple[dict, list[str]]:
    """{archive: [files]} of the archives that could be fetched, and notes on the ones that could not."""
    from mocapviz.db.ingest import expand_paths

    files, notes = {}, []
    for name in spec.archives:
        n_quick = spec.quick_files.get(name, 0)
        if quick and not n_quick:
            continue
        root, err = fetch(name)
        if root is None:
            notes.append(f"{name} missing ({err})")
            continue
        found = expand_paths(root)
        if quick:
            found = found[:: max(1, len(found) // n_quick)][:n_quick]
        files[name] = [str(f) for f in found]
    return files, notes


def _archive_of(db, archives) -> np.ndarray:
    """The shared archive each document's source file belongs to ("" if none), by path prefix."""
    out = np.full(len(db.documents), "", dtype=object)
    for name in archives:
        root, _ = fetch(name)
        if root is not None:
            out[db.documents["path"].str.startswith(str(Path(root).resolve())).to_numpy()] = name
    return out


def add_mirrored(db, archives, need: int) -> dict:
    """Append left/right mirrored copies of the documents of ``archives`` until ``db`` holds ``need`` frames.

    Round 1 mirrors each document once (in database order); later rounds repeat the mirrored copies (exact
    duplicates of frames already present). Returns the reopened database and {"documents", "frames",
    "repeated_frames"} added.
    """
    from mocapviz.motion.skeleton import mirror

    docs = db.documents[np.isin(_archive_of(db, archives), archives)]
    motions, metas, frames, repeated, round_ = [], [], db.n_frames, 0, 0
    while frames < need and len(docs):
        round_ += 1
        for row in docs.itertuples():
            if frames >= need:
                break
            m = mirror(db.motion(int(row.doc_id)))
            motions.append(m)
            metas.append({"name": f"{row.name}_mirror{round_}", "path": row.path, "format": row.format,
                          "source_fps": row.source_fps, "sha256": f"mirror{round_}-{row.sha256}",
                          "mirror_of": int(row.doc_id)})  # fmt: skip
            frames += m.n_frames
            repeated += m.n_frames if round_ > 1 else 0
    added = {"documents": len(motions), "frames": frames - db.n_frames, "repeated_frames": repeated}
    return db.append_motions(motions, metas), added


def stretched(motion, factor: float):
    """The clip slowed down by ``factor`` at the same frame rate: resampled to ``factor`` x its rate
    (``Motion.resample``: linear positions, slerp rotations), then relabelled with the original rate."""
    from dataclasses import replace

    return replace(motion.resample(motion.fps * factor), fps=motion.fps)


def on_source_frames(n_out: int, factor: float) -> int:
    """Frames of a clip of ``n_out`` frames stretched by ``factor`` that fall exactly on a source frame (equal to
    it): output frame k is at source time k / factor, an integer when k is a multiple of p, factor = p / q."""
    from fractions import Fraction

    p = Fraction(factor).limit_denominator(1000).numerator
    return (n_out - 1) // p + 1 if n_out else 0


def add_variants(db, archives, need: int, stretches, chunk_frames: int = 500_000) -> tuple:
    """Append derived copies of the documents of ``archives`` until ``db`` holds ``need`` frames, in rounds:
    round 1 a left/right mirrored copy of each document; then for each factor s of ``stretches``, the original
    and its mirror image slowed down by s (:func:`stretched`: new, interpolated frames, a slower performance of
    the same motion). A stretched frame whose time falls exactly on a source frame equals that frame of the
    original or of the mirror image (every 11th frame at s = 1.1, every 6th at 1.2: :func:`on_source_frames`);
    these are counted as ``repeated_frames``; all other frames are new. Appended in chunks of ``chunk_frames``
    (``MotionDB.append_motions``) to bound memory.

    Returns the reopened database and {"documents", "frames", "repeated_frames", "rounds": {name: frames}}.
    """
    from mocapviz.motion.skeleton import mirror

    chunk_size = chunk_frames
    docs = db.documents[np.isin(_archive_of(db, archives), archives)]
    rounds = [("mirrored", False, 1.0)]
    for s in stretches:
        rounds += [(f"stretched x{s:g}", False, s), (f"mirrored + stretched x{s:g}", True, s)]
    frames, added_docs, per_round, chunk, chunk_frames, repeated = db.n_frames, 0, {}, ([], []), 0, 0
    for i, (name, mirrored, factor) in enumerate(rounds):
        if frames >= need:
            break
        for row in docs.itertuples():
            if frames >= need:
                break
            m = db.motion(int(row.doc_id))
            if i == 0 or mirrored:
                m = mirror(m)
            if factor != 1.0:
                m = stretched(m, factor)
                repeated += on_source_frames(m.n_frames, factor)
            chunk[0].append(m)
            chunk[1].append({"name": f"{row.name}_v{i}", "path": row.path, "format": row.format,
                             "source_fps": row.source_fps, "sha256": f"v{i}-{row.sha256}",
                             "mirror_of": int(row.doc_id), "variant": name})  # fmt: skip
            frames += m.n_frames
            chunk_frames += m.n_frames
            per_round[name] = per_round.get(name, 0) + m.n_frames
            added_docs += 1
            if chunk_frames >= chunk_size:
                db = db.append_motions(*chunk)
                chunk, chunk_frames = ([], []), 0
                log(f"  {frames:,} frames")
    if chunk[0]:
        db = db.append_motions(*chunk)
    added = {"documents": added_docs, "frames": sum(per_round.values()), "repeated_frames": repeated,
             "rounds": per_round}
    return db, added


def benchmark_db(spec: BenchDB, quick: bool):
    """The cached benchmark MotionDB of ``spec`` and its build record (ingest seconds, sources, mirrored copies).

    Built under a temporary name and renamed into place, so an interrupted build is never taken for a database.
    """
    from mocapviz.db.database import MotionDB
    from mocapviz.errors import MotionDBError

    folder = REPO / ".cache" / "bench" / (spec.tag + ("-quick" if quick else ""))
    record_file = folder / "build.json"
    if record_file.is_file():
        try:
            db = MotionDB.open(folder / "db")
            record = json.loads(record_file.read_text())
            if record.get("n_frames") == db.n_frames:
                return db, record | {"cached": True}
        except (MotionDBError, ValueError, OSError) as exc:
            log(f"cached benchmark database unusable ({exc}); rebuilding")
    files, missing = _source_files(spec, quick)
    if not files:
        raise RuntimeError("no shared archive could be fetched: " + "; ".join(missing))
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("db.tmp-*"):  # left by an interrupted build
        shutil.rmtree(old)
    tmp = folder / f"db.tmp-{os.getpid()}"
    all_files = [f for fs in files.values() for f in fs]
    log(f"building the benchmark database: {len(all_files)} files at {spec.fps:g} Hz, threads={INGEST_THREADS} -> {folder}")
    t0 = time.perf_counter()
    db = MotionDB.ingest(all_files, tmp, fps=spec.fps, threads=INGEST_THREADS, progress=False)
    t_ingest = time.perf_counter() - t0
    log(f"  ingest {t_ingest:.1f} s, {db.n_frames:,} frames")
    real_frames = db.n_frames
    mirrored = {"documents": 0, "frames": 0, "repeated_frames": 0}
    need = spec.quick_min_frames if quick else spec.min_frames
    if spec.stretches and db.n_frames < need:
        db, mirrored = add_variants(db, spec.mirror_archives, need, spec.stretches, spec.chunk_frames)
        log(f"  added {mirrored['documents']:,} mirrored / time-stretched documents, {mirrored['frames']:,} frames")
    elif db.n_frames < spec.min_frames and not quick:
        db, mirrored = add_mirrored(db, spec.mirror_archives, spec.min_frames)
        log(f"  added {mirrored['documents']:,} mirrored documents, {mirrored['frames']:,} frames")
    if (folder / "db").exists():
        shutil.rmtree(folder / "db")
    tmp.rename(folder / "db")
    db = MotionDB.open(folder / "db")
    record = {
        "tag": spec.tag, "t_ingest": t_ingest, "threads": INGEST_THREADS, "fps": spec.fps,
        "files": {k: len(v) for k, v in files.items()}, "missing": missing, "real_frames": real_frames,
        "mirrored_documents": mirrored["documents"], "mirrored_frames": mirrored["frames"],
        "repeated_frames": mirrored["repeated_frames"],
        "n_frames": db.n_frames, "n_documents": len(db), "built": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "variant_frames": mirrored.get("rounds", {}), "min_frames": need if spec.stretches else spec.min_frames,
    }  # fmt: skip
    record_file.write_text(json.dumps(record, indent=2))
    return db, record | {"cached": False}


def _on_source_text(variant_frames: dict) -> str:
    """"every 11th at s = 1.1, 6th at 1.2": which stretched frames fall on a source frame, per factor used."""
    from fractions import Fraction

    factors = sorted({float(k.rsplit("x", 1)[1]) for k in variant_frames if "stretched x" in k})
    parts = [f"every {Fraction(s).limit_denominator(1000).numerator}th at s = {s:g}" for s in factors]
    return ", ".join(parts) or "none stretched"


def ingest_how(record: dict) -> str:
    """How the benchmark database of ``record`` was read: ``threads=N``, or ``n_jobs=N`` (reader processes) for a
    database cached before ingest ran on threads."""
    return f"threads={record['threads']}" if "threads" in record else f"n_jobs={record['n_jobs']} (processes)"


def describe_db(db, record: dict) -> list[str]:
    """Lines saying what a benchmark database holds: real documents and frames per archive (with their native
    rates when resampled), mirrored and repeated copies, missing archives, the ingest time."""
    docs = db.documents
    fps = record["fps"]
    real = ~docs["format"].eq("memory").to_numpy()
    if "mirror_of" in docs:  # mirrored copies keep their original's format and path
        real &= docs["mirror_of"].isna().to_numpy()
    archive = _archive_of(db, list(record["files"]))
    parts = []
    for name in record["files"]:
        sel = real & (archive == name)
        native = sorted(set(docs.loc[sel, "source_fps"].round(1)))
        rate = "/".join(f"{r:g}" for r in native)
        note = f", resampled {rate} → {fps:g} Hz" if native and native != [fps] else ""
        parts.append(f"{name} {int(sel.sum())} documents, {int(docs.loc[sel, 'n_frames'].sum()):,} frames{note}")
    lines = [f"benchmark database: {len(db):,} documents, {db.n_frames:,} frames at {fps:g} Hz "
             f"({db.n_frames / fps / 3600:.1f} h); real: {record['real_frames']:,} frames — " + "; ".join(parts)]
    if record.get("variant_frames"):
        lines.append(
            f"**{record['mirrored_documents']:,} derived documents** ({record['mirrored_frames']:,} frames) were "
            f"appended to reach {record['min_frames']:,} frames: left/right MIRRORED copies "
            "(`mocapviz.motion.skeleton.mirror`), then TIME-STRETCHED copies of the originals and of their mirror images "
            f"(`Motion.resample` to s × {fps:g} Hz, relabelled {fps:g} Hz: the same motion performed s times "
            "slower, linearly interpolated positions / slerped rotations). Frames per kind: "
            + "; ".join(f"{k} {v:,}" for k, v in record["variant_frames"].items())
            + f". Of the stretched frames, **{record['repeated_frames']:,} fall exactly on a source frame** "
            f"({_on_source_text(record['variant_frames'])}) and so duplicate a frame of the original or of its "
            "mirror image; every other frame is new"
        )
    elif record["mirrored_documents"]:
        lines.append(
            f"**{record['mirrored_documents']:,} left/right MIRRORED copies** of real documents "
            f"({record['mirrored_frames']:,} frames, `mocapviz.motion.skeleton.mirror`) were appended to reach "
            f"{record['min_frames']:,} frames"
            + (f"; of these, **{record['repeated_frames']:,} frames repeat a mirrored copy** (second round: exact "
               "duplicates of frames already in the database)" if record["repeated_frames"] else "")
        )  # fmt: skip
    elif db.n_frames >= record["min_frames"]:
        lines.append(f"no mirrored copies: the real data alone exceed {record['min_frames']:,} frames")
    else:
        lines.append("quick run: a small database, far from the paper's scale; no mirrored copies")
    if record["missing"]:
        lines.append("missing archives: " + "; ".join(record["missing"]))
    cached = " (database from the cache; measured when it was built)" if record["cached"] else ""
    lines.append(f"MotionDB.ingest of the {sum(record['files'].values())} source files at {fps:g} Hz, "
                 f"{ingest_how(record)}: {record['t_ingest']:.1f} s{cached}")  # fmt: skip
    return lines
