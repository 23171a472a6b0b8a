"""Scene descriptions (Müller et al. 2005 §6.3): the language's errors, its answers through the relational index
against the frame-wise scan on real databases (every shipped description, sequences on CMU's long takes), learned
descriptions finding their templates' examples, and the `find` command."""
from __future__ import annotations

import time

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from mocapviz import MotionDB, ParameterError
from mocapviz.cli import main
from mocapviz.db.hits import COLUMNS
from mocapviz.errors import DescriptionError
from mocapviz.features import relational_features
from mocapviz.relational import description as language
from mocapviz.relational.description import (
    Event,
    Named,
    Sequence,
    declared_set,
    named_descriptions,
    parse_description,
)
from mocapviz.relational.index import build
from mocapviz.relational.scene import describe, find, find_by_scan
from mocapviz.relational.templates import learn_class, store_template
from mocapviz.relational.vocabulary import vocabulary_of, vocabulary_table

SEQUENCES = ["kick_right then punch_left within 2 s", "kick_left | kick_right", "squat then jump within 3 s",
             "(kick_left | kick_right) then (punch_left | punch_right) within 1.5 s"]  # fmt: skip


# ================================================================================================ the language
def test_every_feature_has_two_words_and_each_word_one_meaning():
    for relational_set in ("2005", "2006"):
        table = vocabulary_table(relational_set)
        words = vocabulary_of(relational_set)
        assert len(table) == len(words.features) and table["feature"].is_unique
        pairs = pd.concat([table[["part", "state_0"]].set_axis(["part", "word"], axis=1),
                           table[["part", "state_1"]].set_axis(["part", "word"], axis=1)])  # fmt: skip
        assert not pairs.duplicated().any(), pairs[pairs.duplicated()]
        for row in table.itertuples():
            assert words.resolve(row.part, [row.state_0, row.state_1]) == (row.feature, [0, 1])
            assert words.resolve(row.feature, ["0", "1", "*"]) == (row.feature, [0, 1, None])


def test_shipped_descriptions_read_and_print_back():
    for name, body in named_descriptions("2005").items():
        assert not isinstance(body, DescriptionError), (name, body)
        again = parse_description(f"define copy: {body}; copy").definitions["copy"]
        assert again == body, name
    d = parse_description("kick_right then punch_left within 2 s")
    assert isinstance(d.root, Sequence) and d.root.within == 2.0
    assert isinstance(d.root.first, Named) and isinstance(d.root.first.body, Event)
    assert parse_description("kick_right then punch_left").root.within == 2.0  # the default, docs/descriptions.md


@pytest.mark.parametrize("text, where, says", [
    ("rkne: straight bent straight", (1, 1), "unknown body part or feature 'rkne' in the 2005 set; did you mean 'rknee'"),
    ("rknee: straight bnt straight", (1, 17), "'bnt' is not a state of rknee in the 2005 set; did you mean 'bent'"),
    ("rknee: bent", (1, 1), "a progression needs at least two states"),
    ("rknee: straight straight bent", (1, 17), "'straight' twice in a row"),
    ("rfoot: lowered fast", (1, 1), "mixes the states of two features"),
    ("rknee: *  *", (1, 1), "at least one state other than *"),
    ("kick_right then punch_left within -1 s", (1, 35), "times and counts are numbers >= 0"),
    ("rknee: straight bent straight and rknee bent for 2..1 s", (1, 50), "the shortest time is longer"),
    ("kick_rigth", (1, 1), "unknown description 'kick_rigth'; did you mean 'kick_right'"),
    ("rknee: straight bent straight and overlap rknee bent, rfoot raised", (1, 55), "no progression of this event "
     "describes rfoot"),
    ("rknee: straight bent straight and overlap rknee bent[3], rknee bent", (1, 54), "has 1 'bent' state(s)"),
    ("rknee: straight bent straight\n  and rfoot: lowered raised lowered\n  then", (3, 7), "unexpected end of the text"),
    ("define k: rknee: straight bent straight\ndefine j: k; k", (2, 1), "end each definition with ';'"),
    ("set 2004; kick_right", (1, 5), "the relational sets are 2005, 2006"),
    ("set 2006; rhand: back in_front back", (1, 18), "'back' is not a state of rhand in the 2006 set"),
])  # fmt: skip
def test_bad_descriptions_say_what_and_where(text, where, says):
    with pytest.raises(DescriptionError) as err:
        parse_description(text)
    assert (err.value.line, err.value.column) == where, str(err.value)
    assert says in str(err.value) and str(err.value).startswith(f"line {where[0]}, column {where[1]}: ")
    assert isinstance(err.value, ParameterError)


