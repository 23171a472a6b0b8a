"""Every path on a database of a real lab's mix (issue 38, item 6): labelled and unlabelled takes, three rigs, two
rates. One MotionDB, ingested, indexed (2005 and 2006) and given its numeric features through the CLI, holds

- the embedded sample's 22 HDM05 clips (ASF/AMC, 120 Hz; label, actor, class, take, split);
- one CMU take copied into a folder without ``labels.tsv`` (ASF/AMC, 120 Hz): no label of any kind;
- three Bandai Namco 1 files (BVH, another rig, 30 Hz): label = content and style, no actor, class or take;
- one C3D marker file (CMU 07_01, 120 Hz): no label of any kind.

Every command and option family runs on it and its answer is checked: the unlabelled documents are found like any
other, print and write as empty cells (never "nan", "NaN", "<NA>" or "None"), whole numbers stay whole (take 17,
not 17.0), and quality figures count only the labelled documents and say how many they left out.
"""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from mocapviz import MotionDB
from mocapviz.cli import main
from mocapviz.errors import ParameterError

BANDAI = ("dataset-1_bow_active_001", "dataset-1_bye_active_001", "dataset-1_kick_normal_001")
C3D = "cmu_07_01.c3d"
UNLABELLED = ("135_08", "cmu_07_01")  # the CMU take without labels.tsv and the C3D file
KICKS = ("HDM_dg_kickLFront1Reps_017_120", "HDM_mm_kickLFront1Reps_023_120")
MISSING_TEXT = ("nan", "NaN", "<NA>", "None")  # what a missing cell must never read as

pytestmark = pytest.mark.slow  # 22-35 s in all: the database built through the CLI (2-6 s), two local clusters (9-15 s)


@pytest.fixture(scope="module")
def mixed(tmp_path_factory, bandai1_files, c3d_dir) -> MotionDB:
    """The mixed database, built through the CLI (ingest, index 2005 and 2006, features)."""
    from mocapviz.io import datasets

    sample = datasets.sample()
    root = tmp_path_factory.mktemp("mixed")
    own = root / "own"  # a lab's own take: no labels.tsv beside it
    own.mkdir()
    shutil.copy(sample / "cmu-asfamc" / "asf" / "martialwalk.asf", own)
    shutil.copy(sample / "cmu-asfamc" / "amc" / "martialwalk" / "135_08.amc", own)
    bandai = [str(f) for f in bandai1_files if f.stem in BANDAI]
    assert len(bandai) == len(BANDAI)
    db = root / "db"
    quiet = ["--no-cluster", "--quiet"]
    assert main(["ingest", str(sample / "hdm05-cut"), str(own), *bandai, str(c3d_dir / C3D), "--out", str(db),
                 *quiet]) == 0  # fmt: skip
    for relational_set in ("2005", "2006"):
        assert main(["index", str(db), "--relational-set", relational_set, *quiet]) == 0
    assert main(["features", str(db), *quiet]) == 0
    return MotionDB.open(db)


@pytest.fixture(scope="module")
def ids(mixed) -> dict[str, int]:
    """Document name -> doc id."""
    return dict(zip(mixed.documents["name"], mixed.documents["doc_id"].astype(int), strict=True))


@pytest.fixture(scope="module")
def kick_template(mixed) -> str:
    """The template of kickLFront1Reps learned through the CLI (stored with the database): its name."""
    assert main(["template", "learn", str(mixed.path), "--label", "kickLFront1Reps"]) == 0
    return "kickLFront1Reps"


def _run(capsys, *args) -> tuple[int, str]:
    """``mocapviz ARGS`` in this process: (exit status, stdout + stderr)."""
    rc = main([str(a) for a in args])
    out = capsys.readouterr()
    return rc, out.out + out.err


def _csv(path) -> pd.DataFrame:
    """A CSV a command wrote, every cell as the text it holds ("" for an empty one)."""
    return pd.read_csv(path, dtype=str, keep_default_na=False)


