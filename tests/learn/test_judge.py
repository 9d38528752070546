"""Judges learn the mentor's criteria, are revised by new labels without losing old ones, and grade
whole trials; the kernel pool copes with the label sets a few demonstrations give."""

import dataclasses

import numpy as np
import pytest

from multiform.errors import InvalidInput
from multiform.io import load_npz, save_npz
from multiform.learn.features import feature_names, segment_from_episode, trajectory_features
from multiform.learn.judge import KIND, VERSION, Judge, SegmentGrade, TrialGrade, credit_handovers, grade_episode
from multiform.learn.kernel_pool import KernelPoolClassifier, platt_fit, platt_score
from multiform.learn.labels import LabelRecord

from .synthetic import balanced_segments, episode, segments

VARS = ("theta", "omega", "x")


@pytest.fixture(scope="module")
def judges():
    out = {}
    for place in ("P1", "P2"):
        train, y = balanced_segments(place, 120, 1)
        out[place] = Judge(place, VARS).fit(train, y)
    return out


@pytest.mark.parametrize("place,floor", [("P1", 0.85), ("P2", 0.88)])
def test_held_out_accuracy_and_pool_report(judges, place, floor):
    j = judges[place]
    test, y = balanced_segments(place, 300, 2)
    acc = float((j.predict(test) == y).mean())
    print(f"\n{j.summary()}\nheld-out accuracy {acc:.3f} on {len(y)} segments")
    assert acc >= floor
    assert set(j.cv_scores_) == {"rbf", "poly", "linear", "sigmoid"}
    assert all(np.isfinite(r["score"]) for r in j.cv_scores_.values())
    assert j.cv_scores_[j.best_kernel_]["score"] == max(r["score"] for r in j.cv_scores_.values())
    s = j.grade_many(test)
    assert np.all((s >= 0) & (s <= 1))
    diverged = dataclasses.replace(test[0], values=np.where(np.arange(len(test[0].values))[:, None] > 5, np.nan,
                                                           test[0].values))
    assert j.grade(diverged) == 0.0


def test_features_have_names_and_known_values():
    v = np.array([[0.0, 1.0], [2.0, -3.0], [1.0, 0.5]])
    f = trajectory_features(v, 0.01)
    names = feature_names(["a", "b"])
    assert len(f) == len(names) == 15
    got = dict(zip(names, f))
    assert got["a.start"] == 0 and got["a.end"] == 1 and got["a.max"] == 2 and got["b.min"] == -3
    assert got["b.absmax"] == 3 and got["a.mean"] == 1 and got["duration"] == pytest.approx(0.03)


def test_twenty_new_labels_revise_a_judge_and_keep_the_old():
    # demonstrations only ever ended near the centre, so the judge learned "balanced = theta small"
    old, y_old = segments("P2", 80, 10, x_range=(0.0, 0.1))
    j = Judge("P2", VARS).fit(old, y_old)
    # the mentor then labels 20 trials that stayed upright but drifted to the workspace edge: failures
    new, y_new = segments("P2", 20, 11, amp_range=(0.02, 0.2), x_range=(0.25, 0.35))
    alike, y_alike = segments("P2", 100, 12, amp_range=(0.02, 0.2), x_range=(0.25, 0.35))
    before_new = (j.predict(new) == y_new).mean()
    before_alike = (j.predict(alike) == y_alike).mean()
    old_X, old_keys = j.X_.copy(), list(j.keys_)

    j.revise(new, y_new)
    after_new = (j.predict(new) == y_new).mean()
    after_alike = (j.predict(alike) == y_alike).mean()
    print(f"\nagreement with the 20 new labels {before_new:.2f} -> {after_new:.2f}; "
          f"on 100 unseen segments like them {before_alike:.2f} -> {after_alike:.2f}")
    assert before_new <= 0.5 and after_new >= 0.9          # decisions changed where the labels say so
    assert after_alike >= 0.9
    assert len(j.y_) == 100                                  # nothing lost: 80 old + 20 new rows
    np.testing.assert_array_equal(j.X_[:80], old_X)
    np.testing.assert_array_equal(j.y_[:80], y_old)
    assert j.keys_[:80] == old_keys
    assert (j.predict(old) == y_old).mean() >= 0.9           # and it still agrees with the old labels


