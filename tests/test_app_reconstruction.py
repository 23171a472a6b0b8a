"""The dashboard's Reconstruction page (Krüger et al. 2010 §5.2) on the embedded sample: in the browser, and its
bounds without one."""

from __future__ import annotations

import numpy as np
import pytest
from browser_helpers import (
    assert_no_exception_names,
    open_dashboard,
    open_tab,
    pick_document,
    picked_document,
    record_timing,
    timed,
)
from playwright.sync_api import expect

from mocapviz.app.pages.reconstruction import DEFAULT_NOISE_CM, SEED, check_settings, default_k
from mocapviz.errors import ParameterError
from mocapviz.motion.skeleton import heading
from mocapviz.similarity.reconstruction import (
    NOISE_RANGE_CM,
    PosePrior,
    reconstruct,
    reconstruction_errors,
    synthetic_markers,
)

TEST_DOC = 3  # HDM_dg_elbowToKnee1RepsLelbowStart_017_120: 100 frames of actor dg
ERROR = ".mv-recon-error p"
MESSAGE = ".mv-recon-message"


def _open_page(page, url: str) -> None:
    """Load the dashboard and show the Reconstruction tab."""
    open_dashboard(page, url)
    open_tab(page, "Reconstruction")
    page.locator(ERROR).get_by_text("mean error").wait_for(timeout=180_000)  # the session's clip, on opening


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
    pick_document(page, ".mv-recon-clip", TEST_DOC)
    page.locator(".mv-recon-prior select").select_option(label="without the test clip's actor")
    screenshot("options")
    ms = timed(lambda: page.locator(".mv-recon-run button").click(),
               lambda: page.locator(".mv-recon-summary", has_text="without actor dg's clips").wait_for(timeout=180_000))
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
    assert picked_document(page, ".mv-recon-clip") == 0  # the session's Selection.doc: the first document
    pick_document(page, ".mv-recon-clip", TEST_DOC)
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
    page.locator(".mv-input-note", has_text="marker noise ± cm must be 0–100: -1 was set to 0.").wait_for()
    expect(noise).to_have_value("0")
    noise.fill("1000000000")  # unbounded, 1e9 cm made the page unresponsive for minutes
    noise.press("Enter")
    page.locator(".mv-input-note", has_text="marker noise ± cm must be 0–100: 1,000,000,000 was set to 100.").wait_for()
    expect(noise).to_have_value("100")
    screenshot("k-too-large")
    pick_document(page, ".mv-recon-clip", 0)  # a CMU trial: no actor
    page.locator(".mv-recon-prior select").select_option(label="without the test clip's actor")
    page.locator(".mv-recon-run button").click()
    page.locator(MESSAGE).get_by_text("Document 0 has no actor label").wait_for()
    assert not page.locator(ERROR).is_visible()
    assert_no_exception_names(page)


def test_the_noise_is_bounded_by_the_library_and_the_box_by_the_same_range(sample_db):
    """The marker noise: at most 100 cm (NOISE_RANGE_CM) in the library, and the page's box ends there too."""
    from mocapviz.app.backend import Backend
    from mocapviz.app.pages.reconstruction import ReconstructionPage
    from mocapviz.app.state import Selection

    truth = np.zeros((3, 24, 3))
    assert np.abs(synthetic_markers(truth, 100.0, seed=0)).max() <= 100.0
    for bad in (100.01, 1e9, -0.1, float("inf")):
        with pytest.raises(ParameterError, match=r"noise_cm must be a number in \[0, 100\]"):
            synthetic_markers(truth, bad, seed=0)
        assert "must be a number in [0, 100]" in check_settings(sample_db, TEST_DOC, "clip", 16, bad)
    page = ReconstructionPage(Backend.open(sample_db.path), Selection())
    assert (page.noise.start, page.noise.end) == (NOISE_RANGE_CM.low, NOISE_RANGE_CM.high) == (0, 100)
    page.noise.value = 1e9
    assert page.noise.value == 100 and check_settings(sample_db, TEST_DOC, "clip", 16, page.noise.value) is None


def test_real_markers_of_a_c3d_clip_against_the_same_takes_amc(c3d_dir, cmu_dir, tmp_path):
    """The page's real-marker reconstruction (no browser): a database of the CMU takes and the C3D file of 135_02 at
    30 Hz; the C3D clip's own marker joints rebuilt, the AMC of the same take found by name, left out of the prior
    and used as the truth: the error is the experiment's (mocapviz.experiments.markers, measured at 120 Hz then
    resampled) within 0.5 cm; a clip read from an AMC is refused for real markers with the reason."""
    from mocapviz import MotionDB
    from mocapviz.app.backend import Backend
    from mocapviz.app.pages.reconstruction import check_settings, run_reconstruction, same_take
    from mocapviz.experiments.markers import marker_reconstruction

    db = MotionDB.ingest([cmu_dir, c3d_dir / "cmu_135_02.c3d"], tmp_path / "db", fps=30, progress=False)
    docs = db.documents.set_index("name")
    c3d, amc = int(docs.at["cmu_135_02", "doc_id"]), int(docs.at["135_02", "doc_id"])
    assert same_take(db, c3d) == amc and same_take(db, amc) is None
    assert "C3D file" in check_settings(db, amc, "clip", 256, 0.1, "real")
    assert check_settings(db, c3d, "clip", 256, 0.1, "real") is None
    result = run_reconstruction(Backend(db), c3d, "clip", "F15E", 256, 0.1, "real")
    assert result["truth_doc"] == amc and "135_02" not in result["left_out"] and str(amc) in result["left_out"]
    assert result["prior_frames"] == db.n_frames - docs.at["cmu_135_02", "n_frames"] - docs.at["135_02", "n_frames"]
    expected = marker_reconstruction(c3d_dir, cmu_dir).set_index("markers").loc["real (C3D marker clusters)"]
    assert abs(result["errors"]["mean_cm"] - expected["mean_cm"]) < 0.5