def _assert_clean(table: pd.DataFrame, db: MotionDB) -> None:
    """No cell reads as a missing value's name; an unlabelled document's label columns are empty; a take is a whole
    number (17, not 17.0) or empty."""
    for column in table.columns:
        bad = table[column].isin(MISSING_TEXT)
        assert not bad.any(), f"column {column!r}: {table.loc[bad, column].tolist()[:3]}"
    label_columns = [c for c in db.label_columns if c in table]
    unlabelled = table["name"].isin(UNLABELLED)
    assert (table.loc[unlabelled, label_columns] == "").all().all()
    if "take" in table:
        assert table["take"].str.fullmatch(r"\d*").all(), table["take"].tolist()


def _assert_printed_clean(printed: str) -> None:
    """A printed table shows a missing cell as blank."""
    words = set(printed.split())
    assert not words & set(MISSING_TEXT), words & set(MISSING_TEXT)


# ============================================================================================ the database itself
def test_the_database_mixes_labels_rigs_and_rates(mixed, ids, capsys):
    docs = mixed.documents.set_index("name")
    assert len(docs) == 22 + 1 + len(BANDAI) + 1
    assert set(docs["format"]) == {"amc", "bvh", "c3d"} and set(docs["fps"]) == {30.0, 120.0}
    assert docs.loc[list(UNLABELLED), mixed.label_columns].isna().all().all()
    assert docs.loc[list(BANDAI), "label"].tolist() == ["bow", "bye", "kick"]
    assert docs.loc[list(BANDAI), "style"].tolist() == ["active", "active", "normal"]
    assert docs.loc[list(BANDAI), ["actor", "class", "take", "split"]].isna().all().all()
    assert docs.loc[list(BANDAI) + list(UNLABELLED), "fps"].tolist() == [30.0] * 3 + [120.0] * 2
    # a take beside documents without one stays a whole number (was float64: 17.0 in every table and CSV)
    assert str(docs["take"].dtype) == "Int64" and docs.loc[KICKS[0], "take"] == 17
    assert mixed.motion(ids["135_08"]).labels == {"label": None}  # was {'label': nan}, a truthy NaN
    assert mixed.motion(ids[BANDAI[0]]).labels == {"label": "bow", "content": "bow", "style": "active"}
    assert mixed.motion(ids[KICKS[0]]).labels["actor"] == "dg"

    rc, printed = _run(capsys, "info", mixed.path, "--documents")
    assert rc == 0
    summary = {line.split()[0]: line.split()[1:] for line in printed.splitlines()[1:] if line.strip()}
    assert summary["(none)"][0] == "2" and summary["bow"][0] == "1" and summary["total"][0] == str(len(docs))
    _assert_printed_clean(printed)
    assert mixed.summary().loc["(none)", "documents"] == 2

    rc, printed = _run(capsys, "check", mixed.path)
    assert rc == 0 and "DAMAGED" not in printed and "stale" not in printed
    assert "markers of document" in printed  # the C3D file's markers are checked too


# ============================================================================================== relational query
def test_query_by_a_labelled_and_an_unlabelled_example(mixed, ids, tmp_path, capsys):
    out = tmp_path / "kick.csv"
    rc, printed = _run(capsys, "query", mixed.path, "--no-exclude-document", "--example", ids[KICKS[0]], "--features",
                       "rknee_bent,lknee_bent", "-K", 30, "--csv", out)  # fmt: skip
    assert rc == 0
    kick = _csv(out)
    assert kick["name"].tolist() == list(KICKS) and kick["take"].tolist() == ["17", "23"]
    _assert_clean(kick, mixed)

    out = tmp_path / "own.csv"
    rc, printed = _run(capsys, "query", mixed.path, "--no-exclude-document", "--example", ids["135_08"], "--features",
                       "rknee_bent,lknee_bent", "-K", 30, "--csv", out)  # fmt: skip
    assert rc == 0
    own = _csv(out)
    assert own.loc[0, ["name", "start", "end", "score"]].tolist() == ["135_08", "0", "291", "0.0"]
    assert len(own) > 5 and (own["label"] != "").sum() == len(own) - 1  # found the labelled ones after itself
    _assert_clean(own, mixed)
    _assert_printed_clean(printed)

    rc, printed = _run(capsys, "query", mixed.path, "--no-exclude-document", "--example", ids[BANDAI[0]], "--relational-set", "2006",
                       "--mismatch", 1)  # a 30 Hz document without actor  # fmt: skip
    assert rc == 0 and printed.splitlines()[2].split()[1:3] == [str(ids[BANDAI[0]]), BANDAI[0]]
    rc, printed = _run(capsys, "query", mixed.path, "--no-exclude-document", "--example", ids["cmu_07_01"], "--mode", "exact",
                       "--features", "rknee_bent")  # fmt: skip
    assert rc == 0 and printed.splitlines()[2].split()[1:3] == [str(ids["cmu_07_01"]), "cmu_07_01"]
    _assert_printed_clean(printed)


