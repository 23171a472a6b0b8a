"""Sheets for judging the audit's precision by eye (issue 41 item 3; docs/audit.md, "Precision, judged by eye").

Plant copies in a copy of a database (``mocapviz.experiments.audit.plant_copies``, 20 of each kind unless
``--per-kind``), audit it and score the copies (``planted_quality``), then draw, with a fixed seed:

- ``sample``: ``--sample`` pairs at random from all the pairs it reports (real and planted): the precision;
- ``decoy``: ``--decoys`` pairs that are NOT copies: two performances of one motion (an audit of the database's
  HDM05 documents with a threshold of 10 cm, its pairs of a cost over 6 cm, above every learned threshold), so that
  a judge who calls every pair a copy is caught;
- ``planted``: ``--planted`` pairs that found a planted copy (known copies: noise, re-timing, other bones).

Each item is one PNG, named only by its number (the judge sees no document name, cost or kind): six moments of
the pair along its warping path (``Engine.audit_path``), stretch A and stretch B drawn over each other (B on A's
bone lengths, its root moved onto A's at each moment, so that the postures compare; a mirrored pair shows A's
mirror image and says so), and both roots' paths from above, each stretch's first frame at the origin facing the
same way. The key (what each item is) is written apart, for scoring after the judging; ``--from-key`` draws the
sheets of a key's items again (the copies planted again with the same seed) without a new audit.

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
from mocapviz.experiments.audit import plant_copies, planted_quality
from mocapviz.motion.skeleton import bone_lengths, heading, mirror, retarget
from mocapviz.viz.palette import OTHERS
from mocapviz.viz.skeleton import BY_SIDE, render_skeletons, scene_bounds

MOMENTS = 6
KEY_COLUMNS = ["item", "kind", "doc_a", "name_a", "start_a", "end_a", "doc_b", "name_b", "start_b", "end_b", "cost",
               "mirrored", "scale"]  # fmt: skip


def _placed(positions: np.ndarray) -> np.ndarray:
    """A stretch moved and turned about y once, as :func:`~mocapviz.motion.skeleton.body_frame` places its first
    frame (root over the origin, facing +z, left at +x), lifted onto the floor; its later frames keep where they
    walk and turn."""
    theta = float(heading(positions[:1])[0])
    c, s = np.cos(theta), np.sin(theta)
    centred = positions - positions[0, 0] * np.array([1.0, 0.0, 1.0])
    x, z = centred[..., 0], centred[..., 2]
    out = np.stack([x * c - z * s, centred[..., 1], x * s + z * c], axis=-1)  # body_frame's turn, by -theta
    out[..., 1] -= out[..., 1].min()
    return out


def sheet(engine: Engine, pair: pd.Series, path: Path, item: int) -> None:
    """One item's PNG: MOMENTS moments along the pair's warping path, A and B drawn over each other on one body (B
    retargeted to A's bone lengths: a copy on another body is a copy; B's root moved onto A's, so that the postures
    compare), and both roots' paths from above."""
    db = engine.db
    a = db.motion(int(pair["doc_a"]))[int(pair["start_a"]):int(pair["end_a"])]
    b = db.motion(int(pair["doc_b"]))[int(pair["start_b"]):int(pair["end_b"])]
    steps = engine.audit_path(pair)
    shown_a = mirror(a) if pair["mirrored"] else a
    b = retarget(b.canonical(), bone_lengths(shown_a.canonical().positions))
    pa, pb = _placed(shown_a.canonical().positions.astype(np.float64)), _placed(b.positions.astype(np.float64))
    picks = steps[np.linspace(0, len(steps) - 1, MOMENTS).round().astype(int)]
    fig = plt.figure(figsize=(16, 9), dpi=80)
    for k, (i, j) in enumerate(picks):
        moved = pb[j] - (pb[j, 0] - pa[i, 0]) * np.array([1.0, 0.0, 1.0])  # B's root onto A's (the paths: right)
        image = render_skeletons([pa[i], moved], bounds=scene_bounds(pa[i:i + 1], moved[None]), size=(440, 400),
                                 overlay=True,
                                 colours=[BY_SIDE, OTHERS], opacities=[1.0, 0.85],
                                 titles=[f"moment {k + 1}: A {i / a.fps:.2f} s (red/blue), B {j / b.fps:.2f} s (grey)"])
        ax = fig.add_subplot(2, 4, k + 1 + (k >= 3))
        ax.imshow(image)
        ax.set_axis_off()
    roots = np.concatenate([pa[:, 0], pb[:, 0]])[:, [0, 2]]
    centre, half = (roots.max(axis=0) + roots.min(axis=0)) / 2, max(50.0, np.ptp(roots, axis=0).max() / 2 + 10.0)
    ax = fig.add_subplot(2, 4, 4)  # one scale for both, at least 1 m across
    ax.plot(pa[:, 0, 0], pa[:, 0, 2], color="#1f5fa8", label="A")
    ax.plot(pb[:, 0, 0], pb[:, 0, 2], color="#808080", label="B", linestyle="--")
    ax.plot(0, 0, "go")
    ax.legend(fontsize=8)
    ax.set_title("root paths from above (start: green)", fontsize=9)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")
    ax.set_xlabel("x (cm)", fontsize=8)
    ax.set_ylabel("z (cm)", fontsize=8)
    fig.text(0.78, 0.25, "B drawn on A's bone lengths, its root\nmoved onto A's at each moment\n(where each walks: the paths above)", fontsize=10)
    mirrored = " - A shown MIRRORED (left/right swapped): B should move like this image of A" if pair["mirrored"] \
        else ""  # fmt: skip
    fig.suptitle(f"item {item:03d}: A {a.n_frames / a.fps:.2f} s, B {b.n_frames / b.fps:.2f} s; six moments "
                 f"aligned on the pair's warping path, A and B drawn over each other{mirrored}", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _databases(db, tmp: Path, per_kind: int, seed: int) -> tuple:
    """The planted database (copies of ``db``'s clips appended, as ``audit_quality`` plants them, seeded) and a
    database of ``db``'s HDM05 documents (the decoys'), both made in ``tmp``."""
    planted, truth = plant_copies(db, tmp / "planted.mdb", n_per_kind=per_kind, seed=seed)
    docs = db.documents
    hdm05 = docs[docs["path"].str.contains("hdm05", case=False)]
    decoy_db = MotionDB.create(tmp / "hdm05.mdb").append_motions([db.motion(int(d)) for d in hdm05["doc_id"]],
                                                                  [{"name": n} for n in hdm05["name"]])  # fmt: skip
    return planted, truth, decoy_db


def _draw(engine: Engine, decoy_engine: Engine, truth: pd.DataFrame, args, rng) -> pd.DataFrame:
    """The items: the planted database's audit pairs at random, decoys, found copies; shuffled, numbered from 1."""
    pairs = engine.audit(progress=True)
    quality = planted_quality(engine.db, truth, pairs)
    print(quality.to_string(), f"\nthreshold {pairs.attrs['threshold']:.2f} cm", flush=True)
    copies = quality.attrs["copies"]
    wide = decoy_engine.audit(threshold=10.0)
    decoys = wide[wide["cost"] > 6.0]
    found = copies.loc[copies["found"], "pair"].astype(int).to_numpy()
    parts = [pairs.iloc[rng.choice(len(pairs), min(args.sample, len(pairs)), replace=False)].assign(kind="sample"),
             decoys.iloc[rng.choice(len(decoys), min(args.decoys, len(decoys)), replace=False)].assign(kind="decoy"),
             pairs.iloc[rng.choice(found, min(args.planted, len(found)), replace=False)].assign(kind="planted")]
    items = pd.concat(parts, ignore_index=True)
    items = items.iloc[rng.permutation(len(items))].reset_index(drop=True)
    items.insert(0, "item", np.arange(1, len(items) + 1))
    items["threshold"] = pairs.attrs["threshold"]
    return items


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
    parser.add_argument("--from-key", action="store_true", help="draw the sheets of the items of an existing key "
                        "again (the planted copies made again with the same seed) instead of drawing new items")
    args = parser.parse_args()
    out = Path(args.out)
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        db = MotionDB.open(args.database)
        planted, truth, decoy_db = _databases(db, Path(tmp), args.per_kind, args.seed)
        with Engine(planted) as engine, Engine(decoy_db) as decoy_engine:
            if args.from_key:  # the items of an earlier run, drawn again (the planting is seeded)
                items = pd.read_csv(args.key)
            else:
                items = _draw(engine, decoy_engine, truth, args, rng)
                items[[*KEY_COLUMNS, "threshold"]].to_csv(args.key, index=False)
            for _, row in items.iterrows():
                sheet(decoy_engine if row["kind"] == "decoy" else engine, row, out / f"item_{row['item']:03d}.png",
                      int(row["item"]))  # fmt: skip
                print(f"item {row['item']} of {len(items)}", flush=True)
    print(f"{len(items)} sheets in {out}; key in {args.key}")


if __name__ == "__main__":
    main()
