"""The report page tells the truth in readable words: the pushed split, the robot's verdict, the
configuration and demonstrations, each task's own figure numbers, no raw Python text."""

from __future__ import annotations

import re

import pytest

from multiform.report.browser import chromium, render, visible_text
from multiform.report.page import build_report, page_html
from multiform.stats import evaluation_split, rate

DETAIL = ([{"success": True, "self_success": True, "pushed": True}] * 97 + [{"success": False, "self_success": False,
                                                                             "pushed": True}] * 3
          + [{"success": True, "self_success": True, "pushed": False}] * 96
          + [{"success": True, "self_success": False, "pushed": False}] * 4)


def pendulum_metrics() -> dict:
    """The shape of a pendulum run's metrics.json (numbers of a real seed-0 run)."""
    split = evaluation_split(DETAIL)
    return {
        "skill": "pendulum_strict", "task": "pendulum", "description": "An arm balances a pendulum.",
        "version": "0.1.0", "net_version": 2,
        "config": {"demos": 40, "eval_trials": 200, "ablation_trials": 100, "practice_max_trials": 30,
                   "practice_budget": 100, "learn": False, "workers": 2, "seed": 0, "push_fraction": 0.5,
                   "videos": True, "inverse_model": True},
        "demos": {"count": 40, "file": "demos.h5", "mentor_success_rate": rate(29, 40),
                  "duration_s": {"total": 446.8, "mean": 11.2, "min": 2.0, "max": 20.0}, "samples": 446830,
                  "samples_per_transition": {"t0": 17080, "t1": 22535, "t2": 235784, "t3": 171431}},
        "training": {
            "laws": {"swing_up": {"n": 328920, "heldout_nrmse": 0.26, "mode": "sparse",
                                  "length_scales": {"s": 0.41, "c": 0.675, "omega": 1.76, "x": 0.109},
                                  "signal_std": 0.87, "noise_std": 0.15}},
            "judges": {"P1": {"segments": 57, "success_labels": 42, "heldout_accuracy": 1.0, "heldout_segments": 15,
                              "kernel": "rbf", "cv_score": 0.9667, "cv_scores": {"rbf": 0.9667, "linear": 0.83}}},
            "inverse_model": {"own_motion_s": [40.0, 40.0], "rows": 36500, "servo": "arm_pendulum",
                              "residual_gp": "sparse", "n_inducing": 300,
                              "tracking": {"learned": {"velocity_rms": 0.076, "hold_rms": 5.9e-05, "diverged": False},
                                           "reference": {"velocity_rms": 0.075, "hold_rms": 9.5e-05,
                                                         "diverged": False}, "ratio": 1.02}}},
        "practice_trials": 20,
        "scenarios": {"a_strict": {"title": "(a) the mentor's over-strict t1", "trials": 8, "successes": 5,
                                   "first_success_trial": 3, "stop_reason": "5 successes in a row",
                                   "revisions": [{"version": 1, "operator": "set_condition", "target": "t1",
                                                  "after_trial": 2, "reason": "t1 never fired"}],
                                   "robot_seconds": 127.3, "plot": "plots/practice_a_strict.png"}},
        "revisions": [{"version": 1, "operator": "set_condition", "target": "t1", "after_trial": 2,
                       "reason": "t1 never fired", "scenario": "a_strict"},
                      {"version": 2, "operator": "add_transition", "target": "t7", "after_trial": 2,
                       "reason": "no way back to P1", "scenario": "b_push"}],
        "success_rate": rate(193, 200), "self_assessed": rate(193, 200), "agreement_with_physical_check": 0.98,
        "pushed": split["pushed"], "unpushed": split["unpushed"], "verdicts": split["verdicts"],
        "target_success_rate": 0.95,
        "ablation": [{"name": "multiform", "notes": "the robot's revised net", **rate(193, 200)}],
        "artifacts": {"plots": {"recovery_trial": {"file": "plots/recovery_trial.png", "caption": "pushed while balancing",
                                                   "figure": "Fig. 7", "fired": ["t0", "t2", "t1", "t3", "t7", "t1", "t6"],
                                                   "push_time": 7.75},
                                "evaluation": "plots/evaluation.png"},
                      "nets": [{"file": "nets/net_v0.svg", "caption": "version 0"}], "videos": {}},
        "timings": {"record_s": 24.4, "total_s": 705.6, "closed_loop_us_per_sim_ms": 123.6},
    }


def nunchaku_metrics() -> dict:
    m = pendulum_metrics()
    m.update(skill="nunchaku", task="nunchaku", revisions=[], pushed=None, net_version=0)
    m.update(evaluation_split([r for r in DETAIL if not r["pushed"]]))
    m["success_rate"] = m["unpushed"]
    m["scenarios"] = {"a_practice": {"title": "(a) practice", "trials": 6, "successes": 4, "revisions": [],
                                     "first_success_trial": 1, "robot_seconds": 17.9,
                                     "plot": "plots/practice_a_practice.png"}}
    m["training"]["laws"]["swing"] = {"n": 2882, "heldout_nrmse": 1.37, "mode": "exact",
                                      "length_scales": {"dwell_P1": 0.04, "hand_x": 0.09}, "signal_std": 100.0,
                                      "noise_std": 0.002}
    del m["training"]["inverse_model"]
    m["artifacts"]["plots"] = {"success_trial": {"file": "plots/success_trial.png", "caption": "a successful flip",
                                                 "figure": "Fig. 11", "fired": ["t0", "t1", "t2", "t3", "t4"],
                                                 "push_time": None}}
    return m


