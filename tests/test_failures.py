"""Failure classes of evaluated episodes (pr2_drake/failures.py): read from each report's end,
its rubric items and the physics drawn, by the rules of params/eval/failures.yaml."""

import pytest

from pr2_drake.failures import FailureRules, classify, failures_by_class, first_missed

RULES = FailureRules.load()
ITEMS = ["onto_step", "over_steps", "touch_button", "touch_button_arm"]


def report(seed=0, termination="fell", t=10.0, score=5.0, items=("onto_step",), **physics):
    physics.setdefault("friction", 0.9)
    physics.setdefault("latency", 0.002)
    physics.setdefault("pushes", [])
    return {"seed": seed, "termination": termination, "sim_time": t, "score": score,
            "max_score": 20.0, "items": [{"item": i, "points": 5, "time": 1.0} for i in items],
            "physics": physics}


def push(t):
    return {"time": t, "duration": 0.15, "force": [35.0, 0.0]}


def test_the_rules_load_from_their_yaml():
    assert (RULES.push_window, RULES.low_friction, RULES.high_latency) == (2.0, 0.6, 0.007)


@pytest.mark.parametrize("physics, termination, expected", [
    (dict(pushes=[push(8.1)]), "fell", "fell after a push"),  # 1.9 s before the end
    (dict(pushes=[push(7.5)], friction=0.55), "fell", "fell, friction < 0.6"),  # 2.5 s before
    (dict(pushes=[push(10.5)]), "fell", "fell (other)"),  # after the end: not this one
    (dict(pushes=[push(9.9)], friction=0.5), "left_region", "left the region after a push"),
    (dict(), "left_region", "left the region (drift)"),
    (dict(latency=0.0099), "timeout", "out of time, latency >= 7 ms"),
    (dict(latency=0.006, pushes=[push(9.5)]), "timeout", "out of time"),
    (dict(), "diverged", "diverged"),
])
def test_each_end_gets_its_class(physics, termination, expected):
    assert classify(report(termination=termination, **physics), RULES) == expected


def test_full_marks_are_no_failure_and_nominal_reports_have_no_physics_causes():
    assert classify(report(termination="completed", score=20.0, items=ITEMS), RULES) is None
    nominal = report()
    del nominal["physics"]
    assert classify(nominal, RULES) == "fell (other)"
    nominal["termination"] = "timeout"
    assert classify(nominal, RULES) == "out of time"


def test_failures_are_grouped_by_class_with_seeds_in_order_and_where_each_stopped():
    reports = [report(seed=3, pushes=[push(9.0)], items=("onto_step", "over_steps")),
               report(seed=1, pushes=[push(9.0)], items=()),
               report(seed=2, termination="completed", score=20.0, items=ITEMS),
               report(seed=0, termination="left_region")]
    out = failures_by_class(reports, ITEMS, RULES)
    assert list(out) == ["left the region (drift)", "fell after a push"]
    assert [(e["seed"], e["missed"]) for e in out["fell after a push"]] == [
        (1, "onto_step"), (3, "touch_button")]
    assert first_missed(report(items=ITEMS), ITEMS) is None