# ======================================================================================================= find
def test_find_shipped_names_and_a_template(mixed, ids, kick_template, tmp_path, capsys):
    out = tmp_path / "find.csv"
    rc, printed = _run(capsys, "find", mixed.path, "kick_left", "--csv", out)
    assert rc == 0 and sorted(_csv(out)["name"]) == sorted(KICKS)
    rc, printed = _run(capsys, "find", mixed.path, "rknee: straight bent straight", "--csv", out)
    steps = _csv(out)
    assert rc == 0 and set(steps["name"]) & set(BANDAI)  # the 30 Hz takes are searched at their own rate
    _assert_clean(steps, mixed)
    out = tmp_path / "template.csv"
    rc, printed = _run(capsys, "find", mixed.path, f"template:{kick_template}", "--csv", out, "--explain")
    found = _csv(out)
    assert rc == 0 and set(KICKS) <= set(found["name"])
    _assert_clean(found, mixed)
    _assert_printed_clean(printed)


# ======================================================================================================== knn
def test_knn_of_an_unlabelled_and_a_labelled_frame(mixed, ids, tmp_path, capsys):
    out = tmp_path / "knn.csv"
    rc, printed = _run(capsys, "knn", mixed.path, "--frame", f"{ids['135_08']}:100", "-k", 20, "--per-document",
                       "--no-exclude-document", "--csv", out)  # fmt: skip
    own = _csv(out)
    assert rc == 0 and own.loc[0, ["name", "start", "distance"]].tolist() == ["135_08", "100", "0.0"]
    _assert_clean(own, mixed)
    _assert_printed_clean(printed)
    rc, printed = _run(capsys, "knn", mixed.path, "--frame", f"{ids[KICKS[0]]}:60", "-k", 10,
                       "--exclude-document", "--csv", out)  # fmt: skip
    kick = _csv(out)
    assert rc == 0 and len(kick) == 10 and KICKS[0] not in set(kick["name"])


# ====================================================================================================== match
def test_match_by_lng_and_dtw(mixed, ids, tmp_path, capsys):
    out = tmp_path / "dtw.csv"
    rc, printed = _run(capsys, "match", mixed.path, "--example", ids[KICKS[0]], "--method", "dtw", "-K", 10,
                       "--csv", out, "--paths")  # fmt: skip
    dtw = _csv(out)
    assert rc == 0 and dtw.loc[0, "name"] == KICKS[1] and len(dtw) == 10
    assert dtw["name"].isin(UNLABELLED).any()  # the C3D take moves like a kick somewhere
    _assert_clean(dtw, mixed)
    _assert_printed_clean(printed.split("path 1")[0])
    out = tmp_path / "lng.csv"
    rc, printed = _run(capsys, "match", mixed.path, "--example", ids[KICKS[0]], "-k", 1024, "--csv", out)
    assert rc == 0 and _csv(out)["name"].tolist() == [KICKS[1]]
    rc, printed = _run(capsys, "match", mixed.path, "--example", ids[BANDAI[1]], "-k", 1024, "--csv", out)
    lng = _csv(out)  # a 30 Hz query without an actor among 120 Hz clips
    assert rc == 0 and len(lng) >= 1 and BANDAI[1] not in set(lng["name"])  # its own document left out
    _assert_clean(lng, mixed)
    _assert_printed_clean(printed)