def test_the_set_statement_and_the_set_argument():
    assert declared_set("set 2006; rfoot: lowered raised lowered") == "2006"
    assert parse_description("set 2006; rfoot: lowered raised lowered").root.progressions[0].feature == "rfoot_raised_2006"
    assert parse_description("rfoot: lowered raised lowered").root.progressions[0].feature == "rfoot_raised"
    with pytest.raises(DescriptionError, match="says 'set 2006;' but is read with the 2005 set"):
        parse_description("set 2006; rknee: straight bent straight", "2005")
    assert str(parse_description("set 2006; rknee: straight bent straight")).startswith("set 2006;")


# ================================================================================================ the answers
@pytest.fixture(scope="module")
def hdm05(hdm05_db30):
    """All 287 HDM05 cut clips (30 Hz), their 2005 indexes (not saved) and frame-wise values."""
    values, _ = relational_features(hdm05_db30, "2005", progress=False)
    return hdm05_db30, build(hdm05_db30, "2005", progress=False, values=values, save=False), values


@pytest.fixture(scope="module")
def cmu(cmu_db30):
    """The 32 CMU trials (30 Hz; long takes: martial arts, dance, walks)."""
    values, _ = relational_features(cmu_db30, "2005", progress=False)
    return cmu_db30, build(cmu_db30, "2005", progress=False, values=values, save=False), values


def _spans(hits: pd.DataFrame) -> list[tuple]:
    return sorted(zip(hits["doc_id"], hits["start"], hits["end"]))


def _same_answer(db, indexes, values, text) -> pd.DataFrame:
    every = find(db, text, indexes=indexes, overlapping=True)
    assert _spans(every) == _spans(find_by_scan(db, text, values=values, overlapping=True)), text
    best = find(db, text, indexes=indexes)
    scan = find_by_scan(db, text, values=values)
    assert best[["doc_id", "start", "end", "score"]].equals(scan[["doc_id", "start", "end", "score"]]), text
    return best


@pytest.mark.parametrize("name", list(named_descriptions("2005")))
def test_every_shipped_description_equals_the_frame_wise_scan(hdm05, name):
    db, indexes, values = hdm05
    hits = _same_answer(db, indexes, values, name)
    assert list(hits.columns[: len(COLUMNS)]) == COLUMNS and hits["rank"].tolist() == list(range(1, len(hits) + 1))
    assert (np.diff(hits["score"]) >= 0).all()
    assert np.allclose(hits["score"], (hits["end"] - hits["start"]) / 30.0)
    for doc, group in hits.groupby("doc_id"):  # the best of overlapping hits only
        spans = group.sort_values("start")
        assert (spans["start"].to_numpy()[1:] >= spans["end"].to_numpy()[:-1]).all(), doc


@pytest.mark.parametrize("text", SEQUENCES)
def test_sequences_on_long_takes_equal_the_frame_wise_scan(cmu, text):
    db, indexes, values = cmu
    hits = _same_answer(db, indexes, values, text)
    if " then " in text and len(hits):
        parts = hits["parts"].iloc[0]
        assert "/" in parts  # each named event's progressions and their frames
    for row in hits.itertuples():
        assert 0 <= row.start < row.end <= db.document(row.doc_id)["n_frames"]


def test_progression_framing_and_durations_on_a_real_clip(hdm05):
    """The hits of 'lknee: straight bent straight' are the knee's bent runs (read off the clip's own frame-wise
    values), plus one frame on either side; a duration bound keeps the runs of that length."""
    db, indexes, values = hdm05
    doc = int(db.select(label="kickLFront1Reps")["doc_id"].iloc[0])
    row = db.document(doc)
    col = values[row["start"] : row["start"] + row["n_frames"], vocabulary_of().features.index("lknee_bent")]
    cuts = np.flatnonzero(np.diff(col.astype(int))) + 1
    bounds = np.concatenate([[0], cuts, [col.size]])
    bent = [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if col[a] and a > 0 and b < col.size]
    hits = find(db, "lknee: straight bent straight", indexes=indexes, overlapping=True)
    got = sorted((s, e) for d, s, e in _spans(hits) if d == doc)
    assert got == [(a - 1, b + 1) for a, b in bent] and got
    longest = max(b - a for a, b in bent) / 30.0
    hits = find(db, f"lknee: straight bent straight and lknee bent for {longest - 1e-6:.6f}.. s", indexes=indexes,
                overlapping=True)  # fmt: skip
    assert len([s for d, s, e in _spans(hits) if d == doc]) == sum(b - a == round(longest * 30) for a, b in bent)


def test_an_empty_answer_says_which_part_found_nothing(hdm05):
    db, indexes, _ = hdm05
    hits = find(db, "kick_left then kick_left within 0.1 s", indexes=indexes)
    assert hits.empty and "kick_left then kick_left" in hits.attrs["empty_reason"]
    assert "kick_left (" in hits.attrs["empty_reason"]  # what its parts did find
    hits = find(db, "rknee: straight bent straight and rknee bent for 30.. s", indexes=indexes)
    assert hits.empty and hits.attrs["empty_reason"] == "'rknee' found nothing"


