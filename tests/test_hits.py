"""One result convention (docs/glossary.md, Results): every search's hits as the same table, on a real database
mixing 120 Hz (HDM05) and 30 Hz (Bandai Namco) documents, in Python, on the command line (--csv) and on the
dashboard's pages; the old column names read with a warning; bad spans named."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from mocapviz import MotionDB, ParameterError
from mocapviz.cli import main
from mocapviz.db.hits import COLUMNS, database_frames, from_database_frames, hit_table
from mocapviz.features import store_numeric
from mocapviz.relational.index import build
from mocapviz.relational.query import query_by_example
from mocapviz.similarity.knn import KnnIndex, describe_frames
from mocapviz.similarity.motion_matching import graph_k, match_motion
from mocapviz.similarity.search import SimilaritySearch

FEATURES = ["rknee_bent", "lknee_bent", "rfoot_raised"]


@pytest.fixture(scope="module")
def mixed(hdm05_dir, bandai1_files, tmp_path_factory):
    """Two HDM05 clips (120 Hz) and two Bandai Namco takes (30 Hz), with the 2005 indexes and F15E stored."""
    amc = sorted((hdm05_dir / "amc").rglob("*.amc"))[:2]
    db = MotionDB.ingest([*amc, *bandai1_files[:2]], tmp_path_factory.mktemp("mixed") / "db", progress=False)
    assert sorted(db.documents["fps"]) == [30.0, 30.0, 120.0, 120.0]
    build(db, progress=False)
    store_numeric(db, ["F15E"], progress=False)
    return MotionDB.open(db.path)


def check_convention(db, hits: pd.DataFrame) -> None:
    """Every hit: the shared leading columns, in-document half-open frames, seconds at the document's own rate."""
    assert list(hits.columns[: len(COLUMNS)]) == COLUMNS
    docs = db.documents.set_index("doc_id")
    n_frames = docs.loc[hits["doc_id"], "n_frames"].to_numpy()
    fps = docs.loc[hits["doc_id"], "fps"].to_numpy()
    assert ((hits["start"] >= 0) & (hits["start"] < hits["end"]) & (hits["end"] <= n_frames)).all()
    assert (hits["frames"] == hits["end"] - hits["start"]).all()
    assert np.allclose(hits["start_s"], hits["start"] / fps) and np.allclose(hits["end_s"], hits["end"] / fps)
    assert hits["rank"].tolist() == list(range(1, len(hits) + 1))
    assert (hits["name"].to_numpy() == docs.loc[hits["doc_id"], "name"].to_numpy()).all()


def own_whole_hit(db, hits: pd.DataFrame, doc: int) -> pd.Series:
    """The hit covering all of document ``doc`` (a query finds itself): end = n_frames, end_s = its duration."""
    row = db.documents.set_index("doc_id").loc[doc]
    own = hits[(hits["doc_id"] == doc) & (hits["start"] == 0) & (hits["end"] == row["n_frames"])]
    assert len(own) == 1, hits.head()
    assert own["end_s"].iloc[0] == pytest.approx(row["n_frames"] / row["fps"])
    return own.iloc[0]