# ===================================================================================================== search
@pytest.mark.parametrize("example", ["135_08", KICKS[0]])
def test_search_clips_and_stretches_in_every_mode(mixed, ids, tmp_path, capsys, example):
    tables = {}
    for stretches in (False, True):
        for mode in ("fast", "exact", "brute"):
            out = tmp_path / f"{mode}-{stretches}.csv"
            rc, printed = _run(capsys, "search", mixed.path, "--example", ids[example], "--mode", mode, "-K", 8,
                               "--no-exclude-document", *(["--stretches"] if stretches else []),
                               "--csv", out)  # fmt: skip
            assert rc == 0
            tables[mode, stretches] = table = _csv(out)
            assert table.loc[0, ["name", "start", "cost"]].tolist() == [example, "0", "0.0"]
            _assert_clean(table, mixed)
            _assert_printed_clean(printed)
        pd.testing.assert_frame_equal(tables["exact", stretches], tables["brute", stretches])
    assert tables["exact", False]["name"].isin(UNLABELLED + BANDAI).any()  # other rigs and rates are ranked
    rc, printed = _run(capsys, "search", mixed.path, "--example", ids[example], "--exclude-document", "-K", 3)
    assert rc == 0 and example not in printed.split("\n", 1)[1]


def test_sharded_answers_equal_one_process_on_the_mixed_database(mixed, ids, tmp_path, capsys):
    """``--scheduler local``: the shards' label columns (one shard may hold none of a column's values) merge into
    the single process's table."""
    for command, options in (("search", ["--mode", "exact", "-K", 12]),
                             ("query", ["--features", "rknee_bent,lknee_bent", "-K", 30])):  # fmt: skip
        one, sharded = tmp_path / f"{command}-one.csv", tmp_path / f"{command}-sharded.csv"
        assert _run(capsys, command, mixed.path, "--example", ids["135_08"], *options, "--csv", one)[0] == 0
        assert _run(capsys, command, mixed.path, "--example", ids["135_08"], *options, "--csv", sharded,
                    "--scheduler", "local")[0] == 0  # fmt: skip
        assert one.read_text() == sharded.read_text()


# ================================================================================================== templates
def test_template_learn_and_search(mixed, ids, kick_template, tmp_path, capsys):
    from mocapviz.relational.templates import load_template

    kick = load_template(mixed, kick_template)
    assert kick.n_examples == 2 and kick.meta["negatives"] > 0  # the unlabelled takes are not "other classes"
    rc, printed = _run(capsys, "template", "learn", mixed.path, "--label", "bow")  # a class of one 30 Hz take
    assert rc == 0 and load_template(mixed, "bow").n_examples == 1
    rc, printed = _run(capsys, "template", "learn", mixed.path, "--label", "bow", "--actors", "dg")
    assert rc == 1 and "no document" in printed and "label 'bow' and actor in ['dg']" in printed
    assert "Traceback" not in printed
    out = tmp_path / "template.csv"
    rc, printed = _run(capsys, "template", "search", mixed.path, kick_template, "-K", 10, "--csv", out)
    hits = _csv(out)
    assert rc == 0 and set(hits["name"][:2]) == set(KICKS) and hits["name"].isin(BANDAI).any()
    _assert_clean(hits, mixed)
    _assert_printed_clean(printed)
    rc, printed = _run(capsys, "template", "search", mixed.path, "bow", "-K", 3, "--prefilter", "--max-cost", 0.2)
    assert rc == 0 and printed.splitlines()[2].split()[1:3] == [str(ids[BANDAI[0]]), BANDAI[0]]