# ================================================================================================ learned descriptions
@pytest.mark.parametrize("label", ["kickLFront1Reps", "squat1Reps", "hopBothLegs1hops", "lieDownFloor"])
def test_a_described_template_finds_its_own_examples(sample_db, tmp_path, label):
    """describe(learn_class(...)) read back by find: every training clip of the sample's class is hit."""
    template = learn_class(sample_db, label)
    text = describe(template)
    assert text.splitlines()[1] == "set 2006;" and parse_description(text).relational_set == "2006"
    indexes = build(sample_db, "2006", progress=False, save=False)
    hits = find(sample_db, text, indexes=indexes)
    examples = set(template.meta["doc_ids"])
    assert examples <= set(hits["doc_id"]), (text, hits[["doc_id", "label"]])


def test_template_atoms(sample_db, tmp_path):
    db = MotionDB.ingest(sample_db.documents["path"].tolist(), tmp_path / "db", progress=False)
    kick = learn_class(db, "kickLFront1Reps")  # 2006 set
    store_template(db, kick, "kick-dg")
    hits = find(db, "template:kick-dg", template_cost=0.2)
    assert set(db.select(label="kickLFront1Reps")["doc_id"]) <= set(hits["doc_id"])
    assert hits.attrs["relational_set"] == "2006" and hits["parts"].str.startswith("template:kick-dg").all()
    with pytest.raises(DescriptionError, match="template:kick-dg was learned on the 2006 relational set"):
        find(db, "template:kick-dg then kick_left within 2 s", relational_set="2005")
    with pytest.raises(DescriptionError, match="^no stored template 'nothing-here' in .*; stored: kick-dg "):
        find(db, "template:nothing-here")


# ================================================================================================ the command
def test_find_command(sample_db, tmp_path, capsys):
    db = MotionDB.ingest(sample_db.documents["path"].tolist(), tmp_path / "db", progress=False)
    assert main(["index", str(db.path), "--quiet"]) == 0
    capsys.readouterr()
    out = tmp_path / "hits.csv"
    text = "lfoot: lowered raised lowered and lknee: straight bent straight and overlap lfoot raised, lknee bent"
    assert main(["find", str(db.path), text, "-K", "3", "--csv", str(out), "--explain"]) == 0
    printed = capsys.readouterr().out
    expected = find(db, text, n_matches=3)
    written = pd.read_csv(out)
    assert written[["doc_id", "start", "end"]].equals(expected[["doc_id", "start", "end"]].reset_index(drop=True))
    assert list(written.columns) == list(expected.columns)
    assert "matched: lfoot: " in printed and expected["parts"].iloc[0] in printed
    file = tmp_path / "kick.txt"
    file.write_text(f"# a left kick\ndefine k:\n    {text};\nk\n")
    assert main(["find", str(db.path), "--file", str(file), "-K", "3"]) == 0
    assert f"{len(expected)} hits" in capsys.readouterr().out
    assert main(["find", str(db.path), "lknee: straight bnt straight"]) == 1
    err = capsys.readouterr().err.strip()
    assert err == ("mocapviz: error: line 1, column 17: 'bnt' is not a state of lknee in the 2005 set; did you mean "
                   "'bent'?")  # fmt: skip
    assert main(["find", str(db.path), "kick_left", "--file", str(file)]) == 1
    assert "not both" in capsys.readouterr().err
    assert main(["find", "--list"]) == 0
    assert "kick_right:" in capsys.readouterr().out


def test_the_documentation_shows_the_grammar_and_words_the_code_uses():
    from pathlib import Path

    from mocapviz.relational.description import GRAMMAR

    doc = (Path(__file__).resolve().parent.parent / "docs" / "descriptions.md").read_text()
    assert GRAMMAR.strip() in doc
    for relational_set in ("2005", "2006"):
        for row in vocabulary_table(relational_set).itertuples():
            assert f"| `{row.feature}` | {row.group} | `{row.part}` | {row.state_0} | {row.state_1} |" in doc