def test_every_search_returns_the_same_table_at_either_rate(mixed):
    db = mixed
    search = SimilaritySearch(db, "F15E")
    for doc in db.documents["doc_id"].astype(int):
        relational = query_by_example(db, db.motion(doc), FEATURES)
        check_convention(db, relational)
        own_whole_hit(db, relational, doc)
        clips = search.clips(doc, n_matches=4, mode="exact")
        check_convention(db, clips)
        assert own_whole_hit(db, clips, doc)["cost"] == pytest.approx(0.0, abs=1e-6)
        stretches = search.stretches(doc, n_matches=3, mode="exact")
        check_convention(db, stretches)
        assert stretches["doc_id"].iloc[0] == doc and stretches["cost"].iloc[0] == pytest.approx(0.0, abs=1e-6)
        n = int(db.documents.set_index("doc_id").loc[doc, "n_frames"])
        span = (n // 4, n // 4 + min(60, n // 2))
        for method in ("lng", "dtw"):
            matched = match_motion(db, doc, span, method=method, n_matches=3)
            check_convention(db, matched)
            best = matched.iloc[0]
            assert (best["doc_id"], best["start"], best["end"]) == (doc, *span), (method, matched.head())


def test_one_frame_hits_are_one_frame_stretches(mixed):
    db = mixed
    features = SimilaritySearch(db, "F15E").features  # the stored F15E
    index = KnnIndex(features)
    for doc in db.documents["doc_id"].astype(int):
        frame = int(db.documents.set_index("doc_id").loc[doc, "n_frames"]) // 2
        row = database_frames(db, doc, frame, frame + 1).start
        distances, frames = index.query(features[row], 5)
        hits = describe_frames(db, frames, distances)
        check_convention(db, hits)
        assert (hits["frames"] == 1).all()
        assert (hits["doc_id"].iloc[0], hits["start"].iloc[0], hits["distance"].iloc[0]) == (doc, frame, 0.0)


def test_database_frames_round_trip(mixed):
    db = mixed
    docs = db.documents.sort_values("start")
    rows = np.concatenate([docs["start"].to_numpy(), docs["start"].to_numpy() + docs["n_frames"].to_numpy() - 1])
    hits = hit_table(db, *from_database_frames(db, rows, rows + 1))
    check_convention(db, hits)
    for doc, start, end, row in zip(hits["doc_id"], hits["start"], hits["end"], rows):
        assert database_frames(db, int(doc), int(start), int(end)) == slice(int(row), int(row) + 1)
    with pytest.raises(ParameterError, match="hit 1: no document 99"):
        hit_table(db, [99], [0], [1])
    n = int(docs["n_frames"].iloc[0])
    with pytest.raises(ParameterError, match=str(n)):
        hit_table(db, [int(docs["doc_id"].iloc[0])], [0], [n + 1])
    with pytest.raises(ParameterError):
        hit_table(db, [int(docs["doc_id"].iloc[0])], [5], [5])  # an empty hit


def test_old_column_names_read_with_a_warning(mixed):
    db = mixed
    doc = int(db.documents["doc_id"].iloc[0])
    hits = query_by_example(db, db.motion(doc), FEATURES)
    with pytest.warns(FutureWarning, match="'start_frame' is now 'start'"):
        assert hits["start_frame"].tolist() == hits["start"].tolist()
    with pytest.warns(FutureWarning, match="'end_frame' is now 'end'"):
        assert hits["end_frame"].tolist() == (hits["end"] - 1).tolist()  # the old last frame, included
    with pytest.warns(FutureWarning, match="'last' is now 'end'"):
        assert hits["last"].tolist() == (hits["end"] - 1).tolist()


@pytest.mark.parametrize("command", ["search", "match", "query", "knn"])
def test_cli_csv_is_the_library_table(mixed, tmp_path, capsys, command):
    """`--csv` writes the same columns and numbers as the Python call, for a 30 Hz and a 120 Hz document."""
    db = mixed
    for doc in (int(d) for d in db.documents.groupby("fps")["doc_id"].first()):
        out = tmp_path / f"{command}-{doc}.csv"
        n = int(db.documents.set_index("doc_id").loc[doc, "n_frames"])
        if command == "search":
            args = ["--example", str(doc), "-K", "3", "--mode", "exact", "--no-exclude-document"]
            expected = SimilaritySearch(db, "F15E").clips(doc, n_matches=3, mode="exact")
        elif command == "match":
            span = (n // 4, n // 4 + 40)
            args = ["--example", str(doc), "--frames", f"{span[0]}:{span[1]}", "-K", "3"]
            expected = match_motion(db, doc, span, n_matches=3, exclude_document=True,
                                    k=graph_k(db.n_frames, db.typical_fps))  # the engine's default k
        elif command == "query":
            args = ["--example", str(doc), "--features", ",".join(FEATURES), "--no-exclude-document"]
            expected = query_by_example(db, db.motion(doc), FEATURES)  # (the kernel keeps the own document)
        else:
            args = ["--frame", f"{doc}:{n // 2}", "-k", "5", "--quiet", "--no-exclude-document"]
            features = SimilaritySearch(db, "F15E").features
            row = database_frames(db, doc, n // 2, n // 2 + 1).start
            distances, frames = KnnIndex(features).query(features[row], 5)
            expected = describe_frames(db, frames, distances)
        assert main([command, str(db.path), *args, "--csv", str(out)]) == 0, capsys.readouterr().err
        capsys.readouterr()
        written = pd.read_csv(out)
        check_convention(db, written)
        columns = [c for c in expected.columns if c != "path"]
        assert list(written.columns) == columns
        for c in ("doc_id", "start", "end", "frames"):
            assert written[c].tolist() == expected[c].tolist(), (command, c)
        for c in ("start_s", "end_s"):
            assert np.allclose(written[c], expected[c])


def test_dashboard_tables_are_the_library_table(mixed):
    """The Similarity page's tables (neighbours, LNG matches, search results) are the library's hit tables."""
    from mocapviz.app.backend import Backend
    from mocapviz.app.pages.similarity import match_span, nearest_frames, search_span

    db = mixed
    backend = Backend(db)
    for doc in (int(d) for d in db.documents.groupby("fps")["doc_id"].first()):
        n = int(db.documents.set_index("doc_id").loc[doc, "n_frames"])
        span = (n // 4, n // 4 + 40)
        near = nearest_frames(backend, "F15E", doc, n // 2, 5, False)
        check_convention(db, near)
        assert (near["doc_id"].iloc[0], near["start"].iloc[0], near["end"].iloc[0]) == (doc, n // 2, n // 2 + 1)
        lng = match_span(backend, "F15E", doc, span, 64, 3, False)
        check_convention(db, lng)
        assert (lng["doc_id"].iloc[0], lng["start"].iloc[0], lng["end"].iloc[0]) == (doc, *span)
        found = search_span(backend, "F15E", doc, span, "stretches", "exact", 3, False)
        check_convention(db, found)
        assert (found["doc_id"].iloc[0], found["start"].iloc[0], found["end"].iloc[0]) == (doc, *span)


@pytest.mark.parametrize("dropped", [None, 1])
def test_rows_found_with_consecutive_and_with_gapped_doc_ids(mixed, dropped):
    """Consecutive doc ids (every database, every shard) find a document's row by offset, others by search: the
    same names, frame rates and first frames either way, and an id the database lacks is named."""
    from mocapviz.db.hits import first_frames

    docs = mixed.documents
    kept = docs if dropped is None else docs[docs["doc_id"] != dropped].reset_index(drop=True)
    db = MotionDB(mixed.path, mixed.manifest, kept, {"positions": mixed.positions, "quaternions": mixed.quaternions})
    ids = kept["doc_id"].to_numpy()[::-1]
    table = hit_table(db, ids, np.zeros(len(ids), int), np.ones(len(ids), int))
    by_id = kept.set_index("doc_id")
    assert table["name"].tolist() == by_id.loc[ids, "name"].tolist()
    assert np.allclose(table["end_s"], 1 / by_id.loc[ids, "fps"].to_numpy())
    assert first_frames(db, ids).tolist() == by_id.loc[ids, "start"].tolist()
    for missing in [int(docs["doc_id"].max()) + 1, -1] + ([] if dropped is None else [dropped]):
        with pytest.raises(ParameterError, match=f"hit 2: no document {missing} in"):
            hit_table(db, [int(ids[0]), missing], [0, 0], [1, 1])