def words(page: str) -> str:
    """The text a reader sees, without the skill's own names (set as code) — the page's own words."""
    return visible_text(re.sub(r"(?s)<code>.*?</code>", " ", page))


@pytest.mark.parametrize("metrics", [pendulum_metrics, nunchaku_metrics])
def test_the_page_has_no_raw_python_text_no_snake_case_and_no_empty_paragraph(metrics):
    page = page_html(metrics())
    text = words(page)
    for raw in ("{", "}", "': ", "None", "True", "False"):
        assert raw not in text, raw
    assert not re.search(r"\[[\d'\"{(-]", text)                  # a list (units such as [s] are fine)
    assert not re.findall(r"\b[a-z]+_[a-z0-9_]+\b", text)
    assert not re.search(r"<p>\s*</p>", page)


def test_the_page_shows_the_pushed_split_the_robots_verdict_configuration_and_demonstrations():
    text = visible_text(page_html(pendulum_metrics()))
    assert "pushed trials 97.0 % (97/100" in text
    assert "trials not pushed 100.0 % (100/100" in text
    assert "graded successful by its own judges" in text and "agreed with the physical check on 98.0 %" in text
    assert "the robot's judges said physical check: success physical check: failure success 193 0 failure 4 3" in text
    assert "seed 0" in text and "multiform version 0.1.0" in text and "final net version 2" in text
    assert "40 demonstrations by the scripted mentor" in text and "t2 235784" in text
    assert "15/15 (100 %)" in text and "96.7 %" in text            # a judge's accuracy with what it counts
    assert "Fired in order: t0 t2 t1 t3 t7 t1 t6" in text and "pushed at 7.75 s" in text


def test_an_older_run_without_the_unpushed_split_gets_it_from_its_counts():
    m = pendulum_metrics()
    del m["unpushed"]
    assert "trials not pushed 96.0 % (96/100" in visible_text(page_html(m))


def test_the_nunchaku_page_speaks_of_the_nunchaku():
    page = page_html(nunchaku_metrics())
    text = visible_text(page)
    assert "before and after each revision" not in text and "practice revised nothing" in text
    assert "Fig. 11" in text and "Fig. 7" not in text
    assert "no evaluation trial of this task was pushed" in text and "trials not pushed" not in text
    assert "worse than predicting the mean command" in text and "swing is such a law" in text
    assert "the env's own servos" in text


@pytest.mark.skipif(chromium() is None, reason="chromium not installed (make setup installs it)")
def test_headless_chromium_shows_every_item(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    m = pendulum_metrics()
    for rel in ("plots/practice_a_strict.png", "plots/recovery_trial.png", "plots/evaluation.png"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        fig, _ = plt.subplots(figsize=(2, 1))
        fig.savefig(tmp_path / rel)
        plt.close(fig)
    (tmp_path / "nets").mkdir()
    (tmp_path / "nets/net_v0.svg").write_text("<svg xmlns='http://www.w3.org/2000/svg' width='10' height='10'/>")
    page = render(build_report(tmp_path, m))
    assert page["returncode"] == 0 and page["console_errors"] == []
    assert page["images"] == 4 and page["images_ok"] == 4
    text = page["text"]
    for item in ("pushed trials 97.0 %", "trials not pushed", "the robot's own verdict", "Configuration",
                 "Demonstrations", "cf. the paper's Fig. 7", "Fired in order: t0 t2 t1 t3 t7 t1 t6"):
        assert item in text, item


def test_several_mentors_get_a_table_per_maneuver_and_place_and_how_practice_moved_it():
    m = pendulum_metrics()
    m["demos"]["mentors"] = {"expert": {"demos": 5, "success": 4}, "poor": {"demos": 5, "success": 1}}
    m["mentors"] = {
        "estimates": {"mentors": ["expert", "poor"], "items": 20, "verdicts_overruled": 4,
                      "maneuvers": {"t3": {"expert": {"segments": 7, "successes": 5, "precision": 1.0, "success": 0.667,
                                                      "weight": 1.0, "practice": [3.0, 0.5], "samples": 3000, "mse": 0.2},
                                           "poor": {"segments": 9, "successes": 2, "precision": 0.28, "success": 0.27,
                                                    "weight": 0.08, "practice": [0.0, 5.0], "samples": 900, "mse": None}}},
                      "labels": {"P2": {"expert": {"items": 7, "agreement": 1.0, "sensitivity": 1.0, "specificity": 1.0},
                                        "poor": {"items": 9, "agreement": 0.44, "sensitivity": None,
                                                 "specificity": 0.5}}}},
        "history": [{"when": "training", "maneuvers": {"t3": {"expert": 1.0, "poor": 0.12}}, "labels": {}},
                    {"when": "trial 48", "maneuvers": {"t3": {"expert": 1.0, "poor": 0.08}}, "labels": {}}]}
    page = page_html(m)
    text = visible_text(page)
    assert "Several mentors: how far each is trusted" in text and "5 by expert, 5 by poor" in text
    assert "t3 poor 2/9 0.28 0.27 0.12 0.08 0.0 / 5.0" in text
    assert "P2 poor 9 0.44 – 0.5" in text and "updated the estimates 1 time(s)" in text
    assert "None" not in words(page) and not re.search(r"<p>\s*</p>", page)
    assert "Several mentors" not in visible_text(page_html(pendulum_metrics()))