def test_relabelling_a_segment_replaces_its_row():
    segs, y = segments("P2", 30, 20)
    j = Judge("P2", VARS, kernels=("rbf",)).fit(segs, y)
    j.revise(segs[:3], ~y[:3])
    assert len(j.y_) == 30
    np.testing.assert_array_equal(j.y_[:3], ~y[:3])
    np.testing.assert_array_equal(j.y_[3:], y[3:])
    extra, y_extra = segments("P2", 2, 21)
    j.revise([extra[0], extra[1], extra[0]], [True, False, False])      # the last word on a segment counts
    assert len(j.y_) == 32 and list(j.y_[30:]) == [False, False]
    diverged = dataclasses.replace(extra[1], source="trial_9", values=extra[1].values * np.nan)
    with pytest.raises(InvalidInput, match=r"trial_9\[0:"):
        j.revise([diverged], [False])


def test_degenerate_label_sets():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(7, 3))
    only = KernelPoolClassifier().fit(X[:4], [True] * 4)
    assert only.best_kernel_ == "constant"
    np.testing.assert_allclose(only.score_samples(X), 5 / 6)             # Laplace: (n + 1) / (n + 2)
    one_fail = KernelPoolClassifier().fit(X[:5], [True, True, True, True, False])
    assert one_fail.calibration_ == "in-sample" and one_fail.decision_ is not None
    assert np.all(np.isnan([r["score"] for r in one_fail.cv_scores_.values()]))
    few = KernelPoolClassifier(cv=5).fit(X[:6], [True, True, True, False, False, False])
    assert few.n_splits_ == 3 and few.calibration_ == "cross-validated"
    for m in (only, one_fail, few):
        s = m.score_samples(X)
        assert np.all((s >= 0) & (s <= 1))
        np.testing.assert_array_equal(m.predict(X), s >= 0.5)


def test_platt_scaling_is_calibrated_on_noisy_scores():
    rng = np.random.default_rng(1)
    f = rng.normal(size=20000) * 2
    p_true = 1 / (1 + np.exp(-1.5 * f + 0.3))
    y = rng.random(20000) < p_true
    A, B = platt_fit(f, y)
    assert A == pytest.approx(-1.5, abs=0.08) and B == pytest.approx(0.3, abs=0.08)
    A, B = platt_fit(np.r_[-np.ones(5), np.ones(5)], np.r_[np.zeros(5, bool), np.ones(5, bool)])
    assert np.isfinite(A) and 0.5 < platt_score(1.0, A, B) < 1          # separable: finite, not 1


def test_grade_episode_scores_places_and_the_trial(judges):
    ep = episode(5)
    place_of = {"t0": "P1", "t1": "P2"}
    labels = [LabelRecord("trial_5", lab.start, lab.end, lab.transition, place_of[lab.transition],
                          not lab.success) for lab in ep.labels]                  # a contrary mentor
    g = grade_episode(ep, judges, place_of, source="trial_5", labels=labels)
    assert [s.place for s in g.segments] == ["P1", "P2"]
    seg = segment_from_episode(ep, g.segments[0].start, g.segments[0].end, VARS)
    assert g.places["P1"] == pytest.approx(judges["P1"].grade(seg))
    assert g.score == pytest.approx(min(g.places.values()))
    assert len(g.disagreements()) == sum(s.success == lab.success for s, lab in zip(g.segments, ep.labels))
    prod = grade_episode(ep, judges, place_of, combine="product")
    assert prod.score == pytest.approx(np.prod(list(prod.places.values())))
    # a trial that never reached P2 gets 0 for it
    short = episode(5)
    short.transitions = np.array(["t0"] * len(short.transitions))
    assert grade_episode(short, judges, place_of).score == 0.0


