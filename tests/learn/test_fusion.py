"""Trust in several mentors: fused labels recover a careless labeller's flips, a mentor whose
maneuvers fail loses weight (in the demonstrations and in practice), and one mentor is learned from
exactly as if there were no fusion."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from multiform.demos.episode import Episode, SegmentLabel
from multiform.errors import InvalidInput
from multiform.learn.fusion import OUTCOME, Fusion, Item, dawid_skene, estimate_fusion, stay_items
from multiform.learn.labels import LabelStore
from multiform.learn.training import LawSettings, fit_judge, fit_law, mentor_records
from multiform.petri.skillfile import load_skill
from multiform.task import load_task
from multiform.teach.record import record_by_mentors, record_many

pytest.importorskip("crowdkit")
NAMES = ("theta", "omega", "x", "xdot")
FAST = LawSettings(n_hyper=300, hyper_subsets=1, max_train=4000)


def test_dawid_skene_overrules_a_careless_labeller_by_the_outcome_the_careful_ones_vouch_for():
    rng = np.random.default_rng(0)
    items, truth = [], {}
    for k in range(90):
        who = ("ana", "bo", "cy")[k % 3]
        ok = bool(rng.random() < 0.6)
        said = ok if who != "cy" or rng.random() > 0.35 else not ok          # cy flips about a third
        seen = ok if rng.random() > 0.08 else not ok                          # the outcome view errs now and then
        key = (f"demo_{k}", 0, 10)
        items.append(Item(key, "P1", {who: said}, seen))
        truth[key] = ok
    post, trust = dawid_skene(items)
    fused = {k: p >= 0.5 for k, p in post.items()}
    cy_items = [it for it in items if "cy" in it.labels]
    assert sum(fused[it.key] == truth[it.key] for it in cy_items) > sum(it.labels["cy"] == truth[it.key]
                                                                        for it in cy_items)
    agreement = {w: d["agreement"] for w, d in trust["P1"].items()}
    assert agreement["cy"] < 0.8 < min(agreement["ana"], agreement["bo"]) and OUTCOME in agreement


@pytest.fixture(scope="module")
def several():
    """Two demos each by the pendulum's expert and poor mentors, and one by the average mentor."""
    task = load_task("pendulum")
    eps = record_by_mentors("pendulum", list(range(5)), [("expert", 2), ("poor", 2), ("average", 1)],
                            task.DEMO_ENV_KWARGS, workers=2)
    return load_skill(task.SKILL), eps


def test_estimates_are_recorded_with_their_evidence_and_read_back(several, tmp_path):
    apn, eps = several
    fusion = estimate_fusion(apn, eps, seed=0)
    assert fusion is not None and fusion.mentors == ["expert", "poor", "average"]
    table = fusion.table()
    for t, per in table["maneuvers"].items():
        for m, d in per.items():
            assert {"segments", "successes", "precision", "success", "weight", "practice"} <= set(d)
        assert max(d["weight"] for d in per.values()) == pytest.approx(1.0)
    assert set(table["labels"]) == {"P1", "P2"} and fusion.history[0]["when"] == "training"
    fusion.save(tmp_path / "mentors.json")
    back = Fusion.load(tmp_path / "mentors.json")
    assert back.table() == table and back.history == fusion.history
    (tmp_path / "bad.json").write_text('{"__format__": {"kind": "mentors", "version": 1}, "items": 3}')
    with pytest.raises(InvalidInput, match="bad.json"):
        Fusion.load(tmp_path / "bad.json")


def test_a_mentor_whose_segments_fail_loses_weight_in_that_maneuver(several):
    apn, eps = several
    # the poor mentor's balancing as it labelled it, but every catch of its demos falls at once after:
    # the outcome it was honest about for the others' tells the fused verdicts it failed
    failing = []
    for ep in eps:
        if ep.mentor != "poor":
            failing.append(ep)
            continue
        labels = [replace(lab, success=True) for lab in ep.labels]
        failing.append(replace(ep, labels=labels))
    base = estimate_fusion(apn, eps, seed=0)
    fusion = estimate_fusion(apn, failing, seed=0)
    assert fusion.weight("poor", "t3") <= base.weight("poor", "t3") + 1e-9
    assert fusion.weight("poor", "t3") < fusion.weight("expert", "t3")


def _segment_episode(theta: float, tag: str, mentor: str, seed: int, n: int = 600) -> Episode:
    rng = np.random.default_rng(seed)
    obs = np.column_stack([theta + 0.02 * rng.standard_normal(n), 0.1 * rng.standard_normal(n),
                           0.01 * rng.standard_normal(n), 0.01 * rng.standard_normal(n)])
    tags = np.array(["t1"] * 100 + [tag] * (n - 100))
    return Episode(obs=obs, actions=rng.standard_normal((n, 1)), transitions=tags, observation_names=NAMES,
                   command_names=("v_cmd",), dt=1e-3, seed=seed, outcome="success", mentor=mentor,
                   labels=[SegmentLabel(0, 100, "t1", True, mentor), SegmentLabel(100, n, tag, True, mentor)])


