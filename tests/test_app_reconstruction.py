"""Browser tests of the dashboard's Reconstruction page (Krüger et al. 2010 §5.2) on the embedded sample."""

from __future__ import annotations

import numpy as np
from browser_helpers import assert_no_exception_names, open_dashboard, open_tab, record_timing, timed
from playwright.sync_api import expect

from mocapviz.app.pages.reconstruction import DEFAULT_NOISE_CM, SEED, default_k
from mocapviz.motion.skeleton import heading
from mocapviz.similarity.reconstruction import PosePrior, reconstruct, reconstruction_errors, synthetic_markers

TEST_DOC = 3  # HDM_dg_elbowToKnee1RepsLelbowStart_017_120: 100 frames of actor dg
ERROR = ".mv-recon-error p"
MESSAGE = ".mv-recon-message"


def _open_page(page, url: str) -> None:
    """Load the dashboard and show the Reconstruction tab."""
    open_dashboard(page, url)
    open_tab(page, "Reconstruction")
    page.locator(".mv-recon-run button").wait_for()


def _option(db, doc: int) -> str:
    """The clip selector's label of ``doc`` (as Backend.doc_options writes it)."""
    row = db.documents.set_index("doc_id").loc[doc]
    return f"{doc}: {row['name']} ({row['label']})"


def _expected_mean_cm(db, doc: int) -> float:
    """The page's default settings (F15E, default k, 1 mm noise, seed) with the prior without the clip's actor,
    computed with the library."""
    truth = np.asarray(db.positions[db.frames(doc)], dtype=np.float64)
    markers = synthetic_markers(truth, DEFAULT_NOISE_CM, np.random.default_rng([SEED, doc]))
    docs = db.documents.set_index("doc_id")
    frame_actor = docs["actor"].to_numpy()[docs.index.get_indexer(db.document_of(np.arange(db.n_frames)))]
    prior = PosePrior(db, valid=frame_actor != docs.at[doc, "actor"])
    estimate = reconstruct(markers, heading(truth), prior, numeric_set="F15E", k=default_k(db.n_frames))
    return reconstruction_errors(truth, estimate)["mean_cm"]


def test_reconstruct_a_clip(page, sample_dashboard, sample_db, screenshot):
    _open_page(page, sample_dashboard)
    page.locator(".mv-recon-clip select").select_option(label=_option(sample_db, TEST_DOC))
    page.locator(".mv-recon-prior select").select_option(label="without the test clip's actor")
    screenshot("options")
    ms = timed(lambda: page.locator(".mv-recon-run button").click(),
               lambda: page.locator(ERROR).get_by_text("mean error").wait_for(timeout=180_000))
    record_timing("reconstruction_sample_doc3_ms", ms, "ms")
    shown = page.locator(ERROR).inner_text()
    assert f"mean error {_expected_mean_cm(sample_db, TEST_DOC):.2f} cm" in shown, shown
    summary = page.locator(".mv-recon-summary p").inner_text()
    assert "HDM_dg_elbowToKnee1RepsLelbowStart_017_120" in summary and "without actor dg's clips" in summary
    assert "left: original · right: reconstruction" in page.locator(".mv-recon-caption p").inner_text()
    assert page.locator(".mv-recon-page .mv-player-caption p").inner_text().startswith("step 1 of 100")
    assert page.locator(".mv-recon-page .mv-player canvas").is_visible()
    assert page.locator(".mv-recon-page .mv-player canvas").get_attribute("data-clips") == "2"
    assert page.locator(".mv-recon-joints").is_visible() and page.locator(".mv-recon-frames").is_visible()
    assert not page.locator(MESSAGE).is_visible()
    screenshot("result")


def test_bad_choices_say_why(page, sample_dashboard, sample_db, screenshot):
    _open_page(page, sample_dashboard)
    clip = page.locator(".mv-recon-clip select")
    assert clip.input_value() == _option(sample_db, 0)  # the session's Selection.doc: the first document
    clip.select_option(label=_option(sample_db, TEST_DOC))
    frames = sample_db.n_frames - int(sample_db.documents.set_index("doc_id").at[TEST_DOC, "n_frames"])
    expect(page.locator(".mv-recon-k")).to_contain_text(f"k neighbours per frame (1–{frames:,})")  # the prior's size
    k = page.locator(".mv-recon-k input")
    k.fill("99999")  # more than the prior holds: k becomes its size, and the note says so
    k.press("Enter")
    page.locator(".mv-input-note", has_text=f"k neighbours per frame must be 1–{frames:,}: 99,999 was set to "
                                            f"{frames:,}.").wait_for()
    expect(k).to_have_value(str(frames))
    noise = page.locator(".mv-recon-noise input")
    noise.fill("-1")
    noise.press("Enter")
    page.locator(".mv-input-note", has_text="marker noise ± cm must be ≥ 0: -1 was set to 0.").wait_for()
    expect(noise).to_have_value("0")
    screenshot("k-too-large")
    clip.select_option(label=_option(sample_db, 0))  # a CMU trial: no actor
    page.locator(".mv-recon-prior select").select_option(label="without the test clip's actor")
    page.locator(".mv-recon-run button").click()
    page.locator(MESSAGE).get_by_text("Document 0 has no actor label").wait_for()
    assert not page.locator(ERROR).is_visible()
    assert_no_exception_names(page)