def test_find_with_stored_templates_as_written_in_the_issue(sample_db, tmp_path, capsys):
    """`template:NAME` takes the names `mocapviz template learn` stores, hyphens included."""
    db = MotionDB.ingest(sample_db.documents["path"].tolist(), tmp_path / "db", progress=False)
    for label in ("kickLFront1Reps", "squat1Reps"):
        assert main(["template", "learn", str(db.path), "--label", label, "--actors", "dg,mm"]) == 0
    capsys.readouterr()
    out = tmp_path / "seq.csv"
    text = "template:kickLFront1Reps-dg-mm then template:squat1Reps-dg-mm within 4 s"
    assert main(["find", str(db.path), text, "-K", "1000", "--csv", str(out), "--template-cost", "0.3"]) == 0
    printed = capsys.readouterr().out
    expected = find(db, text, template_cost=0.3)
    assert f"{len(expected)} hits" in printed and len(pd.read_csv(out)) == len(expected) > 0
    for row in expected.itertuples():  # a kick's instance, then a squat's starting at most 4 s after it ends
        (_, k0, k1), (_, s0, s1) = [(p.split(" ")[0], *map(int, p.split(" ")[1].split(":")))
                                    for p in row.parts.split(", ")]  # fmt: skip
        assert row.start == k0 and row.end == s1 and 0 <= s0 - k1 <= 4 * db.document(row.doc_id)["fps"]


@pytest.mark.parametrize("text", ["lknee: straight bent straight and somewhere lfoot raised",
                                  "lknee: straight bent straight and never lfoot raised",
                                  "rarm: in sideways in and somewhere rhand above_neck and never arms crossed"])
def test_state_conditions_equal_the_scan_and_split_the_hits(hdm05, text):
    db, indexes, values = hdm05
    _same_answer(db, indexes, values, text)
    if "lknee" in text:  # somewhere and never split the event's hits between them
        base = "lknee: straight bent straight"
        counts = [len(find(db, t, indexes=indexes, overlapping=True)) for t in
                  (base, f"{base} and somewhere lfoot raised", f"{base} and never lfoot raised")]
        assert counts[0] == counts[1] + counts[2] and min(counts[1:]) > 0
    assert "never" in str(parse_description(text)) or "somewhere" in str(parse_description(text))


# ================================================================================================ hostile descriptions
# issue 37: untyped errors at the end of the text, RecursionError, exponential time, int64 overflow, 100 kB messages
def _doubling(levels: int) -> str:
    """A chain of definitions each using the previous one twice (doubling_defs_16.txt is 16 levels)."""
    return "".join(["define a0: rknee: straight bent;\n"] + [f"define a{k}: a{k - 1} | a{k - 1};\n"
                                                                  for k in range(1, levels + 1)] + [f"a{levels}"])


def _error(text: str) -> DescriptionError:
    with pytest.raises(DescriptionError) as err:
        parse_description(text)
    return err.value


@pytest.mark.parametrize("text, where, says", [
    ("squat;", (1, 6), "unexpected ';'; expected the end of the text"),
    ("kick_right )", (1, 12), "unexpected ')'; expected the end of the text"),
    ("rknee: straight bent then", (1, 26), "unexpected end of the text; expected '(' or 'overlap' or a name"),
    ("(squat then jump\n", (1, 17), "unexpected end of the text; expected"),
    ("define a: squat;\n# and nothing else", (2, 19), "the description has no query"),
    ("squat then jump within", (1, 23), "unexpected end of the text; expected a number"),
])  # fmt: skip
def test_errors_at_the_end_of_the_text_are_typed_and_placed(text, where, says):
    err = _error(text)
    assert (err.line, err.column) == where and says in err.reason, str(err)


def test_the_end_of_the_text_through_the_command(sample_db, capsys):
    for text, where in (("squat;", "line 1, column 6"), ("kick_right )", "line 1, column 12")):
        assert main(["find", str(sample_db.path), text]) == 1
        err = capsys.readouterr().err
        assert err.startswith(f"mocapviz: error: {where}: unexpected") and err.count("\n") == 1, err


@pytest.mark.parametrize("file, where, says", [
    ("then_chain_332.txt", (1, 557), f"a chain of 331 'then'; at most {language.MAX_THEN} in one chain"),
    ("deep_parens_492.txt", (1, 22), f"parentheses inside one another more than {language.MAX_PARENS} deep"),
])  # fmt: skip
def test_long_chains_and_deep_parentheses_are_refused_before_recursing(round3, sample_db, capsys, file, where, says):
    text = (round3 / "descriptions" / file).read_text()
    t0 = time.perf_counter()
    err = _error(text)
    assert (err.line, err.column) == where and says in err.reason and time.perf_counter() - t0 < 0.5, str(err)
    assert main(["find", str(sample_db.path), "--file", str(round3 / "descriptions" / file)]) == 1
    printed = capsys.readouterr().err
    assert printed == f"mocapviz: error: line {where[0]}, column {where[1]}: {err.reason}\n"  # one line, no traceback


