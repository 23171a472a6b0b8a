"""mocapviz.experiments.descriptions: event matching, sequence truth, composite streams, and the quality of the
shipped scene descriptions on real data (HDM05 cut clips, Bandai Namco 1, the CMU martial-arts takes)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mocapviz import MotionDB
from mocapviz.errors import ParameterError
from mocapviz.experiments.descriptions import (
    CMU_TAKES,
    clip_quality,
    cmu_sequence_quality,
    cmu_sequence_streams,
    composite_quality,
    composite_streams,
    composite_truth,
    event_quality,
    match_events,
    read_annotations,
    sequence_events,
)

ANNOTATION = Path(__file__).parent / "data" / "cmu135_kicks_punches.csv"


# ================================================================================================ event matching
def _hits(*rows):
    return pd.DataFrame(rows, columns=["rank", "doc_id", "start", "end"])


def _events(*rows):
    return pd.DataFrame(rows, columns=["doc_id", "start", "end"])


def test_match_events_by_hand():
    events = _events((0, 100, 200), (0, 300, 400), (1, 0, 50))
    # rank 1 overlaps both events of doc 0 (by 50 and by 10 frames): it takes the larger overlap, event 0; rank 2
    # overlaps event 0 only, which is taken: a false positive; rank 3 is in doc 1; rank 4 touches event 1 without
    # sharing a frame (half-open): false
    hits = _hits((1, 0, 150, 310), (2, 0, 120, 130), (3, 1, 40, 60), (4, 0, 400, 420))
    m = match_events(hits, events)
    assert m["matched"].tolist() == [0, -1, 2, -1]
    assert (m["tp"], m["hits"], m["events"]) == (2, 4, 3)
    assert m["precision"] == pytest.approx(0.5) and m["recall"] == pytest.approx(2 / 3)
    assert m["f1"] == pytest.approx(2 * 0.5 * (2 / 3) / (0.5 + 2 / 3))


def test_match_events_follows_the_rank_not_the_row_order():
    events = _events((0, 0, 100))
    hits = _hits((2, 0, 0, 100), (1, 0, 90, 95))  # the better-ranked hit comes second in the table
    assert match_events(hits, events)["matched"].tolist() == [-1, 0]


def test_match_events_ties_and_empty():
    events = _events((0, 10, 20), (0, 30, 40))
    assert match_events(_hits((1, 0, 15, 35)), events)["matched"].tolist() == [0]  # equal overlap: earliest event
    empty = match_events(_hits(), events)
    assert empty["tp"] == 0 and np.isnan(empty["precision"]) and empty["recall"] == 0
    none = match_events(_hits((1, 0, 0, 5)), _events())
    assert none["precision"] == 0 and np.isnan(none["recall"])
    with pytest.raises(ParameterError, match="doc_id, start, end"):
        match_events(pd.DataFrame({"doc_id": [0], "start": [0]}), events)


def test_sequence_events_by_hand():
    fps = 120.0
    ev = pd.DataFrame({"doc_id": [0, 0, 0, 0, 1, 1], "event": ["kick", "punch", "punch", "kick", "kick", "punch"],
                       "side": ["right", "left", "left", "right", "right", "right"],
                       "start": [0, 340, 400, 1000, 0, 100], "end": [100, 360, 420, 1100, 50, 120]})  # fmt: skip
    # kick 0 ends at 100; the punch at 340 starts exactly 2 s later (inside), the one at 400 is later still;
    # kick 3 has no punch after it; doc 1's punch is on the right side
    got = sequence_events(ev, {"event": "kick"}, {"event": "punch", "side": "left"}, 2.0, fps)
    assert got[["doc_id", "start", "end"]].values.tolist() == [[0, 0, 360]]
    assert len(sequence_events(ev, {"event": "kick"}, {"event": "punch", "side": "left"}, 1.99, fps)) == 0
    assert len(sequence_events(ev, {"event": "kick"}, {"event": "punch"}, 2.0, fps)) == 2
    assert len(sequence_events(ev, {"event": "punch"}, {"event": "kick"}, 2.0, fps)) == 0  # a punch before a kick
    # starting before the first event ends is not "after"
    overlap = pd.DataFrame({"doc_id": [0, 0], "event": ["kick", "punch"], "start": [0, 50], "end": [100, 150]})
    assert len(sequence_events(overlap, {"event": "kick"}, {"event": "punch"}, 2.0, fps)) == 0


# ================================================================================================ composite streams
def test_composite_streams_frames_and_truth(hdm05_db30):
    """The concatenated documents (real HDM05 clips at 30 Hz): frame count = the clips' sum minus one blend per
    joint; every clip is its source, translated on the floor, outside the blends; the A-then-B truth has one event
    per A-B pair, the reverse none."""
    sample_db = hdm05_db30
    pairs = [("kickLFront1Reps", "squat1Reps")]
    motions, metas, parts = composite_streams(sample_db, pairs, repeats=2, within=1.0, blend_s=0.1)
    fps = sample_db.fps
    blend = round(0.1 * fps)
    assert len(motions) == 5 and {m["actor"] for m in metas} == {"bd", "bk", "dg", "mm", "tr"}
    for k, (motion, meta) in enumerate(zip(motions, metas)):
        mine = parts[parts["stream"] == k].sort_values("order")
        assert motion.n_frames == mine["frames"].sum() - blend * (len(mine) - 1)
        assert list(mine["role"][:2]) == ["A", "B"] and list(mine["role"][-2:]) == ["A", "B"]
        assert (mine["start"].to_numpy()[1:] == mine["end"].to_numpy()[:-1] - blend).all()
        assert meta["derived"] == "concatenated HDM05 cut clips" and len(meta["clips"].split()) == len(mine)
        filler = mine[mine["role"] == "filler"]
        assert (filler["frames"].sum() - blend * len(filler)) / fps > 1.0  # B ... A more than `within` apart
        for _, clip in mine.iterrows():
            source = np.asarray(sample_db.motion(int(clip["doc_id"])).positions)
            inner = motion.positions[clip["start"] + blend : clip["end"] - blend]
            shift = inner - source[blend : len(source) - blend]
            assert np.allclose(shift[..., 1], 0, atol=1e-3)  # height unchanged
            assert np.allclose(shift, shift[0, 0], atol=1e-2)  # one translation for the whole clip
        # continuity: the root's floor position does not jump where clips meet
        step = np.linalg.norm(np.diff(motion.positions[:, 0, [0, 2]], axis=0), axis=1)
        assert step.max() < 25.0  # cm per frame at 30 Hz (27 km/h): no jump where clips meet
    parts["stream_doc"] = parts["stream"]
    truth = composite_truth(parts, 1.0, fps)
    assert len(truth) == 10  # two A-B pairs in each of five streams
    swapped = parts.assign(role=parts["role"].replace({"A": "B", "B": "A"}))
    assert len(composite_truth(swapped, 1.0, fps)) == 0
    with pytest.raises(ParameterError, match="repeats"):
        composite_streams(sample_db, pairs, repeats=0)
    with pytest.raises(ParameterError, match="one class"):
        composite_streams(sample_db, [("squat1Reps", "squat1Reps")])


# ================================================================================================ real clips
@pytest.fixture(scope="module")
def hdm05_120(hdm05_dir, tmp_path_factory):
    from mocapviz.relational.index import build

    db = MotionDB.ingest([hdm05_dir], tmp_path_factory.mktemp("hdm05-120") / "db", progress=False)
    return db, build(db, "2005", progress=False, save=False)


@pytest.fixture(scope="module")
def hdm05_quality(hdm05_120):
    db, indexes = hdm05_120
    return clip_quality(db, indexes=indexes)


# (description, least precision, least recall) on the 287 HDM05 cut clips, measured 2026-11 with the shipped
# library: kick_left 1.00 / 1.00 (29 clips), squat 0.85 / 0.98 (52), lie_down 1.00 / 0.95 (20), hop 0.97 / 0.86
# (36; 0.58 / 0.86 before its never / somewhere clauses), throw 0.78 / 1.00 (14; 0.35 / 1.00 before); the bars
# leave about one clip of slack each
BARS = [("kick_left", 0.95, 0.95), ("squat", 0.80, 0.95), ("lie_down", 0.95, 0.90), ("hop", 0.90, 0.80),
        ("throw", 0.70, 0.90)]  # fmt: skip


@pytest.mark.parametrize("name, precision, recall", BARS)
def test_shipped_descriptions_on_hdm05(hdm05_quality, name, precision, recall):
    row = hdm05_quality["per_description"].set_index("description").loc[name]
    assert row["precision"] >= precision and row["recall"] >= recall, row.to_dict()


def test_hdm05_fire_rates_elsewhere(hdm05_quality):
    q = hdm05_quality["per_description"].set_index("description")
    rates = hdm05_quality["fire_rates"]
    assert q.loc["kick_left", "fire_rate_other"] == 0  # the kick fires on nothing else
    assert rates.loc["kick_right", "kickLFront1Reps"] <= 0.05  # the other side's kick is not a right kick
    assert rates.loc["kick_right", "elbowToKnee1RepsLelbowStart"] <= 0.05  # a raised knee without a kick
    assert rates.loc["squat", "squat1Reps"] >= 0.95 and rates.loc["squat", "lieDownFloor"] <= 0.1
    # descriptions without a labelled HDM05 class get their fire rate only
    assert np.isnan(q.loc["clap", "precision"]) and q.loc["clap", "classes"] == ""
    assert len(rates.columns) == 11 and len(rates) == len(q)  # every class, every shipped description


def test_sides_on_bandai(bandai1_dir, tmp_path):
    """The one Bandai kick clip kicks with the right foot, punch 001 punches with the left hand, 002 with the right
    (seen in their feature runs): the kick fires on its own clip, not the other side's. punch_right fires on its clip
    (002), punch_left not on 001 (its hand is in front in 2 of the 5 punches, after the elbow straightened), each on
    at most 3 % of the other clips (measured, shipped library: 2.3 % and 0.6 %)."""
    db = MotionDB.ingest([bandai1_dir], tmp_path / "db", progress=False)
    q = clip_quality(db, ["kick_right", "kick_left", "punch_right", "punch_left"])
    fired = q["fired"]
    names = {d: set(fired.loc[fired["description"] == d, "name"]) for d in q["per_description"]["description"]}
    assert "dataset-1_kick_normal_001" in names["kick_right"] and "dataset-1_kick_normal_001" not in names["kick_left"]
    assert "dataset-1_punch_normal_002" not in names["punch_left"]  # never the other side's clip
    assert "dataset-1_punch_normal_001" not in names["punch_right"]
    assert "dataset-1_punch_normal_002" in names["punch_right"]
    per = q["per_description"].set_index("description")
    assert per.loc["punch_left", "clips"] == 1 and per.loc["punch_right", "clips"] == 1
    assert (per.loc[["punch_left", "punch_right"], "fire_rate_other"] <= 0.05).all()
    assert per.loc["kick_right", "recall"] == 1.0 and per.loc["kick_left", "tp"] == 0


def test_composite_quality_on_hdm05(hdm05_db30):
    """Templates learned without the stream's actor: "A then B" finds its pairs and "B then A" nothing (issue 25's
    targets: F1 >= 0.85, no reversed hit). Measured at each template's learned threshold: F1 0.87 (23 of 30 pairs,
    precision 1.00), 0 reversed hits; with the examples' worst cost as the threshold and matches reaching back into
    the motion before them 0.85 and 2. At one cost for every template, 0.1, more pairs are found and the reversed
    query finds template matches in the filler clips (counted, not asserted)."""
    res = composite_quality(hdm05_db30)
    s = res["summary"].iloc[0]
    assert s["events"] == 30 and s["f1"] >= 0.85 and s["reversed_hits"] == 0, s.to_dict()
    assert res["per_stream"]["reversed_hits"].sum() == s["reversed_hits"]
    assert set(res["hits"]["query"]) <= {"forward", "reversed"}
    wide = composite_quality(hdm05_db30, template_cost=0.1)["summary"].iloc[0]
    assert wide["f1"] >= 0.9 and wide["tp"] >= s["tp"], wide.to_dict()


# ================================================================================================ the CMU takes
@pytest.fixture(scope="module")
def cmu_120(cmu_dir, tmp_path_factory):
    return MotionDB.ingest([cmu_dir], tmp_path_factory.mktemp("cmu-120") / "db", progress=False)


def _annotation():
    if not ANNOTATION.is_file():
        pytest.skip(f"{ANNOTATION} is not there yet (the hand annotation of the CMU kicks and punches)")
    return ANNOTATION


def test_annotation_rows_are_inside_their_takes(cmu_120):
    table = read_annotations(_annotation(), cmu_120)  # raises for an unknown take or a frame past its end
    docs = cmu_120.documents.set_index("doc_id")
    assert set(table["name"]) <= set(CMU_TAKES)
    assert set(table["event"]) <= {"kick", "punch"} and set(table["side"]) <= {"left", "right"}
    assert (table["start"] >= 0).all() and (table["start"] < table["end"]).all()
    assert (table["end"].to_numpy() <= docs.loc[table["doc_id"], "n_frames"].to_numpy()).all()
    assert (docs.loc[table["doc_id"], "fps"] == 120).all()


def test_event_quality_on_cmu(cmu_120):
    table = read_annotations(_annotation(), cmu_120)
    res = event_quality(cmu_120, table)
    s = res["summary"].set_index("query")
    assert {"kick_right", "punch_left", "kick_right then punch_left within 2 s"} <= set(s.index)
    assert (s["tp"] <= s[["hits", "events"]].min(axis=1)).all()
    # measured with the shipped library: kick_right 1.00 / 1.00 (7 right kicks; 0.86 with Fig. 10's "rknee: straight
    # bent straight"), kick_left 1.00 / 1.00
    assert s.loc["kick_right", "precision"] >= 0.8 and s.loc["kick_right", "recall"] >= 0.9
    assert s.loc["kick_left", "precision"] >= 0.8 and s.loc["kick_left", "recall"] >= 0.8
    # the punches (issue 25): left 0.67 / 1.00 (F1 0.80), right 0.76 / 1.00 (F1 0.87) in the annotated takes with
    # "hand arrives in front, then within 0.1 s the elbow straightens"; with the progressions over the whole
    # in-front, above-neck and fast runs 0.57 / 0.80 and 0.91 / 0.77, before issue 25 0.38 / 0.60 and 0.50 / 0.46
    assert s.loc["punch_left", "recall"] >= 0.9 and s.loc["punch_right", "recall"] >= 0.9
    assert s.loc["punch_left", "f1"] >= 0.75 and s.loc["punch_right", "f1"] >= 0.8
    assert set(res["hits"]["doc_id"]) <= set(table["doc_id"]) | set(
        cmu_120.documents.loc[cmu_120.documents["name"].isin(CMU_TAKES), "doc_id"])


def test_read_annotations_rejects_bad_rows(tmp_path, cmu_120):
    bad = tmp_path / "a.csv"
    bad.write_text("file,event,side,start,end,certain,note\n135_02.amc,kick,right,50,40,1,\n")
    with pytest.raises(ParameterError, match="start < end"):
        read_annotations(bad)
    bad.write_text("file,event,side,start,end,certain,note\n135_02.amc,kick,right,0,99999999,1,\n")
    with pytest.raises(ParameterError, match="end after"):
        read_annotations(bad, cmu_120)
    bad.write_text("file,event,start,end\n135_02.amc,kick,0,10\n")
    with pytest.raises(ParameterError, match="side"):
        read_annotations(bad)


# ================================================================================================ CMU sequence streams
def test_cmu_sequence_streams_are_the_annotated_motion(cmu_120):
    """Derived documents: every kick and punch cut with its margin is its take's motion, translated on the floor,
    outside the blends; the events keep their frames; the units are apart by more than 2 s, so "kick then punch"
    has one true event per kick-punch unit and none in the punch-kick and single streams."""
    table = read_annotations(_annotation(), cmu_120)
    motions, metas, parts = cmu_sequence_streams(cmu_120, table, margin_s=0.75, blend_s=0.1)
    blend, fps = 12, 120.0
    kinds = {m["kind"] for m in metas}
    assert kinds == {"kick_punch", "punch_kick", "single"}
    assert all(m["derived"].startswith("cut and concatenated CMU 135") and m["label"] == "derived" for m in metas)
    by_name = cmu_120.documents.set_index("name")
    events = parts[parts["role"] != "filler"]
    # the two right punches of 135_02 that overlap an uncertain left thrust are left out; all certain rows else
    assert set(events.loc[events["kind"] == "single", "row"]) == set(table.index[table["certain"] == 1]) - {4, 6}
    for k, motion in enumerate(motions):
        mine = parts[parts["stream"] == k].sort_values("order")
        assert motion.n_frames == (mine["end"] - mine["start"]).sum() - blend * (len(mine) - 1)
        for _, clip in mine.iterrows():
            source = np.asarray(cmu_120.motion(int(by_name.loc[clip["take"], "doc_id"])).positions)
            source = source[clip["cut_start"] : clip["cut_end"]]
            inner = motion.positions[clip["start"] + blend : clip["end"] - blend]
            shift = inner - source[blend : len(source) - blend]
            assert np.allclose(shift[..., 1], 0, atol=1e-3) and np.allclose(shift, shift[0, 0], atol=1e-2)
            if clip["role"] != "filler":  # the event's frames, frame-exact, away from the blends
                row = table.loc[clip["row"]]
                assert clip["event_start"] - clip["start"] == row["start"] - clip["cut_start"] >= blend
                assert clip["end"] - clip["event_end"] == clip["cut_end"] - row["end"] >= blend
                assert 0 < row["start"] - clip["cut_start"] <= 90 and 0 < clip["cut_end"] - row["end"] <= 90
            else:
                assert clip["take"] in {"135_03", "135_05", "135_10"} and clip["end"] - clip["start"] == 300
    events = events.rename(columns={"role": "event"})
    events = events.assign(doc_id=events["stream"], start=events["event_start"], end=events["event_end"])
    truth = sequence_events(events, {"event": "kick"}, {"event": "punch"}, 2.0, fps)
    assert len(truth) == 14 and set(events.loc[truth["first_row"], "kind"]) == {"kick_punch"}
    right_left = sequence_events(events, {"event": "kick", "side": "right"}, {"event": "punch", "side": "left"},
                                 2.0, fps)  # fmt: skip
    assert len(right_left) == 7
    assert len(sequence_events(events, {"event": "punch"}, {"event": "kick"}, 2.0, fps)) == 14  # the punch-kick units


def test_cmu_sequence_quality(cmu_120):
    """kick then punch on the derived CMU streams (measured, shipped library: kick_right then punch_left P 1.00
    R 1.00, 7 of 7; (kick_left | kick_right) then (punch_left | punch_right) P 0.93 R 1.00, 14 of 14, one hit in a
    punch-kick stream; no hit of kick_right then punch_left in the punch-kick and single streams). Issue 25's
    target: recall >= 0.9 at precision >= 0.8."""
    res = cmu_sequence_quality(cmu_120, read_annotations(_annotation(), cmu_120))
    s = res["summary"].set_index("query")
    rl, any_ = s.loc["kick_right then punch_left within 2 s"], s.loc["kick then punch within 2 s"]
    assert rl["events"] == 7 and any_["events"] == 14
    assert rl["precision"] >= 0.8 and rl["recall"] >= 0.9, rl.to_dict()
    assert any_["precision"] >= 0.8 and any_["recall"] >= 0.9, any_.to_dict()
    assert rl["hits_punch_kick"] == 0 and rl["hits_single"] == 0
    assert (s["tp_both"] <= s["tp"]).all()
    per = res["per_kind"]
    assert per.loc[per["kind"] != "kick_punch", "tp"].sum() == 0  # no truth outside the kick-punch streams