def test_a_stay_shorter_than_any_taught_is_passed_through(judges):
    """A way back and the way in firing within a few ticks (P2 for 3 ms, P1 for 2 ms): those stays
    are not graded, and each place keeps the grade of its last stay of a length it was taught."""
    taught = {}
    for place in ("P1", "P2"):
        train, y = balanced_segments(place, 60, 3)
        train = [dataclasses.replace(seg, source=f"demo_{i}") for i, seg in enumerate(train)]
        taught[place] = Judge(place, VARS, kernels=("rbf",)).fit(train, y)
        assert taught[place].shortest_taught_ == pytest.approx(min(seg.duration for seg in train))
        assert taught[place].shortest_taught_ > 0.05
    assert judges["P1"].shortest_taught_ == 0.0                          # taught by no demonstration
    ep = episode(3)                                                      # swing-up 2.71 s, balance 4.07 s
    n1, n = ep.labels[0].end, ep.num_samples
    ep.transitions = ep.transitions.copy()
    ep.transitions[n1 + 3:n1 + 5] = "t7"
    place_of = {"t0": "P1", "t1": "P2", "t7": "P1"}
    g = grade_episode(ep, taught, place_of)
    assert [(s.place, s.start, s.end) for s in g.segments] == [("P1", 0, n1), ("P2", n1 + 5, n)]
    whole = segment_from_episode(ep, 0, n1, VARS)
    assert g.places["P1"] == pytest.approx(taught["P1"].grade(whole))
    every = grade_episode(ep, judges, place_of)                          # no demonstrations: every stay
    assert [(s.start, s.end) for s in every.segments] == [(0, n1), (n1, n1 + 3), (n1 + 3, n1 + 5), (n1 + 5, n)]
    # a place whose only stay is shorter than any taught is graded all the same: the robot was quicker
    quick = episode(3)
    quick.transitions = np.array(["t0"] * n1 + ["t1"] * 50 + [""] * (n - n1 - 50))
    g = grade_episode(quick, taught, place_of)
    assert [(s.place, s.start, s.end) for s in g.segments] == [("P1", 0, n1), ("P2", n1, n1 + 50)]
    assert g.places["P2"] > 0


def test_a_stay_that_handed_over_to_a_success_passes_with_it():
    """A swing-up its judge fails, followed through the way in by a catch its judge passes, passes:
    the trial succeeds. Not through a way back (a balance lost, then a good swing-up), and not when
    the next stay failed too; the stays' own grades stay as they were."""
    def trial(*stays):
        segs = [SegmentGrade("t", 100 * i, 100 * i + 100, tag, place, score) for i, (tag, place, score) in enumerate(stays)]
        places = {}
        for g in segs:
            places[g.place] = g.score
        return TrialGrade(segs, places, min(places.values()))

    forward = {"t0", "t1", "t2", "t3"}
    way_in = credit_handovers(trial(("t0", "P1", 0.3), ("t1", "P2", 0.9)), lambda g: g.transition in forward, ["P1", "P2"])
    assert way_in.places == {"P1": 0.9, "P2": 0.9} and way_in.success
    assert [g.score for g in way_in.segments] == [0.3, 0.9]
    # P2's last stay (a balance lost, the way back) failed; the swing-up after it does not lift it
    back = credit_handovers(trial(("t0", "P1", 0.9), ("t1", "P2", 0.2), ("t7", "P1", 0.9)),
                            lambda g: g.transition in forward, ["P1", "P2"])
    assert back.places == {"P1": 0.9, "P2": 0.2} and not back.success
    # only the last stay of a place counts, and only a successor its judge passes credits it
    failed_next = credit_handovers(trial(("t0", "P1", 0.3), ("t1", "P2", 0.4)), lambda g: g.transition in forward, ["P1", "P2"])
    assert failed_next.places == {"P1": 0.3, "P2": 0.4} and not failed_next.success
    product = TrialGrade(way_in.segments, {"P1": 0.3, "P2": 0.9}, 0.27, "product")
    assert credit_handovers(product, lambda g: True, ["P1", "P2"]).score == pytest.approx(0.81)
    # a judged place the trial never reached scores 0, credited or not
    assert credit_handovers(trial(("t0", "P1", 0.3), ("t1", "P2", 0.9)), lambda g: True, ["P1", "P2", "P3"]).score == 0.0
    # credit runs back along a chain of handovers: a pumping and a pull whose ball flew into the cup
    # and stayed both did their job, though their own judges fail them (ball-in-cup, job seed 4)
    chain = credit_handovers(trial(("t0", "P1", 0.29), ("t2", "P2", 0.16), ("t3", "P3", 0.31), ("t4", "P4", 0.94)),
                             lambda g: g.transition in forward | {"t4"}, ["P1", "P2", "P3", "P4"])
    assert chain.places == {"P1": 0.94, "P2": 0.94, "P3": 0.94, "P4": 0.94} and chain.success
    assert [g.score for g in chain.segments] == [0.29, 0.16, 0.31, 0.94]
    # ... and stops at a link that is not a way forward
    broken = credit_handovers(trial(("t0", "P1", 0.29), ("t9", "P2", 0.16), ("t3", "P3", 0.31), ("t4", "P4", 0.94)),
                              lambda g: g.transition in forward | {"t4"}, ["P1", "P2", "P3", "P4"])
    assert broken.places == {"P1": 0.29, "P2": 0.94, "P3": 0.94, "P4": 0.94} and not broken.success