def test_a_definition_used_twice_is_evaluated_once(hdm05, round3):
    """doubling_defs_16.txt took 11.4 s (each level doubled the time; 30 levels never finished): now one evaluation
    per definition. Every level's hits are those of the one progression, as the scan finds them too."""
    db, indexes, values = hdm05
    text = (round3 / "descriptions" / "doubling_defs_16.txt").read_text()
    assert text.strip() == _doubling(16)
    expected = _spans(find(db, "rknee: straight bent", indexes=indexes, overlapping=True))
    assert expected
    for levels in (16, 30, 49):
        t0 = time.perf_counter()
        hits = find(db, _doubling(levels), indexes=indexes, overlapping=True)
        assert time.perf_counter() - t0 < 2.0, levels
        assert _spans(hits) == expected and len(hits.attrs["counts"]) <= 3 * levels + 2
        assert hits["parts"].str.fullmatch(r"a0 \d+:\d+").all()  # the one leaf under every name
    assert _spans(find_by_scan(db, _doubling(30), values=values, overlapping=True)) == expected
    err = _error(_doubling(50))
    assert (err.line, err.column) == (51, 8) and f"at most {language.MAX_DEPTH}" in err.reason


@pytest.mark.parametrize("bound", ["9223372036854775808", "99999999999999999999999999999999999999", "100000000000"])
def test_a_time_bound_longer_than_the_documents_is_no_bound(hdm05, round3, bound):
    """huge_within.txt found nothing (the bound overflowed int64 after x fps); any bound past the documents' ends
    finds what 100000 s finds, through the index and the scan."""
    db, indexes, values = hdm05
    text = (round3 / "descriptions" / "huge_within.txt").read_text().replace("9223372036854775808", bound)
    assert f"within {bound} s" in text
    expected = find(db, "rknee: straight bent then lknee: straight bent within 100000 s", indexes=indexes)
    assert len(expected) == 65  # as 1e17 s found in the probe
    hits = find(db, text, indexes=indexes)
    assert hits[["doc_id", "start", "end", "parts"]].equals(expected[["doc_id", "start", "end", "parts"]])
    scan = find_by_scan(db, text, values=values)
    assert scan[["doc_id", "start", "end"]].equals(expected[["doc_id", "start", "end"]])


@pytest.mark.parametrize("make, where", [
    (lambda: "x" * 100_000, (1, language.MAX_CHARS + 1)),
    (lambda: "y" * 19_000, (1, 1)),
    (lambda: "rknee: straight bent and rfoot: lowered " + "y" * 5_000, (1, 41)),
    (lambda: "squat then jump within " + "9" * 10_000 + " s", (1, 24)),
    (lambda: "template:" + "t" * 10_000, (1, 1)),
    (lambda: "rknee: straight bent straight " + "bent straight " * 900 + "and overlap rknee bent[9999], rknee bent",
     (1, 12_654)),
    (lambda: "define " + "d" * 80 + ": squat;\n" + "d" * 79 + "x", (2, 1)),
    (lambda: "squat;" + "x" * 10_000, (1, 6)),
])  # fmt: skip
def test_messages_quote_a_bounded_excerpt(make, where):
    """A 100 kB name was echoed in a 100,068-character message: now no message quotes more than EXCERPT characters of
    the text."""
    text = make()
    err = _error(text)
    assert (err.line, err.column) == where, str(err)[:300]
    assert len(str(err)) < 300, str(err)[:300]
    quoted = [q for q in str(err).split("'")[1::2]]
    assert all(len(q) <= language.EXCERPT for q in quoted), str(err)


def test_the_limits_are_where_the_docs_say(capsys):
    """Each limit: a text at it is read, one past it refused, at the place it is passed; the docs' table gives the
    values of the constants."""
    from pathlib import Path

    doc = (Path(__file__).resolve().parent.parent / "docs" / "descriptions.md").read_text()
    for name in ("MAX_CHARS", "MAX_WORD", "MAX_PARENS", "MAX_THEN", "MAX_DEFINITIONS", "MAX_DEPTH", "MAX_PAIRS"):
        assert f"| `{name}` | {getattr(language, name):,} |" in doc, name
    chain = "squat" + " then squat" * language.MAX_THEN
    parse_description(chain)
    assert _error(chain + " then jump").column == len(chain) + 2
    parens = "(" * language.MAX_PARENS + "squat" + ")" * language.MAX_PARENS
    parse_description(parens)
    assert _error(f"({parens})").column == language.MAX_PARENS + 2
    defs = "".join(f"define d{k}: squat;\n" for k in range(language.MAX_DEFINITIONS))
    parse_description(defs + "d1")
    assert _error(f"{defs}define extra: jump;\nextra").line == language.MAX_DEFINITIONS + 1
    padded = "squat\n#" + "-" * (language.MAX_CHARS - 7)
    assert len(padded) == language.MAX_CHARS and parse_description(padded).root.name == "squat"
    assert (_error(padded + "-").line, _error(padded + "-").column) == (2, language.MAX_CHARS - 5)
    word = "a" * language.MAX_WORD
    assert parse_description(f"define {word}: squat; {word}").root.name == word
    assert f"at most {language.MAX_WORD}" in _error(f"define {word}b: squat; squat").reason
    longest = "template:" + "t" * 128  # the longest stored template name (templates.is_template_name)
    assert len(longest) == language.MAX_WORD and parse_description(longest).templates() == ["t" * 128]