# ===================================================================================================== export
def test_export_a_hit_table_with_unlabelled_hits(mixed, ids, tmp_path, capsys):
    hits = tmp_path / "hits.csv"
    assert _run(capsys, "match", mixed.path, "--example", ids[KICKS[0]], "--method", "dtw", "-K", 10,
                "--csv", hits)[0] == 0  # fmt: skip
    table = _csv(hits)
    rc, printed = _run(capsys, "export", mixed.path, "--hits", hits, "--format", "glb", "--out", tmp_path / "glb")
    written = sorted(p.name for p in (tmp_path / "glb").iterdir())
    assert rc == 0 and len(written) == len(table) and any("cmu_07_01" in name for name in written)
    rc, printed = _run(capsys, "export", mixed.path, "--hits", hits, "--format", "bvh", "--out", tmp_path / "bvh")
    assert rc == 1 and "C3D file" in printed and "--rig canonical" in printed and not (tmp_path / "bvh").exists()
    rc, printed = _run(capsys, "export", mixed.path, "--hits", hits, "--format", "bvh", "--rig", "canonical",
                       "--out", tmp_path / "bvh")  # fmt: skip
    assert rc == 0 and len(list((tmp_path / "bvh").iterdir())) == len(table)
    rc, printed = _run(capsys, "export", mixed.path, "--doc", ids["135_08"], "--format", "amc", "--out",
                       tmp_path / "amc")  # fmt: skip
    assert rc == 0 and sorted(p.suffix for p in (tmp_path / "amc").iterdir()) == [".amc", ".asf"]


# ================================================================================ what the dashboard's pages read
def test_database_page_filters_and_summary(mixed, ids):
    from mocapviz.app.documents import NO_PERFORMER, document_table, filter_documents
    from mocapviz.app.pages.database import _choices

    table = document_table(mixed.documents)
    by_name = table.set_index("name")
    assert by_name.loc[list(UNLABELLED), "label"].tolist() == ["", ""]
    assert by_name.loc[list(BANDAI) + ["cmu_07_01"], "performer"].eq(NO_PERFORMER).all()
    assert by_name.loc["135_08", "performer"] == "135"  # a CMU trial's subject, read from its name
    assert "" not in _choices(table["label"]) and {"bow", "squat1Reps"} <= set(_choices(table["label"]))
    assert filter_documents(table, labels=["bow"])["name"].tolist() == [BANDAI[0]]
    assert filter_documents(table, performers=["dg"])["doc_id"].tolist() == sorted(
        mixed.select(actor="dg")["doc_id"].astype(int))  # fmt: skip
    assert filter_documents(table, text="cmu_07")["name"].tolist() == ["cmu_07_01"]
    assert filter_documents(table, labels=["squat1Reps"], seconds=(0, 1.5))["name"].tolist() == [
        "HDM_dg_squat1Reps_033_120"]  # fmt: skip


def test_pages_that_read_labels(mixed, ids):
    from mocapviz.app.pages import correlations, reconstruction, templates
    from mocapviz.app.pages.retrieval import label_columns
    from mocapviz.viz.query import precision_recall

    docs = mixed.documents
    assert "bow" not in templates.class_options(docs) and "kickLFront1Reps" in templates.class_options(docs)
    assert templates.default_class(docs) == "depositFloorR"
    assert templates.actors_of(docs, "bow") == [] and templates.actors_of(docs, "squat1Reps") == ["dg", "mm"]
    assert correlations.default_clips(docs) == 2
    sample, why = correlations.sample_of(mixed, 2)
    assert not why and sample["label"].notna().all() and len(sample) == 22
    assert label_columns(docs, mixed.label_columns) == ["label", "actor", "class", "take", "split", "style"]
    with pytest.raises(ParameterError, match="no actor label"):
        reconstruction.prior_mask(mixed, ids[BANDAI[0]], "actor")
    valid, _ = reconstruction.prior_mask(mixed, ids[KICKS[0]], "actor")
    assert not valid[mixed.frames(ids[KICKS[0]])].any() and valid[mixed.frames(ids["135_08"])].all()
    kick = ids[KICKS[0]]
    curve = precision_recall([kick, ids["135_08"], ids[KICKS[1]]], docs, kick)
    assert curve["relevant"].tolist() == [False, True] and curve.attrs["n_relevant"] == 1
    with pytest.raises(ParameterError, match="has no label"):
        precision_recall([kick], docs, ids["135_08"])


