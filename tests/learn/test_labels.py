"""The label store keeps every label, lets a mentor's later word supersede for training, and never
damages its file."""

import json

import numpy as np
import pytest

from multiform.errors import InvalidInput
from multiform.learn.judge import Judge
from multiform.learn.labels import LabelRecord, LabelStore, records_from_episode

from .synthetic import episode

PLACE_OF = {"t0": "P1", "t1": "P2"}


def rec(source="demo_0", start=0, end=100, success=True, labeller="mentor", **kw):
    return LabelRecord(source, start, end, kw.pop("transition", "t0"), kw.pop("place", "P1"), success, labeller,
                       kw.pop("time", "2025-01-01T10:00:00+00:00"), **kw)


def test_append_reload_and_history(tmp_path):
    path = tmp_path / "labels.jsonl"
    store = LabelStore(path)
    store.add(rec(success=True))
    store.add_many([rec(start=100, end=200, success=False, labeller="alice"),
                    rec(success=False, labeller="bob", note="the swing was too wild")])
    store.add(rec(start=100, end=200, success=True, labeller="robot", score=0.8))
    lines = path.read_text().splitlines()
    assert json.loads(lines[0]) == {"__format__": {"kind": "labels", "version": 1}}
    again = LabelStore(path)
    assert again.records == store.records and len(again) == 4
    hist = again.history("demo_0", 0, 100)
    assert [r.labeller for r in hist] == ["mentor", "bob"] and [r.success for r in hist] == [True, False]
    eff = {r.key: r for r in again.effective()}
    assert eff[("demo_0", 0, 100)].labeller == "bob" and not eff[("demo_0", 0, 100)].success   # later mentor wins
    assert eff[("demo_0", 100, 200)].labeller == "alice"                                        # robot never trains
    assert again.effective(place="P2") == []


def test_store_revision_keeps_every_earlier_label(tmp_path):
    """20 new mentor labels on the robot's trials revise the judge fitted from the store; every
    earlier record is still in the store and still trains the judge."""
    store = LabelStore(tmp_path / "labels.jsonl")
    episodes = {f"demo_{i}": episode(100 + i) for i in range(40)}
    for src, ep in episodes.items():
        store.add_many(records_from_episode(src, ep.labels, PLACE_OF, time="2025-01-01T10:00:00+00:00"))
    n_before = len(store)
    j = Judge("P2", ("theta", "omega", "x"), kernels=("rbf", "linear")).fit_records(store.effective(place="P2"), episodes)
    assert len(j.y_) == 40

    trials = {f"trial_{i}": episode(500 + i) for i in range(20)}
    new = [LabelRecord(src, ep.labels[1].start, ep.labels[1].end, "t1", "P2", ep.labels[1].success, "alice")
           for src, ep in trials.items()]
    store.add_many(new)
    j.fit_records(store.effective(place="P2"), {**episodes, **trials})
    assert len(store) == n_before + 20 and len(j.y_) == 60
    assert set(j.keys_) >= {(r.source, r.start, r.end) for r in store.records if r.place == "P2" and
                            r.source.startswith("demo")}


def test_corrupt_file_is_reported_and_left_alone(tmp_path):
    path = tmp_path / "labels.jsonl"
    store = LabelStore(path)
    store.add_many([rec(), rec(start=100, end=200)])
    good = path.read_text()

    path.write_text(good + "{not json\n")
    with pytest.raises(InvalidInput, match="line 4") as e:
        LabelStore(path)
    assert "labels.jsonl" in str(e.value)
    with pytest.raises(InvalidInput, match="line 4"):
        store.add(rec(start=300, end=400))                    # a write re-validates first ...
    assert path.read_text() == good + "{not json\n"           # ... and leaves the file as it was

    obj = json.loads(good.splitlines()[1])
    del obj["success"]
    obj["start"] = -3
    path.write_text(good + json.dumps(obj) + "\n")
    with pytest.raises(InvalidInput) as e:
        LabelStore(path)
    msg = str(e.value)
    assert "line 4.success: is missing" in msg
    path.write_text(good.replace('"labels"', '"judge"'))
    with pytest.raises(InvalidInput, match="expected 'labels'"):
        LabelStore(path)
    path.write_text(good.replace('"version": 1', '"version": 7'))
    with pytest.raises(InvalidInput, match="version 7"):
        LabelStore(path)
    path.write_bytes(b"\x89PNG\x00\xff")
    with pytest.raises(InvalidInput, match="labels.jsonl"):
        LabelStore(path)


def test_bad_new_records_write_nothing(tmp_path):
    path = tmp_path / "labels.jsonl"
    store = LabelStore(path)
    store.add(rec())
    good = path.read_bytes()
    with pytest.raises(InvalidInput, match="end"):
        store.add_many([rec(start=500, end=600), rec(start=10, end=5)])
    with pytest.raises(InvalidInput, match="success"):
        store.add_many([{**rec().to_json(), "success": "yes"}])
    assert path.read_bytes() == good and len(store) == 1


def test_records_from_episode():
    ep = episode(3)
    recs = records_from_episode("demo_3", ep.labels, lambda t: PLACE_OF.get(t))
    assert [(r.place, r.transition, r.start, r.end) for r in recs] == \
        [("P1", "t0", ep.labels[0].start, ep.labels[0].end), ("P2", "t1", ep.labels[1].start, ep.labels[1].end)]
    assert all(r.labeller == "mentor" for r in recs)
    assert records_from_episode("demo_3", ep.labels, {"t0": "P1"})[0].place == "P1"
    assert len(records_from_episode("demo_3", ep.labels, {"t0": "P1"})) == 1
    assert np.all([r.time for r in recs])