def test_the_deepest_descriptions_run_in_a_thread_with_little_stack_left(hdm05, round3):
    """A served dashboard evaluates descriptions in threads already deep in the server's frames: the deepest the
    limits allow needs about 260 frames, so 400 left are enough; the refused ones never recurse."""
    import sys
    import threading

    db, indexes, _ = hdm05
    step = "rknee: straight bent"
    deepest = {
        "then": " then ".join([step] * (language.MAX_THEN + 1)),
        "parentheses": "(" * language.MAX_PARENS + f"{step} then {step} | {step}" + ")" * language.MAX_PARENS,
        "names": _doubling(49),
        "names and then": f"define a0: {' then '.join([step] * (language.MAX_THEN + 1))};\ndefine a1: a0 then "
                          + " then ".join([step] * 47) + ";\na1",
    }  # fmt: skip
    refused = [(round3 / "descriptions" / f).read_text() for f in ("then_chain_332.txt", "deep_parens_492.txt")]
    outcome = {}

    def run():
        def dive(n: int):
            if n > 0:
                return dive(n - 1)
            for name, text in deepest.items():
                outcome[name] = len(find(db, text, indexes=indexes))
            for text in refused:
                with pytest.raises(DescriptionError):
                    find(db, text, indexes=indexes)
            outcome["refused"] = True

        try:
            import inspect

            dive(sys.getrecursionlimit() - 400 - len(inspect.stack(0)))
        except BaseException as exc:  # noqa: BLE001 - reported in the test's thread
            outcome["error"] = exc

    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    assert "error" not in outcome, repr(outcome.get("error"))
    assert outcome["names"] > 0 and outcome["parentheses"] > 0 and outcome["refused"]


