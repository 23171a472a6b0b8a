"""Derived data brought up to date incrementally after an ingest (mocapviz.relational.index.extend,
mocapviz.features.numeric.extend_numeric, mocapviz.engine.derived.update_derived): for random splits of the demo's
documents into a first ingest and 1-3 later ones, the indexes and feature sets extended after each equal those
built from scratch over the whole database, array for array; what cannot be extended is rebuilt. ~15 s."""
from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import MotionDB
from mocapviz.db import layout
from mocapviz.engine.derived import update_derived
from mocapviz.errors import StaleDataError
from mocapviz.features.numeric import extend_numeric, load_numeric, numeric_features, store_numeric
from mocapviz.relational.index import build, extend, load, load_or_build

INDEX_ARRAYS = ("codes", "starts", "lengths", "doc_first_segment", "list_codes", "list_offsets", "positions", "rank")


@pytest.fixture(scope="module")
def demo():
    """The demo's 54 documents (HDM05, CMU, C3D; 7,187 frames at 30 Hz) as clips with their rows."""
    db = MotionDB.demo()
    return [(db.motion(int(d)), row) for d, row in zip(db.documents["doc_id"], _metas(db))]


def _metas(db):
    keep = ["name", "path", "format", "source_fps", "sha256", "label"]
    return [{k: row[k] for k in keep} for row in db.documents.to_dict("records")]


def _append(db: MotionDB, clips) -> MotionDB:
    return db.append_motions([m for m, _ in clips], [meta for _, meta in clips])


def _same_index(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for group, index in a.items():
        for name in INDEX_ARRAYS:
            np.testing.assert_array_equal(getattr(index, name), getattr(b[group], name), err_msg=f"{group}.{name}")
        assert index.meta == b[group].meta


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_extended_indexes_and_features_equal_a_rebuild(demo, tmp_path_factory, data):
    n = len(demo)
    n_later = data.draw(st.integers(1, 3), label="later ingests")
    cuts = sorted(data.draw(st.lists(st.integers(1, n - 1), min_size=n_later, max_size=n_later, unique=True),
                            label="cuts"))  # fmt: skip
    parts = [demo[a:b] for a, b in zip([0, *cuts], [*cuts, n])]
    db = _append(MotionDB.create(tmp_path_factory.mktemp("inc") / "db.mdb"), parts[0])
    build(db, "2005", progress=False)
    store_numeric(db, ["F15E"], progress=False)
    for part in parts[1:]:
        db = _append(db, part)
        with pytest.raises(StaleDataError):
            load(db, "2005")
        extended = extend(db, "2005")
        _same_index(extended, build(db, "2005", save=False, progress=False))
        _same_index(load(db, "2005"), extended)  # stored as extended, current
        np.testing.assert_array_equal(extend_numeric(db, "F15E")["F15E"], numeric_features(db, "F15E", progress=False))
    assert load_numeric(db, "F15E").shape == (db.n_frames, 15)


def test_update_derived_extends_what_is_stored_and_rebuilds_what_cannot_be_extended(demo, tmp_path):
    db = _append(MotionDB.create(tmp_path / "db.mdb"), demo[:40])
    build(db, "2005", progress=False)
    store_numeric(db, ["F15E", "Fp8"], progress=False)
    header = layout.numeric_header(db.path, "F15E")
    older = json.loads(header.read_text())
    del older["documents"]  # as stored by a mocapviz before headers recorded their documents
    header.write_text(json.dumps(older))
    db = _append(db, demo[40:])
    table = update_derived(db).set_index("set")
    assert table.loc["2005", "how"] == "extended" and table.loc["Fp8", "how"] == "extended"
    assert (table.loc["2005", "documents"], table.loc["2005", "frames"]) == (len(demo) - 40, db.n_frames - demo_frames(demo[:40]))
    assert table.loc["F15E", "how"] == "rebuilt"
    np.testing.assert_array_equal(load_numeric(db, "F15E"), numeric_features(db, "F15E", progress=False))
    assert (update_derived(db)["how"] == "current").all()


def test_a_reader_of_an_older_generation_does_not_replace_a_newer_index(demo, tmp_path):
    old = _append(MotionDB.create(tmp_path / "db.mdb"), demo[:50])
    new = _append(old, demo[50:])
    build(new, "2005", progress=False)
    mine = load_or_build(old, "2005")  # built for the older generation, in memory
    assert mine["lower"].meta["n_documents"] == 50
    assert load(new, "2005")["lower"].meta["n_documents"] == len(demo)  # still the newer one on disk


def demo_frames(clips) -> int:
    return sum(m.n_frames for m, _ in clips)