def test_retrieval_quality_counts_labelled_documents_only(mixed, ids):
    """Queries are the 25 labelled documents; the 2 unlabelled ones are searched (ranked by every method) but never
    relevant, and the tables say so; an unlabelled query is refused (it was judged as a query of class None)."""
    from mocapviz.app.pages.retrieval import count_text
    from mocapviz.experiments.evaluation import relevance
    from mocapviz.experiments.retrieval import retrieval_quality

    result = retrieval_quality(mixed, methods=["exact", "lng256", "relational"], timing=False, progress=False)
    summary, per_query = result["summary"], result["per_query"]
    labelled = mixed.documents["label"].notna()
    assert summary.attrs["unlabelled"] == 2 and summary.attrs["documents"] == len(labelled)
    assert summary.attrs["queries"] == labelled.sum() == 25
    assert not per_query["query_doc"].isin([ids[n] for n in UNLABELLED]).any()
    exact = per_query[per_query["method"] == "exact"].set_index("query_doc")
    assert (exact["retrieved"] == len(labelled) - 1).all()  # every other document ranked, unlabelled ones too
    assert exact.loc[ids[KICKS[0]], "relevant_loo"] == 1 and exact.loc[ids[BANDAI[0]], "relevant_loo"] == 0
    assert "2 without a label: searched, never relevant" in count_text(summary, ["exact"], "label", "actor")
    ranking, n_relevant = relevance([ids["135_08"], ids[KICKS[1]]], mixed.documents.set_index("doc_id")["label"],
                                    ids[KICKS[0]])  # fmt: skip
    assert ranking["relevant"].tolist() == [False, True] and n_relevant == 1
    with pytest.raises(ParameterError, match=r"queries \[\d+\] have no 'label'"):
        retrieval_quality(mixed, methods=["exact"], queries=[ids["135_08"], ids[KICKS[0]]], timing=False,
                          progress=False)  # fmt: skip
    content = retrieval_quality(mixed, methods=["exact"], label_column="content", timing=False, progress=False)
    assert content["summary"].attrs["queries"] == len(BANDAI) and content["summary"].attrs["unlabelled"] == 24


def test_other_quality_figures_count_labelled_documents_only(mixed, ids):
    from mocapviz.experiments.descriptions import clip_quality
    from mocapviz.experiments.matching import numerical_search, similarity_matrices

    # a class whose graph matches reach the unlabelled takes (crashed: boolean value of NA is ambiguous)
    row = numerical_search(mixed, classes=["bow"], numeric_sets=("F15E",), factor=100, k=1024,
                           iterations=0).iloc[0]  # fmt: skip
    assert row["relevant"] == 0 and row["correct"] == 0 and 0 < row["wrong"] < 50
    quality = clip_quality(mixed, ["kick_left", "squat", "walk_step"])
    per = quality["per_description"].set_index("description")
    assert per.attrs["unlabelled"] == 2 and not quality["fired"]["name"].isin(UNLABELLED).any()
    assert (per["fire_rate"] * 25).round(9).eq((per["fire_rate"] * 25).round()).all()  # shares of 25 clips
    with pytest.raises(ParameterError, match="has no label"):
        similarity_matrices(mixed, ids["135_08"], (0, 60), numeric_sets=("F15E",))
    out = similarity_matrices(mixed, ids["135_08"], (0, 60), [ids[KICKS[0]]], numeric_sets=("F15E",), k=8)
    assert out["F15E"]["distance"].shape == (60, mixed.documents.set_index("name").loc[KICKS[0], "n_frames"])
    assert np.isfinite(out["F15E"]["distance"]).all()
