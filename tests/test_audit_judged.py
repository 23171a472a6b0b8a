"""The audit's precision judged by eye (issue 41 item 3; docs/audit.md "Precision, judged by eye"): the committed
judgements (``docs/audit_judged.csv``: the key of ``scripts/audit_judging.py`` joined with a blind judge's
verdicts) are whole, and the figures docs/audit.md states are the ones they give."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
VERDICTS = {"copy", "not a copy", "unsure"}


@pytest.fixture(scope="module")
def judged() -> pd.DataFrame:
    return pd.read_csv(DOCS / "audit_judged.csv")


def test_every_item_is_judged_once_and_the_kinds_are_as_drawn(judged):
    assert judged["item"].tolist() == list(range(1, len(judged) + 1))
    assert set(judged["verdict"]) <= VERDICTS and judged["reason"].str.len().min() > 0
    assert judged["kind"].value_counts().to_dict() == {"sample": 100, "decoy": 20, "planted": 10}
    threshold = judged["threshold"].iloc[0]
    assert (judged.loc[judged["kind"] != "decoy", "cost"] <= threshold).all()  # pairs the audit reports
    assert (judged.loc[judged["kind"] == "decoy", "cost"] > 6.0).all()  # above every learned threshold
    assert judged.loc[judged["kind"] == "planted", "name_b"].str.contains("~").all()  # a planted copy's name


def test_the_docs_state_the_figures_the_judgements_give(judged):
    text = (DOCS / "audit.md").read_text()
    copies = judged[judged["verdict"] == "copy"].groupby("kind").size().reindex(["sample", "decoy", "planted"],
                                                                                 fill_value=0)  # fmt: skip
    stated = re.search(r"judged copies: (\d+) of 100 sampled pairs, (\d+) of 20 decoys, (\d+) of 10 known copies",
                       text)  # fmt: skip
    assert stated, "docs/audit.md does not state the judged figures"
    assert [int(g) for g in stated.groups()] == copies.tolist()
