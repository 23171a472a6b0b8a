"""The dashboard's skeleton player (mocapviz.app.player): what Python sends the browser, steps and alignment; then in
headless Chromium: playback frame rate, scrubbing without the server, the camera, the step synced back to Python."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from browser_helpers import ARTIFACTS, open_dashboard, record_timing
from playwright.sync_api import expect

from mocapviz.app import player as player_mod
from mocapviz.app.player import SPEEDS, PlayerView, SkeletonPlayer, decode, joint_sides
from mocapviz.motion.skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS
from mocapviz.viz.palette import SIDES


@pytest.fixture(scope="module")
def clips(sample_db):
    docs = sample_db.select(label="kickLFront1Reps")["doc_id"].to_numpy()
    return [np.asarray(sample_db.positions[sample_db.frames(int(d))]) for d in docs[:2]]


def _recentred(c):
    """A clip as the player shows it: its first root position above the origin."""
    c = np.asarray(c, dtype=np.float32)
    return c - np.array([c[0, 0, 0], 0.0, c[0, 0, 2]], dtype=np.float32)


# ============================================================================ Python side
def test_the_browser_gets_the_clips_exactly(clips):
    p = SkeletonPlayer(size=(200, 100))
    p.load(clips, titles=["a", "b"], fps=120)
    sent, alignment = decode(p.view)
    assert len(sent) == 2
    for got, clip in zip(sent, clips):
        np.testing.assert_array_equal(got, _recentred(clip))  # float32 bytes: exact
    assert len(p.view.positions) == 4 * 3 * 24 * sum(len(c) for c in clips)
    meta = p.view.meta
    assert meta["lengths"] == [len(c) for c in clips] and meta["titles"] == ["a", "b"] and meta["fps"] == 120
    assert meta["parents"] == CANONICAL_PARENTS.tolist() and meta["n_joints"] == 24
    lo, hi = np.array(meta["bounds"])
    assert (lo <= np.concatenate(sent).min(axis=(0, 1))).all() and (hi >= np.concatenate(sent).max(axis=(0, 1))).all()
    assert lo[1] <= 0 <= hi[1]  # the floor is in the box
    np.testing.assert_array_equal(alignment[:, 0], np.minimum(np.arange(p.n_steps), len(clips[0]) - 1))


def test_sides_follow_the_joint_names_in_the_palettes_colours(clips):
    sides = dict(zip(CANONICAL_JOINTS, joint_sides()))
    assert sides["lhip"] == sides["lwrist"] == "l" and sides["rknee"] == sides["rclavicle"] == "r"
    assert sides["root"] == sides["belly"] == sides["headtop"] == "c"
    assert joint_sides(["lefty", "ltoe", "rtoe", "look"]) == ["c", "l", "r", "c"]
    p = SkeletonPlayer(size=(200, 100))
    p.load(clips[:1], fps=120)
    # the browser colours bones by the palette's sides, the one definition the skeleton pictures use too
    assert p.view.meta["sides"] == joint_sides() and p.view.meta["side_colours"] == SIDES
    script = (Path(player_mod.__file__).parent / "player.js").read_text()
    assert SIDES["r"] not in script and "meta.side_colours" in script  # no second definition in the script


def test_unaligned_clips_hold_their_last_frame(clips):
    p = SkeletonPlayer(size=(200, 100))
    p.load(clips, titles=["a", "b"], fps=120)
    assert p.n_steps == max(len(c) for c in clips)
    p.step = p.n_steps - 1
    assert p.view.step == p.n_steps - 1  # Python moves the browser's player
    assert p.frames() == [len(c) - 1 for c in clips]
    assert p.caption() == f"step {p.n_steps} of {p.n_steps} · {p.n_steps / 120:.2f} s at 1×"
    p.load(clips[:1], fps=120)  # a new clip starts at its first step
    assert p.step == p.view.step == 0


def test_alignment_steps_map_to_the_right_frames(clips):
    a, b = clips
    path = np.column_stack([np.arange(len(a)), np.linspace(0, len(b) - 1, len(a)).round().astype(int)])
    p = SkeletonPlayer(size=(200, 100))
    p.load(clips, fps=120, alignment=path)
    sent, alignment = decode(p.view)
    np.testing.assert_array_equal(alignment, path)
    for s in (0, 17, len(path) // 2, len(path) - 1):  # the poses the browser draws at step s
        np.testing.assert_array_equal(sent[0][alignment[s, 0]], _recentred(a)[path[s, 0]])
        np.testing.assert_array_equal(sent[1][alignment[s, 1]], _recentred(b)[path[s, 1]])
    p.view.step = 17  # as the browser reports it
    assert p.step == 17 and p.frames() == [17, int(path[17, 1])]


def test_speed_goes_both_ways(clips):
    p = SkeletonPlayer(size=(200, 100))
    p.load(clips[:1], fps=120)
    assert p.speed == p.view.speed == 1.0
    p.view.speed = 2.0  # a click in the browser
    assert p.speed == 2.0
    assert p.caption().endswith(f" · {len(clips[0]) / 120 / 2:.2f} s at 2×")  # the time it plays in at 2×
    p.speed = 0.25
    assert p.view.speed == 0.25 and set(SPEEDS) == {0.25, 0.5, 1.0, 2.0}


def test_bad_clips_and_alignments_are_refused(clips):
    p = SkeletonPlayer(size=(200, 100))
    with pytest.raises(ValueError, match=r"\(L, 2\)"):
        p.load(clips, alignment=np.zeros((5, 3), int))
    with pytest.raises(ValueError, match="leaves clip 1"):
        p.load(clips, alignment=np.array([[0, len(clips[1])]]))
    with pytest.raises(ValueError, match="non-empty"):
        p.load([])
    with pytest.raises(ValueError, match=r"\(T, 24, 3\)"):
        p.load([clips[0][:, :10]])
    with pytest.raises(ValueError, match="positive"):
        p.load(clips[:1], fps=0)


def test_payload_of_a_thousand_frames():
    """The wire format's size (reported beside the browser timings): float32 bytes, a Bokeh binary buffer on the
    server's WebSocket, against the same clip as a JSON list of numbers."""
    rng = np.random.default_rng(0)
    clip = np.cumsum(rng.normal(0, 0.5, (1000, 24, 3)), axis=0).astype(np.float32) + [0, 100, 0]
    p = SkeletonPlayer()
    p.load([clip], fps=120)
    binary = len(p.view.positions) + len(p.view.alignment) + len(json.dumps(p.view.meta))
    as_list = len(json.dumps(np.round(clip, 2).tolist()))
    assert len(p.view.positions) == 288_000 and binary < 300_000 < as_list
    record_timing("player_payload_1000_frames_bytes", binary, "bytes")
    record_timing("player_payload_1000_frames_json_list_bytes", as_list, "bytes")


