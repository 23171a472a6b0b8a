"""Sheets for judging the audit's precision by eye (issue 41 item 3; docs/audit.md, "Precision, judged by eye").

Run the planted-copies audit of a database (``mocapviz.experiments.audit.audit_quality``, 20 copies of each kind
unless ``--per-kind``), then draw, with a fixed seed:

- ``sample``: ``--sample`` pairs at random from all the pairs it reports (real and planted): the precision;
- ``decoy``: ``--decoys`` pairs that are NOT copies: two performances of one motion (an audit of the database's
  HDM05 documents with a threshold of 10 cm, its pairs of a cost over 6 cm, above every learned threshold), so that
  a judge who calls every pair a copy is caught;
- ``planted``: ``--planted`` pairs that found a planted copy (known copies: noise, re-timing, other bones).

Each item is one PNG, named only by its number (the judge sees no document name, cost or kind): six moments of
the pair along its warping path (``Engine.audit_path``), stretch A beside stretch B, both placed so that their
first frame stands at the origin facing the camera (the path they walk stays visible), and the top view of both
roots' paths. A mirrored pair shows A's mirror image (the caption says so). The key (what each item is) is
written to a separate folder for scoring after the judging.

    python scripts/audit_judging.py build/all.mdb build/audit-judging --key /tmp/audit-judging-key.csv
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from mocapviz import Engine, MotionDB
from mocapviz.experiments.audit import audit_quality
from mocapviz.motion.skeleton import CANONICAL_JOINTS, mirror
from mocapviz.viz.skeleton import render_skeletons, scene_bounds

MOMENTS = 6
KEY_COLUMNS = ["item", "kind", "doc_a", "name_a", "start_a", "end_a", "doc_b", "name_b", "start_b", "end_b", "cost",
               "mirrored", "scale"]  # fmt: skip


def _placed(positions: np.ndarray) -> np.ndarray:
    """A stretch moved and turned about y once, so that its first frame's root is at the origin (on the floor) and
    its hips face +z (left hip at +x); its later frames keep where they walk and turn."""
    lhip, rhip = CANONICAL_JOINTS.index("lhip"), CANONICAL_JOINTS.index("rhip")
    side = positions[0, lhip] - positions[0, rhip]
    angle = np.arctan2(side[2], side[0])  # turn the hip line onto +x
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    out = (positions - positions[0, 0] * np.array([1.0, 0.0, 1.0])) @ turn.T
    out[..., 1] -= out[..., 1].min()
    return out


def sheet(engine: Engine, pair: pd.Series, path: Path, item: int) -> None:
    """One item's PNG: MOMENTS moments along the pair's warping path (A beside B), and both roots' top view."""
    db = engine.db
    a = db.motion(int(pair["doc_a"]))[int(pair["start_a"]):int(pair["end_a"])]
    b = db.motion(int(pair["doc_b"]))[int(pair["start_b"]):int(pair["end_b"])]
    steps = engine.audit_path(pair)
    shown_a = mirror(a) if pair["mirrored"] else a
    pa, pb = _placed(shown_a.positions.astype(np.float64)), _placed(b.positions.astype(np.float64))
    bounds = scene_bounds(pa, pb)
    picks = steps[np.linspace(0, len(steps) - 1, MOMENTS).round().astype(int)]
    fig = plt.figure(figsize=(15, 7.5), dpi=80)
    for k, (i, j) in enumerate(picks):
        image = render_skeletons([pa[i], pb[j]], bounds=bounds, size=(480, 300),
                                 titles=[f"A {i / a.fps:.2f} s", f"B {j / b.fps:.2f} s"])  # fmt: skip
        ax = fig.add_subplot(2, 4, k + 1 + (k >= 3))
        ax.imshow(image)
        ax.set_axis_off()
    for slot, (what, pos) in enumerate((("A", pa), ("B", pb))):
        ax = fig.add_subplot(2, 4, 4 + 4 * slot)
        ax.plot(pos[:, 0, 0], pos[:, 0, 2], color="black")
        ax.plot(pos[0, 0, 0], pos[0, 0, 2], "go")
        ax.set_title(f"{what}: root path from above (start: green)", fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x (cm)", fontsize=8)
        ax.set_ylabel("z (cm)", fontsize=8)
    mirrored = " - A shown MIRRORED (left/right swapped): B should look like this image of A" if pair["mirrored"] \
        else ""  # fmt: skip
    fig.suptitle(f"item {item:03d}: A {a.n_frames / a.fps:.2f} s, B {b.n_frames / b.fps:.2f} s; six moments "
                 f"aligned on the pair's warping path (right side red, left blue){mirrored}", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("database")
    parser.add_argument("out", help="the folder of the sheets (made new)")
    parser.add_argument("--key", required=True, help="the key's CSV: keep it away from the judge")
    parser.add_argument("--per-kind", type=int, default=20)
    parser.add_argument("--sample", type=int, default=100)
    parser.add_argument("--decoys", type=int, default=20)
    parser.add_argument("--planted", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    out = Path(args.out)
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        db = MotionDB.open(args.database)
        table = audit_quality(db, Path(tmp) / "planted.mdb", Engine, n_per_kind=args.per_kind, seed=args.seed,
                              progress=True)  # fmt: skip
        pairs, copies = table.attrs["pairs"], table.attrs["copies"]
        print(table.to_string())
        docs = db.documents
        hdm05 = docs[docs["path"].str.contains("hdm05", case=False)]
        decoy_db = MotionDB.create(Path(tmp) / "hdm05.mdb").append_motions(
            [db.motion(int(d)) for d in hdm05["doc_id"]], [{"name": n} for n in hdm05["name"]])
        with Engine(MotionDB.open(table.attrs["database"])) as engine, Engine(decoy_db) as decoy_engine:
            wide = decoy_engine.audit(threshold=10.0)
            decoys = wide[wide["cost"] > 6.0]
            found = copies.loc[copies["found"], "pair"].astype(int).to_numpy()
            parts = [
                pairs.iloc[rng.choice(len(pairs), min(args.sample, len(pairs)), replace=False)].assign(kind="sample"),
                decoys.iloc[rng.choice(len(decoys), min(args.decoys, len(decoys)), replace=False)].assign(kind="decoy"),
                pairs.iloc[rng.choice(found, min(args.planted, len(found)), replace=False)].assign(kind="planted")]
            items = pd.concat(parts, ignore_index=True)
            items = items.iloc[rng.permutation(len(items))].reset_index(drop=True)
            items.insert(0, "item", np.arange(1, len(items) + 1))
            for i, row in items.iterrows():
                sheet(decoy_engine if row["kind"] == "decoy" else engine, row, out / f"item_{row['item']:03d}.png",
                      int(row["item"]))  # fmt: skip
                print(f"item {row['item']} of {len(items)}", flush=True)
        items["threshold"] = pairs.attrs["threshold"]
        items[[*KEY_COLUMNS, "threshold"]].to_csv(args.key, index=False)
    print(f"{len(items)} sheets in {out}; key in {args.key}")


if __name__ == "__main__":
    main()