def test_practice_failures_where_the_robot_followed_a_mentor_lower_its_weight():
    apn = load_skill("pendulum_strict")
    demos = [_segment_episode(+0.1, "t3", "ana", 0), _segment_episode(+0.1, "t3", "ana", 1),
             _segment_episode(-0.1, "t3", "bo", 2), _segment_episode(-0.1, "t3", "bo", 3)]
    fusion = Fusion(["ana", "bo"], [], {"t3": {"ana": {"segments": 2, "successes": 2, "precision": 1.0},
                                               "bo": {"segments": 2, "successes": 2, "precision": 1.0}}})
    assert fusion.weight("bo", "t3") == pytest.approx(1.0)
    for k in range(6):                  # the robot balanced where bo did, and the judges failed it each time
        trial = _segment_episode(-0.1, "t3", "", 10 + k)
        assert fusion.observe_trial(apn, demos, trial, {(0, 100): True, (100, 600): False}) >= 1
    assert fusion.weight("bo", "t3") < 0.5 and fusion.weight("ana", "t3") == pytest.approx(1.0)
    assert fusion.practice["t3"]["bo"][1] > 5 and fusion.practice["t3"].get("ana", [0, 0])[1] < 0.5


def test_a_grader_whose_grades_the_trials_contradict_loses_agreement():
    apn = load_skill("pendulum_strict")
    fusion = Fusion(["ana", "bo"], [], {})
    for k in range(8):
        trial = _segment_episode(0.0, "t3", "", 20 + k)          # P2 stay to the end of a successful trial
        fusion.observe_grades(apn, trial, f"trial_{k}", [SegmentLabel(0, 600, "P2", True, "ana")])
        fusion.observe_grades(apn, trial, f"other_{k}", [SegmentLabel(0, 600, "P2", k % 4 == 0, "bo")])
    agree = {w: d["agreement"] for w, d in fusion.labels["P2"].items()}
    assert agree["bo"] < 0.5 < agree["ana"]


@pytest.fixture(scope="module")
def one_mentor():
    task = load_task("pendulum")
    return load_skill(task.SKILL), record_many("pendulum", [0, 1, 2, 3], task.DEMO_ENV_KWARGS, workers=2)


def test_one_mentor_is_learned_from_as_if_there_were_no_fusion(one_mentor, tmp_path):
    """A single mentor's file gives no trust estimate, and a fusion that trusts everyone alike gives
    the very law and judge arrays of the plain fit."""
    apn, eps = one_mentor
    assert estimate_fusion(apn, eps) is None
    alike = Fusion([eps[0].mentor], [], {t: {eps[0].mentor: {"segments": 3, "successes": 2, "precision": 1.0}}
                                         for t in ("t0", "t1", "t2", "t3")})
    plain, _ = fit_law(apn, eps, "balance", seed=0, settings=FAST)
    fused, _ = fit_law(apn, eps, "balance", seed=0, settings=FAST, fusion=alike)
    a, b = dict(np.load(_save(plain, tmp_path / "a.npz"))), dict(np.load(_save(fused, tmp_path / "b.npz")))
    arrays = [k for k in a if a[k].dtype.kind in "fiub"]
    assert a.keys() == b.keys() and len(arrays) >= 5 and all(np.array_equal(a[k], b[k]) for k in arrays)
    store = LabelStore()
    store.add_many(mentor_records(apn, eps))
    j1, i1 = fit_judge(apn, eps, store, "P2", seed=0)
    j2, i2 = fit_judge(apn, eps, store, "P2", seed=0, fusion=alike)
    assert np.array_equal(j1.X_, j2.X_) and np.array_equal(j1.y_, j2.y_) and i1 == i2


def _save(law, path):
    law.save(path)
    return path


def test_thinning_keeps_about_the_weight_of_a_mentors_samples(several):
    apn, eps = several
    fusion = estimate_fusion(apn, eps, seed=0)
    masks = fusion.sample_masks(eps, seed=0)
    for ep, mask in zip(eps, masks):
        for t in ("t2", "t3"):
            inside = ep.transitions == t
            w = fusion.weight(ep.mentor, t)
            if mask is None or inside.sum() < 2000:
                continue
            assert abs(mask[inside].mean() - w) < 0.05, (ep.mentor, t, w)
    assert fusion.switch_episodes(eps, "t1") == [ep for ep in eps if fusion.weight(ep.mentor, "t1") >= 0.5]


def test_stay_items_read_what_happened_next():
    apn = load_skill("pendulum_strict")
    ep = _segment_episode(0.0, "t3", "ana", 0)
    ep = replace(ep, outcome="failure", transitions=np.array(["t0"] * 200 + ["t1"] * 200 + ["t2"] * 200),
                 labels=[SegmentLabel(0, 200, "t0", True, "ana"), SegmentLabel(200, 400, "t1", True, "ana"),
                         SegmentLabel(400, 600, "t2", False, "ana")])
    items = {it.key: it for it in stay_items(apn, ep, "demo_0", {"P1", "P2"})}
    assert sorted(items) == [("demo_0", 0, 200), ("demo_0", 200, 400), ("demo_0", 400, 600)]
    assert items[("demo_0", 0, 200)].place == "P1" and items[("demo_0", 0, 200)].outcome   # t1 took it on to P2
    assert items[("demo_0", 200, 400)].place == "P2" and not items[("demo_0", 200, 400)].outcome  # fell back: t2
    assert not items[("demo_0", 400, 600)].outcome          # the demo ended there, and it was no success