def test_the_component_code_ships_with_the_package():
    esm = PlayerView._esm
    assert "export function render" in esm and "function makeCamera" in esm  # its own code after skeleton.js
    assert not re.search(r"^\s*import\b|\bimport\(|https?://", esm, re.MULTILINE)  # self-contained: nothing fetched


# ============================================================================ in the browser
_PLAYBACK = """async ([host, seconds]) => {
    const root = host.shadowRoot || host;
    const canvas = root.querySelector('canvas');
    root.querySelector('button.play').click();
    await new Promise((r) => setTimeout(r, 300));
    const n = Number(root.querySelector('input.mv-player-slider').max) + 1;
    const drawn0 = Number(canvas.dataset.drawn);
    let frames = 0, steps = 0, last = Number(canvas.dataset.step);
    const t0 = performance.now();
    await new Promise((done) => {
        const tick = () => {
            frames += 1;
            const step = Number(canvas.dataset.step);
            steps += (step - last + n) % n;
            last = step;
            if (performance.now() - t0 < 1000 * seconds) requestAnimationFrame(tick); else done();
        };
        requestAnimationFrame(tick);
    });
    const elapsed = (performance.now() - t0) / 1000;
    const drawn = Number(canvas.dataset.drawn) - drawn0;
    root.querySelector('button.play').click();
    return {drawn, frames, steps, elapsed};
}"""

