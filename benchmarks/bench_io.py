"""Reader and ingest benchmarks: mocapviz beside plain-Python / PyPI baselines, on the shared archives.

1. Parse + forward kinematics of ASF/AMC (all 287 HDM05 cut clips): ``mocapviz.io.load`` against a plain
   Python ASF/AMC reader written here (lines split into a dict of bone -> values per frame, then numpy forward
   kinematics vectorised over frames per bone with ``scipy.spatial.transform.Rotation`` matrices).
2. Parse + forward kinematics of BVH (all of Bandai Namco 1 and the first 500 files of Bandai Namco 2, sorted):
   ``mocapviz.io.load`` against the ``bvh`` package from PyPI for parsing plus the same kind of numpy/scipy
   forward kinematics.
3. ``MotionDB.ingest`` of all the shared archives with ``threads=1`` and ``threads=2`` (reader threads).
4. The large reproducers of ``../shared/reliability/big.tar.xz`` (1M-frame BVH and AMC, 20,000-joint rigs, a
   10,000-bone ASF chain) and an HDM05 clip tiled to 200,000 frames: what ``MotionDB.ingest`` does with each file,
   ``load`` → ``canonical`` → ``resample`` to 30 and to 120 fps, in a fresh process; wall and CPU time and peak RSS
   of each step against the arrays returned (``python -m benchmarks.bench_io --large`` runs only this part). The
   1M-frame AMC holds frame numbers only, which its skeleton refuses (its row: the memory until then); it is also
   read on that skeleton without DOFs (:func:`without_dofs`), where its frames are complete.

Each reader figure is the median wall time of ``repeats`` runs (frames/s = frames / median time), measured in
one process and over a pool of 2 worker processes (``concurrent.futures.ProcessPoolExecutor``, one task per
file, pool start-up and shut-down included, workers return the frame count). Before timing, each baseline's
positions are checked against mocapviz's on one file, so both sides do the same work.
"""

from __future__ import annotations

import csv
import datetime as _dt
import itertools
import json
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from .common import REPO, CpuMonitor, fetch, log, machine_info, markdown

TARGET_AMC = 100_000  # frames/s
TARGET_BVH = 300_000  # frames/s
TARGET_INGEST_S = 60.0  # seconds for all shared data
CHECK_TOL_CM = 1e-3
WORKERS = 2
BN2_SUBSET = 500
QUICK_FILES = 20
BIG_ARCHIVE = REPO.parent / "shared" / "reliability" / "big.tar.xz"
LARGE_FILES = ("M1_bvh_1M_frames_2MB.bvh", "M2_amc_1M_markers_7MB.amc", "H1_wide20000.bvh", "H1b_deep20000.bvh",
               "H2_chain10000_rev.amc")
TARGET_LOAD_RATIO = 4.0  # peak RSS of a load (above the process's own) / arrays returned
TARGET_MEMORY_RATIO = 2.0  # peak RSS of load -> canonical -> resample / the largest arrays one of them returns
LARGE_RATES = (30.0, 120.0)  # the rates ingest resamples to: kNN at 30 fps, relational features at 120
TILED_CLIP = "HDM_mm_kickLFront1Reps_023_120.amc"  # a real AMC of the embedded sample, tiled for a large row
TILED_FRAMES = 200_000


# ============================================================================ baseline: plain-Python ASF/AMC
@dataclass
class BaselineBone:
    name: str
    parent: str
    offset: np.ndarray  # (3,) cm: length * unit direction
    order: str  # axis order, e.g. "XYZ"
    c: np.ndarray  # (3, 3) the bone's axis frame C
    dof: list  # ["rx", "ry", "rz"] as in the AMC columns


@dataclass
class BaselineSkeleton:
    cm: float
    degrees: bool
    root_order: list
    root_axis: str
    root_position: np.ndarray
    root_c: np.ndarray
    bones: list = field(default_factory=list)  # parents first


def baseline_read_asf(path) -> BaselineSkeleton:
    """Parse an ASF file the way a user would: one pass over the split lines, section by section."""
    section = None
    length_unit, degrees = 1.0, True
    root = {
        "order": ["TX", "TY", "TZ", "RX", "RY", "RZ"],
        "axis": "XYZ",
        "position": [0, 0, 0],
        "orientation": [0, 0, 0],
    }
    bones, bone, children = {}, None, {}
    with open(path, encoding="latin-1") as fh:
        for line in fh:
            parts = line.split()
            if not parts or parts[0].startswith("#"):
                continue
            if parts[0].startswith(":"):
                section = parts[0][1:]
                continue
            key = parts[0]
            if section == "units":
                if key == "length":
                    length_unit = float(parts[1])
                elif key == "angle":
                    degrees = parts[1].lower() == "deg"
            elif section == "root":
                if key == "order":
                    root["order"] = [p.upper() for p in parts[1:]]
                elif key == "axis":
                    root["axis"] = parts[1].upper()
                elif key in ("position", "orientation"):
                    root[key] = [float(v) for v in parts[1:4]]
            elif section == "bonedata":
                if key == "begin":
                    bone = {"dof": []}
                elif key == "end":
                    bones[bone["name"]] = bone
                elif key == "name":
                    bone["name"] = parts[1]
                elif key == "direction":
                    bone["direction"] = [float(v) for v in parts[1:4]]
                elif key == "length":
                    bone["length"] = float(parts[1])
                elif key == "axis":
                    bone["axis"] = [float(v) for v in parts[1:4]]
                    bone["order"] = parts[4].upper()
                elif key == "dof":
                    bone["dof"] = [p.lower() for p in parts[1:]]
            elif section == "hierarchy" and key not in ("begin", "end"):
                children.setdefault(key, []).extend(parts[1:])
    cm = 2.54 / length_unit
    skel = BaselineSkeleton(
        cm=cm,
        degrees=degrees,
        root_order=root["order"],
        root_axis=root["axis"],
        root_position=np.array(root["position"], dtype=float) * cm,
        root_c=Rotation.from_euler(root["axis"].lower(), root["orientation"], degrees=degrees).as_matrix(),
    )
    todo = [("root", c) for c in children.get("root", [])]
    while todo:  # breadth first: parents before children
        parent, name = todo.pop(0)
        b = bones[name]
        direction = np.array(b["direction"], dtype=float)
        direction /= np.linalg.norm(direction)
        skel.bones.append(
            BaselineBone(
                name=name,
                parent=parent,
                offset=direction * b["length"] * cm,
                order=b["order"],
                c=Rotation.from_euler(b["order"].lower(), b["axis"], degrees=degrees).as_matrix(),
                dof=b["dof"],
            )
        )
        todo += [(name, c) for c in children.get(name, [])]
    return skel