def test_a_join_past_the_limit_is_refused_before_it_is_made(hdm05, monkeypatch):
    """MAX_PAIRS bounds what one then or and may join (a bound longer than the documents joins every pair): the
    error names the part; every shipped description stays far below it."""
    from mocapviz.relational import scene

    db, indexes, _ = hdm05
    text = "rknee: straight bent then lknee: straight bent within 100000 s"
    pairs = len(find(db, text, indexes=indexes, overlapping=True))
    monkeypatch.setattr(scene, "MAX_PAIRS", pairs // 2)
    with pytest.raises(DescriptionError, match=r"rknee: straight bent then lknee: straight bent within 100000 s' "
                                               r"joins [\d,]+ pairs of hits; at most"):  # fmt: skip
        find(db, text, indexes=indexes)
    with pytest.raises(DescriptionError, match=r"^'kick_right' joins [\d,]+ pairs of hits"):
        monkeypatch.setattr(scene, "MAX_PAIRS", 1)
        find(db, "kick_right", indexes=indexes)


# ================================================================================================ against raw runs
# find and find_by_scan against hits counted here, straight from the boolean feature matrix (issue 37: the scan read
# the 2006 set's columns in another order, so comparing the two could not catch a 2006 error)
def _count_hits(db, values, names, feature, steps, durations=(), conditions=()) -> list[tuple[int, int, int]]:
    """(doc_id, start, end) of every hit of one progression, from ``values`` [shape=(N, f)] whose columns are
    ``names``: its L states matched against L consecutive maximal runs of the feature's column in one document
    (None: either), the hit from the last frame of the first run to the first frame of the last run (half-open);
    ``durations`` ((steps, low s, high s), None: unbounded) bound the runs at those steps; ``conditions`` ((kind,
    feature, value)) keep the hits where the state holds at some ("somewhere") or no ("never") frame."""
    hits = set()
    n = len(steps)
    for doc in db.documents.itertuples():
        x = values[doc.start : doc.start + doc.n_frames, names.index(feature)]
        change = np.flatnonzero(x[1:] != x[:-1]) + 1
        first, stop = np.r_[0, change], np.r_[change, x.size]
        seconds = (stop - first) / doc.fps
        for k in range(first.size - n + 1):
            if any(v is not None and x[first[k + i]] != v for i, v in enumerate(steps)):
                continue
            if not all((low is None or seconds[k + s] >= low - 1e-9) and (high is None or seconds[k + s] <= high + 1e-9)
                       for at, low, high in durations for s in at):  # fmt: skip
                continue
            a, b = int(stop[k] - 1), int(first[k + n - 1] + 1)
            held = [(values[doc.start + a : doc.start + b, names.index(f)] == v).any() for _, f, v in conditions]
            if all(h == (kind == "somewhere") for h, (kind, _, _) in zip(held, conditions)):
                hits.add((int(doc.doc_id), a, b))
    return sorted(hits)


def _best_first(db, hits: list[tuple[int, int, int]]) -> list[tuple[int, int, int]]:
    """The hits ranked by length in seconds, then by their first database frame, each kept unless it shares a frame
    with a better one of its document."""
    docs = db.documents.set_index("doc_id")
    ranked = sorted(hits, key=lambda h: ((h[2] - h[1]) / docs.loc[h[0], "fps"], docs.loc[h[0], "start"] + h[1]))
    kept: list[tuple[int, int, int]] = []
    for d, a, b in ranked:
        if all(d != e or b <= s or t <= a for e, s, t in kept):
            kept.append((d, a, b))
    return kept


def _progressions(node):
    """Every progression of a description tree."""
    if isinstance(node, Event):
        yield from node.progressions
    elif isinstance(node, Named):
        yield from _progressions(node.body)
    elif isinstance(node, Sequence):
        yield from _progressions(node.first)
        yield from _progressions(node.second)
    elif hasattr(node, "options"):
        for option in node.options:
            yield from _progressions(option)


def _rows(hits: pd.DataFrame) -> list[tuple[int, int, int]]:
    return [(int(d), int(s), int(e)) for d, s, e in zip(hits["doc_id"], hits["start"], hits["end"])]


def _agree(db, relational_set, indexes, values, names, text, spec=None) -> pd.DataFrame:
    """find == find_by_scan (the whole table, every hit and the best of overlapping ones); with ``spec`` (feature,
    steps, durations, conditions) of a one-progression text, both equal to the hits counted from ``values``."""
    found = find(db, text, relational_set=relational_set, indexes=indexes)
    pd.testing.assert_frame_equal(found, find_by_scan(db, text, relational_set=relational_set, values=values))
    every = find(db, text, relational_set=relational_set, indexes=indexes, overlapping=True)
    pd.testing.assert_frame_equal(every, find_by_scan(db, text, relational_set=relational_set, values=values,
                                                      overlapping=True))  # fmt: skip
    if spec is not None:
        counted = _count_hits(db, values, names, *spec)
        assert sorted(_rows(every)) == counted, text
        assert _rows(found) == _best_first(db, counted), text
    return every


def _check_shipped(db, relational_set) -> int:
    """Every usable shipped description of the set: find == find_by_scan; every progression in it, and every
    one-progression description whole, equal to the runs counted from the raw features. Returns the hits seen."""
    values, names = relational_features(db, relational_set, progress=False)
    indexes = build(db, relational_set, progress=False, values=values, save=False)
    seen = 0
    usable = {n: b for n, b in named_descriptions(relational_set).items() if not isinstance(b, DescriptionError)}
    assert len(usable) >= 9, relational_set
    for name, body in usable.items():
        spec = None
        if isinstance(body, Event) and len(body.progressions) == 1 and not body.overlaps:
            p = body.progressions[0]
            spec = (p.feature, p.values, [(d.ref.steps, d.low, d.high) for d in body.durations],
                    [(c.kind, c.feature, c.value) for c in body.conditions])  # fmt: skip
        seen += len(_agree(db, relational_set, indexes, values, names, name, spec))
        for p in _progressions(body):
            _agree(db, relational_set, indexes, values, names, str(p), (p.feature, p.values))
    return seen


@pytest.mark.parametrize("relational_set", ["2005", "2006"])
def test_shipped_descriptions_equal_runs_counted_from_the_features_on_the_sample(sample_db, relational_set):
    assert _check_shipped(sample_db, relational_set) > 0


@pytest.mark.parametrize("relational_set", ["2005", "2006"])
def test_shipped_descriptions_equal_runs_counted_from_the_features_on_hdm05(hdm05_db30, relational_set):
    assert _check_shipped(hdm05_db30, relational_set) > 100


def test_the_2006_reproducer_scan_equals_the_index(round3, sample_db):
    """set2006_scan.txt of issue 37 (scan 143 candidates, index and a count of the runs 192 on hdm30.mdb)."""
    text = (round3 / "descriptions" / "set2006_scan.txt").read_text()
    values, names = relational_features(sample_db, "2006", progress=False)
    indexes = build(sample_db, "2006", progress=False, values=values, save=False)
    p = parse_description(text).root.progressions[0]
    every = _agree(sample_db, "2006", indexes, values, names, text, (p.feature, p.values))
    assert len(every) > 10 and p.feature == "rknee_bent"
    assert vocabulary_of("2006").features.index("rknee_bent") != names.index("rknee_bent")  # what the scan read


@pytest.fixture(scope="module")
def sample_sets(sample_db) -> dict:
    """Set -> (indexes, values, names) of the sample (indexes not saved)."""
    out = {}
    for relational_set in ("2005", "2006"):
        values, names = relational_features(sample_db, relational_set, progress=False)
        out[relational_set] = build(sample_db, relational_set, progress=False, values=values, save=False), values, names
    return out


@st.composite
def _random_progression(draw):
    """(set, text, spec): a progression of 2..4 states of a random feature of either set, maybe with a duration on
    one of its states and a somewhere / never condition on any feature; spec as :func:`_count_hits` takes it."""
    relational_set = draw(st.sampled_from(["2005", "2006"]))
    words = vocabulary_of(relational_set)
    feature = draw(st.sampled_from(words.features))
    states = words.states(feature)
    steps = [draw(st.sampled_from([0, 1, None]))]
    for _ in range(draw(st.integers(1, 3))):  # a state never twice in a row (the language refuses it)
        steps.append(draw(st.sampled_from([0, 1, None] if steps[-1] is None else [None, 1 - steps[-1]])))
    assume(any(v is not None for v in steps))
    text = f"{words.part(feature)}: " + " ".join("*" if v is None else states[v] for v in steps)
    durations, conditions = [], []
    if draw(st.booleans()):
        value = draw(st.sampled_from([v for v in steps if v is not None]))
        low = draw(st.sampled_from([None, 0.05, 0.2, 0.5]))
        high = draw(st.sampled_from([h for h in (0.1, 0.4, 1.5) if low is None or h >= low] + [None] * (low is not None)))
        text += f" and {words.part(feature)} {states[value]} for {low or ''}..{high or ''} s"
        durations.append(([k for k, v in enumerate(steps) if v == value], low, high))
    if draw(st.booleans()):
        other, value, kind = draw(st.sampled_from(words.features)), draw(st.sampled_from([0, 1])), \
            draw(st.sampled_from(["somewhere", "never"]))  # fmt: skip
        text += f" and {kind} {words.part(other)} {words.states(other)[value]}"
        conditions.append((kind, other, value))
    return relational_set, text, (feature, steps, durations, conditions)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=_random_progression())