_SCRUB = """([host, to]) => {
    const root = host.shadowRoot || host;
    const canvas = root.querySelector('canvas');
    const slider = root.querySelector('input.mv-player-slider');
    const before = {drawn: Number(canvas.dataset.drawn), step: canvas.dataset.step};
    slider.value = String(to);
    slider.dispatchEvent(new Event('input'));
    // read in the same task as the input event: no WebSocket message can have been handled in between
    const shown = {before, drawn: Number(canvas.dataset.drawn), step: canvas.dataset.step, frames: canvas.dataset.frames,
            caption: root.querySelector('.mv-player-caption').innerText};
    slider.dispatchEvent(new Event('change'));  // released: now Python hears of it
    return shown;
}"""


def test_playback_runs_in_the_browser(sample_db, sample_dashboard, page, screenshot):
    open_dashboard(page, sample_dashboard)
    player = page.locator(".mv-player").first
    canvas = player.locator("canvas")
    first = sample_db.documents.iloc[0]
    n, fps = int(first["n_frames"]), float(first["fps"])

    seconds = 3.0
    run = page.evaluate(_PLAYBACK, [player.element_handle(), seconds])
    drawn_fps = run["drawn"] / run["elapsed"]
    raf_fps = run["frames"] / run["elapsed"]
    steps_per_s = run["steps"] / run["elapsed"]
    record_timing("playback_fps", drawn_fps, "frames/s")
    record_timing("playback_raf_fps", raf_fps, "frames/s")
    record_timing("playback_steps_per_s", steps_per_s, f"steps/s (clip at {fps:g} fps, 1x)")
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    (ARTIFACTS / "playback_fps.txt").write_text(
        f"Database page player, headless Chromium: {drawn_fps:.1f} frames drawn/s, {raf_fps:.1f} animation frames/s, "
        f"{steps_per_s:.1f} clip steps/s (clip at {fps:g} fps, speed 1x), over {run['elapsed']:.2f} s\n")
    # the target is 30 frames drawn per second; the player can draw only the animation frames the browser
    # gives it, which a loaded CI machine's headless Chromium cuts below 30 (27 of 27 drawn in one CI run): it must
    # draw (nearly) every one of them, and 30 a second whenever the browser offers them
    assert run["drawn"] >= 0.9 * run["frames"] and drawn_fps >= min(30, 0.9 * raf_fps), run
    assert steps_per_s >= 0.5 * min(fps, raf_fps), run  # the clip advances at (about) its own rate
    expect(canvas).to_have_attribute("data-playing", "0")
    screenshot("played")

    # scrub: the drawn frame changes at once, without the server
    to = n // 2
    scrub = page.evaluate(_SCRUB, [player.element_handle(), to])
    assert scrub["step"] == str(to) and scrub["frames"] == str(to) and scrub["drawn"] == scrub["before"]["drawn"] + 1
    assert scrub["caption"].startswith(f"step {to + 1} of {n} ") and scrub["caption"].endswith(f"{n / fps:.2f} s at 1×")
    # ... and Python hears of it: "span starts here" takes the player's frame
    page.get_by_role("button", name="span starts here").click()
    expect(page.locator(".mv-span")).to_contain_text(f"{to}")
    player.locator("button", has_text="2×").click()  # the caption says how long the clip plays at the lit speed
    expect(player.locator(".mv-player-caption")).to_contain_text(f"step {to + 1} of {n} · {n / fps / 2:.2f} s at 2×")
    screenshot("scrubbed")

    # the camera: drag orbits, the wheel zooms; both redraw in the browser
    def redrawn(action) -> str:
        drawn = int(canvas.get_attribute("data-drawn"))
        action()
        page.wait_for_function("([c, n]) => Number(c.dataset.drawn) > n", arg=[canvas.element_handle(), drawn])
        return canvas.evaluate("c => c.toDataURL()")

    def drag():
        box = canvas.bounding_box()
        x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        page.mouse.move(x, y)
        page.mouse.down()
        page.mouse.move(x + 120, y + 40, steps=6)
        page.mouse.up()

    before = canvas.evaluate("c => c.toDataURL()")
    orbited = redrawn(drag)
    assert orbited != before
    assert redrawn(lambda: page.mouse.wheel(0, -400)) != orbited
    assert canvas.get_attribute("data-step") == str(to)  # the camera leaves the step alone
    screenshot("orbited")