def baseline_read_amc(path, skel: BaselineSkeleton) -> tuple[list, np.ndarray]:
    """Parse an AMC file into a dict of bone -> values per frame, then run forward kinematics.

    Returns the joint names (``root`` and each bone's tip) and positions (T, J, 3) in cm.
    """
    frames = []
    frame = None
    degrees = skel.degrees
    with open(path, encoding="latin-1") as fh:
        for line in fh:
            parts = line.split()
            if not parts:
                continue
            if parts[0][0] in "#:":
                if parts[0].upper() == ":RADIANS":
                    degrees = False
                continue
            if len(parts) == 1 and parts[0].isdigit():
                frame = {}
                frames.append(frame)
            else:
                frame[parts[0]] = [float(v) for v in parts[1:]]
    n = len(frames)
    zero = np.zeros(n)
    # root: translation and rotation C M C^-1
    root = np.array([f["root"] for f in frames])
    channel = {c: root[:, i] for i, c in enumerate(skel.root_order)}
    translation = np.stack([channel.get(c, zero) for c in ("TX", "TY", "TZ")], axis=1) * skel.cm + skel.root_position
    angles = np.stack([channel.get("R" + a, zero) for a in skel.root_axis], axis=1)
    m = Rotation.from_euler(skel.root_axis.lower(), angles, degrees=degrees).as_matrix()
    glob = {"root": skel.root_c @ m @ skel.root_c.T}
    pos = {"root": translation}
    for bone in skel.bones:
        if bone.dof and bone.name in frames[0]:
            values = np.array([f[bone.name] for f in frames])
            angles = np.zeros((n, 3))
            for k, d in enumerate(bone.dof):
                angles[:, bone.order.index(d[1].upper())] = values[:, k]
            m = Rotation.from_euler(bone.order.lower(), angles, degrees=degrees).as_matrix()
            g = glob[bone.parent] @ (bone.c @ m @ bone.c.T)
        else:
            g = glob[bone.parent]  # C I C^-1 = I
        glob[bone.name] = g
        pos[bone.name] = pos[bone.parent] + g @ bone.offset
    names = ["root"] + [b.name for b in skel.bones]
    return names, np.stack([pos[k] for k in names], axis=1)


_BASELINE_ASF_CACHE: dict = {}


def baseline_load_amc(amc, asf) -> tuple[list, np.ndarray]:
    """Baseline AMC read, parsing each ASF once per process (as a user's loop over clips would)."""
    skel = _BASELINE_ASF_CACHE.get(asf)
    if skel is None:
        skel = _BASELINE_ASF_CACHE[asf] = baseline_read_asf(asf)
    return baseline_read_amc(amc, skel)


# ============================================================================ baseline: `bvh` package + numpy FK
def baseline_read_bvh(path) -> tuple[list, np.ndarray]:
    """Parse a BVH file with the ``bvh`` package (PyPI) and run numpy/scipy forward kinematics.

    Rotation channels ``c1 c2 c3`` give ``R = R_c1 R_c2 R_c3``; position channels replace the OFFSET.
    Returns joint names (joints in file order, each ``End Site`` as ``<joint>_end``) and positions (T, J, 3).
    """
    from bvh import Bvh

    with open(path) as fh:
        mocap = Bvh(fh.read())
    data = np.array(mocap.frames, dtype=np.float64)
    n = data.shape[0]
    glob, pos = {}, {}
    names, out = [], []
    start = 0
    # walk the joint nodes directly: the package's name-based look-ups (joint_channels(name), ...) search the
    # whole tree on every call and would make this baseline about 1.5x slower
    for joint in mocap.get_joints():
        name = joint.name
        chans = joint["CHANNELS"][1:]
        t = np.tile(np.array([float(v) for v in joint["OFFSET"]]), (n, 1))
        axes, cols = "", []
        for k, c in enumerate(chans):
            if c.lower().endswith("position"):
                t[:, "XYZ".index(c[0].upper())] = data[:, start + k]
            else:
                axes += c[0].upper()
                cols.append(start + k)
        start += len(chans)
        # upper-case = intrinsic rotations in scipy: "ZXY" -> Rz @ Rx @ Ry
        r = Rotation.from_euler(axes, data[:, cols], degrees=True).as_matrix() if axes else np.eye(3)
        parent = joint.parent.name if joint.parent is not mocap.root else None
        if parent is None:
            g, p = np.broadcast_to(r, (n, 3, 3)), t
        else:
            gp = glob[parent]
            g, p = gp @ r, pos[parent] + (gp @ t[:, :, None])[:, :, 0]
        glob[name], pos[name] = g, p
        names.append(name)
        out.append(p)
        for end in joint.filter("End"):
            names.append(name + "_end")
            out.append(p + g @ np.array([float(v) for v in end["OFFSET"]]))
    return names, np.stack(out, axis=1)