def test_save_load_and_bad_judge_files(judges, tmp_path):
    j = judges["P2"]
    path = tmp_path / "judge_P2.npz"
    j.save(path)
    back = Judge.load(path, variables=VARS, place="P2")
    test, _ = segments("P2", 50, 3)
    np.testing.assert_array_equal(back.grade_many(test), j.grade_many(test))
    assert back.best_kernel_ == j.best_kernel_ and back.cv_scores_ == j.cv_scores_
    assert back.keys_ == j.keys_

    with pytest.raises(InvalidInput, match="variables") as e:
        Judge.load(path, variables=("theta", "omega"))
    assert "judge_P2.npz" in str(e.value)
    with pytest.raises(InvalidInput, match="place"):
        Judge.load(path, place="P1")
    arrays, meta = load_npz(path, KIND, VERSION)
    bad = tmp_path / "bad.npz"
    save_npz(bad, arrays, {**meta, "feature_names": meta["feature_names"][:-1]}, KIND, VERSION)
    with pytest.raises(InvalidInput, match="feature_names"):
        Judge.load(bad)
    save_npz(bad, {**arrays, "train_X": arrays["train_X"][:, :5]}, meta, KIND, VERSION)
    with pytest.raises(InvalidInput, match="train_X"):
        Judge.load(bad)
    save_npz(bad, {k: v for k, v in arrays.items() if k != "svm_dual_coef"}, meta, KIND, VERSION)
    with pytest.raises(InvalidInput, match="svm_dual_coef"):
        Judge.load(bad)
    good = path.read_bytes()
    path.write_bytes(good[: len(good) // 3])
    with pytest.raises(InvalidInput, match="judge_P2.npz"):
        Judge.load(path)
    assert path.read_bytes() == good[: len(good) // 3]


def test_a_failed_save_leaves_the_old_file(judges, tmp_path, monkeypatch):
    path = tmp_path / "judge_P1.npz"
    judges["P1"].save(path)
    good = path.read_bytes()

    def broken_savez(fh, **arrays):
        fh.write(b"PK\x03\x04 half an archive")
        raise OSError("disk full")

    monkeypatch.setattr("multiform.io.np.savez", broken_savez)
    with pytest.raises(OSError, match="disk full"):
        judges["P2"].save(path)
    assert path.read_bytes() == good
    assert [p.name for p in tmp_path.iterdir()] == ["judge_P1.npz"]     # no temporary left behind
    monkeypatch.undo()
    assert Judge.load(path, place="P1").best_kernel_ == judges["P1"].best_kernel_


def test_grouped_folds_keep_a_segment_and_its_mirror_image_together():
    """Exact twins split across folds let a memorising SVM score perfectly on noise; grouped they cannot."""
    rng = np.random.default_rng(0)
    X = rng.normal(size=(40, 3))
    y = rng.random(40) < 0.5
    X2, y2, groups = np.r_[X, X], np.r_[y, y], list(range(40)) * 2
    grids = {"rbf": {"C": [1000.0], "gamma": [300.0]}}
    leaky = KernelPoolClassifier(kernels=("rbf",), grids=grids).fit(X2, y2)
    fair = KernelPoolClassifier(kernels=("rbf",), grids=grids, cv_repeats=3).fit(X2, y2, groups)
    assert leaky.best_score_ > 0.8                  # a twin sits in the training folds 80 % of the time
    assert fair.best_score_ < 0.7
