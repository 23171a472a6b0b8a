"""The dashboard's skeleton player (mocapviz.app.player) without a browser: steps, alignment, speed."""

from __future__ import annotations

import numpy as np
import pytest

from mocapviz.app.player import SkeletonPlayer


@pytest.fixture(scope="module")
def clips(sample_db):
    docs = sample_db.select(label="kickLFront1Reps")["doc_id"].to_numpy()
    return [np.asarray(sample_db.positions[sample_db.frames(int(d))]) for d in docs[:2]]


def test_unaligned_clips_hold_their_last_frame(clips):
    p = SkeletonPlayer(size=(200, 100))
    p.load(clips, titles=["a", "b"], fps=120)
    assert p.n_steps == max(len(c) for c in clips)
    p.step = p.n_steps - 1
    assert p.frames() == [len(c) - 1 for c in clips]
    assert p.player.value == p.n_steps - 1 and p.image.object[:4] == b"\x89PNG"


def test_alignment_drives_both_clips(clips):
    a, b = clips
    path = np.column_stack([np.arange(len(a)), np.linspace(0, len(b) - 1, len(a)).round().astype(int)])
    p = SkeletonPlayer(size=(200, 100))
    p.load(clips, fps=120, alignment=path)
    p.player.value = 17  # the slider moves the player
    assert p.step == 17 and p.frames() == [17, int(path[17, 1])]


def test_speed_sets_the_interval(clips):
    p = SkeletonPlayer(size=(200, 100))
    p.load(clips[:1], fps=120)
    assert p.player.step == 8 and p.player.interval == 67  # 15 shown frames per second at 1x
    p.speed.value = "2×"
    assert p.player.interval == 33


def test_bad_alignment_is_refused(clips):
    p = SkeletonPlayer(size=(200, 100))
    with pytest.raises(ValueError, match=r"\(L, 2\)"):
        p.load(clips, alignment=np.zeros((5, 3), int))
    with pytest.raises(ValueError, match="leaves clip 1"):
        p.load(clips, alignment=np.array([[0, len(clips[1])]]))
    with pytest.raises(ValueError, match="non-empty"):
        p.load([])