# ============================================================================ tasks (picklable, for the pools)
def ours_task(path) -> int:
    from mocapviz.io import load

    return load(path).n_frames


def baseline_amc_task(item) -> int:
    amc, asf = item
    return baseline_load_amc(amc, asf)[1].shape[0]


def baseline_bvh_task(path) -> int:
    return baseline_read_bvh(path)[1].shape[0]


def _clear_caches() -> None:
    """Forget parsed ASF skeletons (ours and the baseline's) so every run parses them, once per process."""
    _BASELINE_ASF_CACHE.clear()
    from mocapviz.io import asfamc

    cached = getattr(asfamc, "_read_asf_cached", None)
    if cached is not None and hasattr(cached, "cache_clear"):
        cached.cache_clear()


def _run_serial(task, items) -> int:
    _clear_caches()
    return sum(task(it) for it in items)


def _run_pool(task, items, workers: int = WORKERS) -> int:
    _clear_caches()  # the workers are forked (Linux default): they start with empty caches too
    with ProcessPoolExecutor(workers) as pool:
        return sum(pool.map(task, items, chunksize=1))


def timed(fn, repeats: int) -> tuple[float, int, list, float]:
    """Time ``repeats`` calls of ``fn`` (which returns a frame count).

    Returns the median wall time, the frame count, all wall times and the median CPU time (this process plus
    its finished worker processes), which other processes sharing the machine disturb less than wall time.
    """
    times, cpus, frames = [], [], None
    for _ in range(repeats):
        c0 = CpuMonitor._ours()
        t0 = time.perf_counter()
        n = fn()
        times.append(time.perf_counter() - t0)
        cpus.append(CpuMonitor._ours() - c0)
        if frames is not None and n != frames:
            raise RuntimeError(f"frame count changed between runs: {frames} then {n}")
        frames = n
    return statistics.median(times), frames, times, statistics.median(cpus)


# ============================================================================ checks
def check_amc(amc, asf) -> float:
    """Max abs difference (cm) between the baseline's and mocapviz's positions on one clip."""
    from mocapviz.io import load

    m = load(amc)
    names, p = baseline_load_amc(str(amc), str(asf))
    return _max_diff(m, names, p)


def check_bvh(path) -> float:
    from mocapviz.io import load

    m = load(path)
    names, p = baseline_read_bvh(str(path))
    return _max_diff(m, names, p)


def _max_diff(motion, names, positions) -> float:
    if sorted(names) != sorted(motion.joint_names) or positions.shape[0] != motion.n_frames:
        raise RuntimeError(
            f"{motion.source}: baseline has {len(names)} joints x {positions.shape[0]} frames, "
            f"mocapviz {motion.n_joints} x {motion.n_frames}"
        )
    idx = [motion.joint_names.index(n) for n in names]
    return float(np.abs(motion.positions[:, idx].astype(np.float64) - positions).max())


# ============================================================================ machine
def header(info: dict, quick: bool, repeats: int) -> str:
    lines = [
        "# mocapviz I/O benchmarks" + (" (--quick: small subsets)" if quick else ""),
        "",
        f"- date: {_dt.datetime.now().isoformat(timespec='seconds')}, mocapviz {info['mocapviz']} @ {info['commit']}",
        f"- CPU: {info['cpu']}, {info['cores']} cores ({info['usable_cores']} usable), RAM {info['ram_gib']} GiB",
        (
            f"- {info['os']}; Python {info['python']}, numpy {info['numpy']}, numba {info['numba']}, "
            f"scipy {info['scipy']}, bvh {info['bvh']}"
        ),
        (
            f"- each figure: median of {repeats} runs; pools: ProcessPoolExecutor({WORKERS}), start method "
            f"'{info['start_method']}', one task per file, start-up included"
        ),
        f"- load average (1/5/15 min) at start: {info['load_start']}; {info.get('others', '')}",
    ]
    return "\n".join(lines)


# ============================================================================ tables
@dataclass
class Row:
    section: str
    benchmark: str
    data: str
    files: int
    frames: int
    workers: int
    ours: float | None
    baseline: float | None
    unit: str
    target: str
    meets: str
    note: str = ""
    ours_runs: list = field(default_factory=list)
    baseline_runs: list = field(default_factory=list)
    baseline_files: int | None = None
    baseline_frames: int | None = None
    ours_cpu: float | None = None  # frames per CPU second (all processes of the run)

    @property
    def ratio(self) -> float | None:
        if self.ours is None or not self.baseline:
            return None
        return self.ours / self.baseline


def _fmt(v, unit="") -> str:
    if v is None:
        return "—"
    if unit == "s":
        return f"{v:.2f}"
    if isinstance(v, float) and v < 100:
        return f"{v:.2f}"
    return f"{v:,.0f}"