def test_random_progressions_find_equals_scan_equals_runs_counted(sample_db, sample_sets, case):
    relational_set, text, spec = case
    indexes, values, names = sample_sets[relational_set]
    every = _agree(sample_db, relational_set, indexes, values, names, text, spec)
    event("hits" if len(every) else "no hit")


# ============================================================================ an event written without a progression
_WORDS = vocabulary_table("2005")
_STATE = st.tuples(st.sampled_from(range(len(_WORDS))), st.sampled_from(["state_0", "state_1"]))


def _framed(row: int, column: str) -> tuple[str, str, str]:
    """(part, the state named, the progression framing it by the other state) of a vocabulary row."""
    w = _WORDS.iloc[row]
    other = w["state_1"] if column == "state_0" else w["state_0"]
    return w["part"], w[column], f"{w['part']}: {other} {w[column]} {other}"


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(a=_STATE, b=_STATE, low=st.sampled_from([None, 0.1, 0.2]), high=st.sampled_from([None, 0.5, 1.0]),
       form=st.sampled_from(["for", "overlap", "somewhere"]))
def test_an_event_without_a_progression_reads_as_the_states_it_names(hdm05, a, b, low, high, form):
    """docs/descriptions.md's clause examples typed alone (`rfoot raised for 0.1..1 s`, `overlap rknee bent, rfoot
    raised`, `somewhere rhand above_neck`): each state named is its run framed by the other state, so the answer is
    the one of the description written out with those progressions, and the frame-wise scan's."""
    db, indexes, values = hdm05
    (part_a, word_a, framed_a), (part_b, word_b, framed_b) = _framed(*a), _framed(*b)
    if form == "for":
        assume(low is not None or high is not None)
        clause = f"{part_a} {word_a} for {'' if low is None else low}..{'' if high is None else high} s"
        written = f"{framed_a} and {clause}"
    elif form == "overlap":
        assume(part_a != part_b and _WORDS.iloc[a[0]]["feature"] != _WORDS.iloc[b[0]]["feature"])
        clause = f"overlap {part_a} {word_a}, {part_b} {word_b}"
        written = f"{framed_a} and {framed_b} and {clause}"
    else:
        clause = f"somewhere {part_a} {word_a}"
        written = f"{framed_a} and {clause}"
    alone = _same_answer(db, indexes, values, clause)
    assert _spans(alone) == _spans(find(db, written, indexes=indexes)), (clause, written)
    event(f"{form}: {'hits' if len(alone) else 'no hit'}")


def test_never_alone_says_what_to_add():
    with pytest.raises(DescriptionError, match="'never arms crossed' only drops the hits of an event where it holds: "
                       "give the event a progression"):  # fmt: skip
        parse_description("never arms crossed")