def markdown_reader_table(rows: list[Row]) -> str:
    return markdown(
        "| format | data | files | frames | workers | mocapviz frames/s | baseline frames/s | ours/baseline "
        "| target | meets | mocapviz frames/CPU-s | note |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|---|---:|---|",
        (
            [r.benchmark, r.data, str(r.files), f"{r.frames:,}", str(r.workers), _fmt(r.ours), _fmt(r.baseline),
             "—" if r.ratio is None else f"{r.ratio:.1f}×", r.target, r.meets, _fmt(r.ours_cpu), r.note]
            for r in rows
        ),
    )


def markdown_ingest_table(rows: list[Row]) -> str:
    return markdown(
        "| data | documents | frames | threads | wall s | frames/s | speed-up vs threads=1 | target | meets "
        "| frames/CPU-s | note |",
        "|---|---:|---:|---:|---:|---:|---:|---|---|---:|---|",
        (
            [r.data, str(r.files), f"{r.frames:,}", str(r.workers), _fmt(r.ours_runs[0] if r.ours_runs else None, "s"),
             _fmt(r.ours), "—" if r.ratio is None else f"{r.ratio:.2f}×", r.target, r.meets, _fmt(r.ours_cpu), r.note]
            for r in rows
        ),
    )


def write_csv(rows: list[Row], path: Path, info: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    ignore = path.parent / ".gitignore"
    if not ignore.exists():
        ignore.write_text("*.csv\n")
    cols = [
        "section",
        "benchmark",
        "data",
        "files",
        "frames",
        "workers",
        "ours",
        "baseline",
        "unit",
        "ours_over_baseline",
        "target",
        "meets_target",
        "ours_runs_s",
        "baseline_runs_s",
        "baseline_files",
        "baseline_frames",
        "ours_frames_per_cpu_s",
        "note",
        "cpu",
        "python",
        "numpy",
        "numba",
        "commit",
    ]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow(
                [
                    r.section,
                    r.benchmark,
                    r.data,
                    r.files,
                    r.frames,
                    r.workers,
                    "" if r.ours is None else f"{r.ours:.1f}",
                    "" if r.baseline is None else f"{r.baseline:.1f}",
                    r.unit,
                    "" if r.ratio is None else f"{r.ratio:.3f}",
                    r.target,
                    r.meets,
                    ";".join(f"{t:.4f}" for t in r.ours_runs),
                    ";".join(f"{t:.4f}" for t in r.baseline_runs),
                    "" if r.baseline_files is None else r.baseline_files,
                    "" if r.baseline_frames is None else r.baseline_frames,
                    "" if r.ours_cpu is None else f"{r.ours_cpu:.1f}",
                    r.note,
                    info["cpu"],
                    info["python"],
                    info["numpy"],
                    info["numba"],
                    info["commit"],
                ]
            )


# ============================================================================ benchmarks
def reader_rows(
    fmt: str, data: str, ours_items, base_items, base_task, target: int, repeats: int, note: str = ""
) -> list[Row]:
    """Rows for one data set: 1 process and WORKERS processes, ours and baseline."""
    rows = []
    for workers in (1, WORKERS):

        def run(task, items, workers=workers):
            if workers == 1:
                return lambda: _run_serial(task, items)
            return lambda: _run_pool(task, items, workers)

        log(f"{fmt} {data}: mocapviz, {workers} process(es), {len(ours_items)} files")
        t_ours, n_ours, ours_runs, cpu_ours = timed(run(ours_task, ours_items), repeats)
        log(f"  {n_ours / t_ours:,.0f} frames/s; baseline, {len(base_items)} files")
        t_base, n_base, base_runs, _ = timed(run(base_task, base_items), repeats)
        log(f"  {n_base / t_base:,.0f} frames/s")
        ours = n_ours / t_ours
        rows.append(
            Row(
                section="reader",
                benchmark=f"{fmt} parse+FK",
                data=data,
                files=len(ours_items),
                frames=n_ours,
                workers=workers,
                ours=ours,
                baseline=n_base / t_base,
                unit="frames/s",
                target=f"≥ {target:,} frames/s",
                meets="yes" if ours >= target else "NO",
                note=note,
                ours_runs=ours_runs,
                baseline_runs=base_runs,
                baseline_files=len(base_items),
                baseline_frames=n_base,
                ours_cpu=n_ours / cpu_ours if cpu_ours else None,
            )
        )
    return rows


def hdm05_asf(root: Path, amc: Path) -> Path:
    """The skeleton of an HDM05 clip: ``HDM_<actor>_<class>_<take>_120.amc`` -> ``<root>/asf/HDM_<actor>.asf``."""
    return root / "asf" / ("_".join(amc.name.split("_")[:2]) + ".asf")


def bench_amc(repeats: int, quick: bool) -> tuple[list[Row], list[str]]:
    notes = []
    root, err = fetch("hdm05-cut")
    if root is None:
        return [_skipped("ASF/AMC parse+FK", "hdm05-cut", f"fetch failed: {err}")], notes
    amcs = sorted((root / "amc").glob("*.amc"))
    if quick:
        amcs = amcs[:: max(1, len(amcs) // QUICK_FILES)][:QUICK_FILES]

    diff = check_amc(amcs[0], hdm05_asf(root, amcs[0]))
    ok = diff < CHECK_TOL_CM
    verdict = "ok" if ok else "FAILED"
    notes.append(f"AMC check on {amcs[0].name}: max |baseline − mocapviz| = {diff:.2e} cm ({verdict})")
    note = "" if ok else f"CHECK FAILED ({diff:.2e} cm): baseline differs"
    base_items = [(str(a), str(hdm05_asf(root, a))) for a in amcs]
    return reader_rows(
        "ASF/AMC", "hdm05-cut", [str(a) for a in amcs], base_items, baseline_amc_task, TARGET_AMC, repeats, note
    ), notes


def bench_bvh(repeats: int, quick: bool) -> tuple[list[Row], list[str]]:
    rows, notes = [], []
    for name in ("bandai-namco-1", "bandai-namco-2"):
        root, err = fetch(name)
        label = name if name == "bandai-namco-1" else f"{name} (first {BN2_SUBSET} sorted)"
        if root is None:
            rows.append(_skipped("BVH parse+FK", label, f"skipped, fetch failed: {err}"))
            continue
        files = sorted(str(p) for p in (root / "data").glob("*.bvh"))
        if name == "bandai-namco-2":
            files = files[:BN2_SUBSET]
        if quick:
            files = files[:: max(1, len(files) // QUICK_FILES)][:QUICK_FILES]
            label = name
        diff = check_bvh(files[0])
        ok = diff < CHECK_TOL_CM
        notes.append(
            f"BVH check on {Path(files[0]).name}: max |baseline − mocapviz| = {diff:.2e} cm "
            f"({'ok' if ok else 'FAILED'})"
        )
        note = "" if ok else f"CHECK FAILED ({diff:.2e} cm): baseline differs"
        rows += reader_rows("BVH", label, files, files, baseline_bvh_task, TARGET_BVH, repeats, note)
    return rows, notes


def _skipped(benchmark, data, note) -> Row:
    return Row(
        section="reader",
        benchmark=benchmark,
        data=data,
        files=0,
        frames=0,
        workers=0,
        ours=None,
        baseline=None,
        unit="frames/s",
        target="",
        meets="—",
        note=note,
    )


def bench_ingest(quick: bool) -> tuple[list[Row], list[str]]:
    from mocapviz.db.database import MotionDB
    from mocapviz.db.ingest import expand_paths

    notes = []
    roots, missing = [], []
    for name in ("hdm05-cut", "cmu-asfamc", "bandai-namco-1", "bandai-namco-2"):
        root, err = fetch(name)
        (roots.append(root) if root is not None else missing.append(f"{name} ({err})"))
    files = expand_paths(roots)
    if quick:
        files = [f for r in roots for f in sorted(p for p in files if str(p).startswith(str(r.resolve())))[:5]]
    data = "all shared data" if not quick else f"{len(files)} files from 4 archives"
    if missing:
        data += " except " + ", ".join(missing)
    # read every file once so that both runs find them in the page cache
    nbytes = sum(len(Path(f).read_bytes()) for f in files)
    notes.append(f"ingest input: {len(files)} files, {nbytes / 2**20:.0f} MiB (page cache warmed first), fps=None")
    rows = []
    for threads in (1, WORKERS):
        with tempfile.TemporaryDirectory(prefix="mocapviz-bench-") as tmp:
            log(f"ingest {len(files)} files, threads={threads}")
            c0 = CpuMonitor._ours()
            t0 = time.perf_counter()
            db = MotionDB.ingest(files, Path(tmp) / "db", fps=None, threads=threads, progress=False)
            wall = time.perf_counter() - t0
            cpu = CpuMonitor._ours() - c0
            n_docs, n_frames = len(db), db.n_frames
            del db
        log(f"  {wall:.1f} s, {n_docs} documents, {n_frames} frames")
        fps = n_frames / wall
        rows.append(
            Row(
                section="ingest",
                benchmark="MotionDB.ingest",
                data=data,
                files=n_docs,
                frames=n_frames,
                workers=threads,
                ours=fps,
                baseline=rows[0].ours if rows else None,
                unit="frames/s",
                target=f"< {TARGET_INGEST_S:.0f} s (all shared data)",
                meets=("yes" if wall < TARGET_INGEST_S else "NO") if not quick else "(quick)",
                note="single run",
                ours_runs=[wall],
                ours_cpu=n_frames / cpu if cpu else None,
            )
        )
    return rows, notes


# ============================================================================ large reproducers
_MEASURE = """
import json, sys, time
from mocapviz.errors import MocapvizError
from mocapviz.io import load

def status(key):  # bytes; VmHWM is this process's peak RSS (reset by exec, unlike getrusage's ru_maxrss)
    line = next(l for l in open("/proc/self/status") if l.startswith(key + ":"))
    return int(line.split()[1]) * 1024

def reset_peak():  # VmHWM back to the current RSS (Linux 4.0+), so that each step has its own peak
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False

def arrays(m):
    return sum(a.nbytes for a in (m.positions, m.quaternions, m.euler) if a is not None)

path, rates, warm = sys.argv[1], [float(r) for r in sys.argv[2].split(",") if r], sys.argv[3:]
for w in warm:  # imports, numba kernels from their disk cache: the process's own memory
    warmed = load(w)
    if warmed.n_joints > 1:
        [warmed.canonical().resample(r) for r in rates]
    del warmed
steps, clip, source = [], None, None
todo = [("load", lambda: load(path)), ("canonical", lambda: source.canonical())]
todo += [(f"resample {r:g}", lambda r=r: clip.resample(r)) for r in rates]
reset = reset_peak()
base = status("VmRSS")
for name, step in todo:
    if name.startswith("resample") and clip is None:
        break
    reset = reset_peak() and reset
    t, c = time.perf_counter(), time.process_time()
    try:
        m = step()
    except MocapvizError as exc:
        reason = getattr(exc, "reason", None)  # (a MocapFormatError's, without the file's path)
        steps.append(dict(step=name, refused=type(exc).__name__ + (f": {reason}" if reason else ""),
                          wall=time.perf_counter() - t, peak=status("VmHWM")))
        break
    steps.append(dict(step=name, wall=time.perf_counter() - t, cpu=time.process_time() - c, peak=status("VmHWM"),
                      frames=m.n_frames, joints=m.n_joints, fps=m.fps, arrays=arrays(m)))
    if name == "load":
        source = m
    elif name == "canonical":
        source, clip = None, m  # (ingest keeps only the canonical clip)
    del m  # (the resampled clip: each rate from the canonical one)
print(json.dumps(dict(base=base, reset=reset, steps=steps)))
"""


def measure_pipeline(path: Path, rates=LARGE_RATES, warm=()) -> dict:
    """``load(path)`` → ``.canonical()`` → ``.resample(r)`` for each rate ``r`` (from the canonical clip), in a fresh
    process, after the same steps on the ``warm`` files (small: imports and compiled kernels are the process's own).

    Returns ``base`` (the process's RSS before the load, bytes), ``reset`` (whether each step's peak is its own, else
    the peaks are cumulative) and ``steps``: per step (``load``, ``canonical``, ``resample 30``, ...) its wall and CPU
    seconds, ``peak`` (the process's peak RSS during the step, bytes), and frames, joints, fps and ``arrays`` (bytes of
    positions, quaternions and Euler angles) of the Motion it returns, or ``refused`` (the typed error that ended the
    run; no resample follows a refused canonical).
    """
    done = subprocess.run([sys.executable, "-c", _MEASURE, str(path), ",".join(map(str, rates)), *map(str, warm)],
                          capture_output=True, text=True, cwd=REPO, timeout=1800, check=False)  # fmt: skip
    if done.returncode:
        raise RuntimeError(f"measuring {path.name} failed: {done.stderr.strip().splitlines()[-1:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def without_dofs(amc: Path, out: Path) -> Path:
    """A copy of ``amc`` in the folder ``out`` beside its ASF (same stem) without DOFs: no ``dof`` or ``limits`` lines,
    the root's ``order`` empty. Returns the copy.

    M2 of big.tar.xz is 1M frame numbers without bone lines: on its own skeleton that is no motion, refused at the
    first frame; on this skeleton every frame is complete, and the load does what M2's did before that refusal (the
    scan of 1M frame numbers, forward kinematics of 1M x 31 joints at rest).
    """
    out.mkdir(parents=True, exist_ok=True)
    copy = out / amc.name
    copy.write_bytes(amc.read_bytes())
    lines = amc.with_suffix(".asf").read_text(encoding="latin-1").split("\n")
    kept = ["   order" if s.split()[:1] == ["order"] else s for s in lines
            if s.split()[:1] not in (["dof"], ["limits"]) and not s.lstrip().startswith("(")]
    copy.with_suffix(".asf").write_text("\n".join(kept), encoding="latin-1")
    return copy


def pipeline_memory(r: dict, rate: float) -> dict:
    """Of a :func:`measure_pipeline` result, the ingest of one file at ``rate``: load → canonical → resample(rate).

    Returns ``peak`` (the largest peak RSS of those steps above the RSS before the load, bytes), ``largest`` (the
    largest arrays one of them returns), ``final`` (those of the last step done), ``ratio`` (peak / largest) and
    ``steps`` (those steps, in order).
    """
    steps = [s for s in r["steps"] if not s["step"].startswith("resample") or s["step"] == f"resample {rate:g}"]
    done = [s["arrays"] for s in steps if "arrays" in s]
    peak = max(s["peak"] for s in steps) - r["base"]
    largest = max(done, default=0)
    return {"peak": peak, "largest": largest, "final": done[-1] if done else 0,
            "ratio": peak / largest if largest else None, "steps": steps}


def tiled_amc(amc: Path, asf: Path, out: Path, n_frames: int) -> Path:
    """An AMC of ``n_frames`` frames: the frames of ``amc`` over and over, numbered 1 to ``n_frames``, in the folder
    ``out`` beside a copy of its skeleton ``asf`` (same stem, so that :func:`mocapviz.io.find_asf` finds it).
    Returns the new AMC."""
    out.mkdir(parents=True, exist_ok=True)
    lines = amc.read_bytes().split(b"\n")
    marks = [i for i, line in enumerate(lines) if line.strip().isdigit()] + [len(lines)]  # the frame numbers
    blocks = [b"\n".join(line for line in lines[a + 1 : b] if line.strip()) for a, b in itertools.pairwise(marks)]
    path = out / f"tiled{n_frames}.amc"
    with open(path, "wb") as fh:
        fh.write(b"\n".join(lines[: marks[0]]) + b"\n")
        fh.writelines(b"%d\n%s\n" % (k + 1, blocks[k % len(blocks)]) for k in range(n_frames))
    path.with_suffix(".asf").write_bytes(asf.read_bytes())
    return path


def sample_clip() -> tuple[Path, Path]:
    """:data:`TILED_CLIP` of the sample shipped with mocapviz (HDM05, 31 joints, 120 fps) and its ASF skeleton."""
    from mocapviz.io import datasets

    root = datasets.sample() / "hdm05-cut"
    return root / "amc" / TILED_CLIP, hdm05_asf(root, root / "amc" / TILED_CLIP)


def warm_files(tmp: Path) -> list[Path]:
    """Small files for the warm-up of :func:`measure_pipeline`, written to the folder ``tmp``: a one-joint BVH, and
    2 frames of :func:`sample_clip` for the AMC reader, ``canonical`` and ``resample``."""
    bvh = tmp / "warm.bvh"
    bvh.write_text("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 1 Xposition\n}\nMOTION\nFrames: 1\n"
                   "Frame Time: 0.01\n0\n")  # fmt: skip
    return [bvh, tiled_amc(*sample_clip(), tmp / "warm", 2)]


def bench_large() -> tuple[list[dict], list[str]]:
    """One row per member of big.tar.xz (unpacked with the tarfile ``data`` filter into a temporary folder), for M2 on
    its skeleton without DOFs, and for :func:`sample_clip` tiled to :data:`TILED_FRAMES` frames (a real AMC's text)."""
    if not BIG_ARCHIVE.is_file():
        return [], [f"large reproducers skipped: {BIG_ARCHIVE} not found"]
    rows = []
    with tempfile.TemporaryDirectory(prefix="mocapviz-big-") as tmp:
        with tarfile.open(BIG_ARCHIVE) as tar:
            tar.extractall(tmp, filter="data")
        warm = warm_files(Path(tmp))
        files = [(name, Path(tmp) / name) for name in LARGE_FILES]
        m2 = without_dofs(Path(tmp) / LARGE_FILES[1], Path(tmp) / "no-dofs")
        files.insert(2, (f"{m2.name} (ASF without DOFs)", m2))
        files.append((f"{TILED_CLIP} tiled", tiled_amc(*sample_clip(), Path(tmp) / "tiled", TILED_FRAMES)))
        for name, path in files:
            log(f"large reproducer {name}: load, canonical, resample to {', '.join(map(str, LARGE_RATES))} fps")
            r = measure_pipeline(path, LARGE_RATES, warm)
            r.update(name=name, size=path.stat().st_size)
            for rate in LARGE_RATES:
                m = pipeline_memory(r, rate)
                log(f"  {rate:g} fps: peak RSS +{m['peak'] / 1e6:.0f} MB, largest arrays {m['largest'] / 1e6:.0f} MB")
            rows.append(r)
    note = (f"large reproducers: {BIG_ARCHIVE}, and {TILED_CLIP} (HDM05) tiled to {TILED_FRAMES:,} frames; each file "
            "in a fresh process: load, canonical, then resample of the canonical clip to each rate (as "
            "MotionDB.ingest reads a file at fps=30 or 120); peak RSS = the process's VmHWM during the step (reset "
            "before each step through /proc/self/clear_refs), above its RSS before the load")
    if not all(r["reset"] for r in rows):
        note += "; /proc/self/clear_refs was not writable: each step's peak is that of the steps up to it"
    return rows, [note]


def _mb(v) -> str:
    return "—" if v is None else f"{v / 1e6:,.0f}"


def markdown_load_table(rows: list[dict]) -> str:
    """The load step of each file: its peak against the arrays it returns."""
    cells = []
    for r in rows:
        s = r["steps"][0]
        if "arrays" not in s:
            cells.append([r["name"], f"{r['size'] / 1e6:.1f}", "—", "—", f"{s['wall']:.2f}", "—", "—",
                          _mb(s["peak"] - r["base"]), _mb(r["base"]), "—", f"≤ {TARGET_LOAD_RATIO:g}×",
                          f"— (refused: {s['refused']})"])
            continue
        ratio = (s["peak"] - r["base"]) / s["arrays"]
        meets = "yes" if ratio <= TARGET_LOAD_RATIO else "yes (< 64 MB)" if s["peak"] - r["base"] < 64e6 else "NO"
        cells.append([r["name"], f"{r['size'] / 1e6:.1f}", f"{s['frames']:,}", f"{s['joints']:,}", f"{s['wall']:.2f}",
                      f"{s['cpu']:.2f}", _mb(s["arrays"]), _mb(s["peak"] - r["base"]), _mb(r["base"]),
                      f"{ratio:.2f}×", f"≤ {TARGET_LOAD_RATIO:g}×", meets])
    return markdown(
        "| file | MB on disk | frames | joints | wall s | CPU s | arrays MB | peak RSS above before MB | RSS before MB "
        "| load / arrays | target | meets |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|",
        cells,
    )


def markdown_pipeline_table(rows: list[dict]) -> str:
    """Per file and rate (one row for a file refused before the resample): each step's peak, the arrays of the last
    step and the largest, the ratio."""
    cells = []
    for r in rows:
        resampled = any(s["step"].startswith("resample") for s in r["steps"])
        for rate in LARGE_RATES if resampled else LARGE_RATES[:1]:
            m = pipeline_memory(r, rate)
            peaks = {s["step"].split()[0]: s for s in m["steps"]}
            last = m["steps"][-1]
            out = f"{last['frames']:,} at {last['fps']:g} fps" if "frames" in last else f"refused at {last['step']}"
            if not m["largest"]:
                meets = "— (refused)"
            elif m["ratio"] <= TARGET_MEMORY_RATIO:
                meets = "yes"
            else:
                meets = "yes (< 64 MB)" if m["peak"] < 64e6 else "NO"
            cells.append([r["name"], f"{rate:g}" if resampled else "—", out]
                         + [_mb(peaks[k]["peak"] - r["base"]) if k in peaks else "—" for k in ("load", "canonical",
                                                                                               "resample")]
                         + [_mb(m["final"]), _mb(m["largest"]), _mb(m["peak"]),
                            "—" if m["ratio"] is None else f"{m['ratio']:.2f}×", f"≤ {TARGET_MEMORY_RATIO:g}×", meets,
                            f"{sum(s['wall'] for s in m['steps']):.1f}", last.get("refused", "")])
    return markdown(
        "| file | fps | frames out | load peak MB | canonical peak MB | resample peak MB | final arrays MB "
        "| largest arrays MB | peak MB | peak / largest | target | meets | wall s | note |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|---|---:|---|",
        cells,
    )


def print_large(rows: list[dict], notes: list[str]) -> None:
    print("## Large reproducers (`../shared/reliability/big.tar.xz`): load → canonical → resample, as ingest")
    print()
    if rows:
        print(markdown_pipeline_table(rows))
        print()
        print("The load step alone:")
        print()
        print(markdown_load_table(rows))
        print()
    for n in notes:
        print(f"- {n}")
    print("- peaks are above the process's RSS before the load. meets: the ingest of a file (load → canonical → "
          f"resample) needs at most {TARGET_MEMORY_RATIO:g}× the largest arrays one of its steps returns (the load's "
          "when the clip is resampled down, the resampled clip's when up), or under 64 MB; the final arrays alone "
          "cannot bound it when the clip is resampled down (the loaded clip is there first). The load alone: at "
          f"most {TARGET_LOAD_RATIO:g}× its arrays. Before issue 29 (commit b195651): M1 at 120 fps 20.5 GB (7.6×: "
          "the slerp of the whole clip in float64), at 30 fps 1.53 GB (2.02×: canonical copied the quaternions "
          "twice); M2 refused after 0.27 GB (4-byte line indices); M2 without DOFs at 30 fps 1.91 GB (2.21×: "
          "resample's float64 temporaries); the tiled HDM05 clip 0.68 GB (3.1×: the scanner's table of every "
          "line's start for numbers such as 3.1e-018, the file's bytes kept to the end). Before issue 18 (commit "
          "e57603e): M1 3.3 GB and M2 3.9 GB peak RSS for the load, 7.6 s and 4.0 s; H2 4.7 s.")


def main(quick: bool = False, repeats: int = 3, ingest: bool = True, out_dir: Path | None = None,
         large: bool = True) -> int:
    from mocapviz.io import load

    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info()
    # warm-up: the first call of the numba kernels compiles them (or loads them from the disk cache)
    hdm, _ = fetch("hdm05-cut")
    bn1, _ = fetch("bandai-namco-1")
    t0 = time.perf_counter()
    if hdm is not None:
        load(min((hdm / "amc").glob("*.amc")))
    if bn1 is not None:
        load(min((bn1 / "data").glob("*.bvh")))
    warm = time.perf_counter() - t0

    amc_rows, amc_notes = bench_amc(repeats, quick)
    bvh_rows, bvh_notes = bench_bvh(repeats, quick)
    reader = amc_rows + bvh_rows
    ingest_rows, ingest_notes = bench_ingest(quick) if ingest else ([], [])
    large_rows, large_notes = bench_large() if large else ([], [])

    info["others"] = monitor.report()
    print(header(info, quick, repeats))
    print(f"- warm-up (numba compile or disk-cache load + first reads): {warm:.2f} s, not timed")
    for n in amc_notes + bvh_notes:
        print(f"- {n}")
    print()
    print("## Parse + forward kinematics (frames/s, higher is better)")
    print()
    print(markdown_reader_table(reader))
    print()
    print(
        "Baselines: ASF/AMC — plain-Python reader in `benchmarks/bench_io.py` (split lines, dict of bone → values "
        "per frame, numpy/scipy `Rotation` FK vectorised over frames per bone); BVH — `bvh` package (PyPI) to "
        "parse, then numpy/scipy FK. mocapviz: `mocapviz.io.load` (AMC: includes `find_asf`). Each run parses "
        "every ASF once per process on both sides. Workers return the frame count only. frames/CPU-s: frames per "
        "CPU second of the run's processes (parent and workers), less disturbed than wall time by other processes "
        "sharing the machine."
    )
    if ingest_rows:
        print()
        print("## MotionDB.ingest (native frame rates, single run each)")
        print()
        print(markdown_ingest_table(ingest_rows))
        print()
        for n in ingest_notes:
            print(f"- {n}")
    if large:
        print()
        print_large(large_rows, large_notes)
    out_dir = Path(out_dir) if out_dir is not None else Path(__file__).resolve().parent / "results"
    csv_path = out_dir / ("io-quick.csv" if quick else "io.csv")
    write_csv(reader + ingest_rows, csv_path, info)
    print()
    print(f"CSV: {csv_path}; total benchmark time {time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    import argparse
    import os

    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_io", description=__doc__)
    parser.add_argument("--large", action="store_true", help="only the large reproducers of big.tar.xz")
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    if args.large:
        print_large(*bench_large())
        sys.exit(0)
    sys.exit(main(quick=args.quick, repeats=args.repeats))
