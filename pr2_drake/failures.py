"""Failure classes of evaluated episodes, from their reports (``pr2-drake eval``).

An episode without full marks gets one class: how it ended, and what the physics drawn for it
(``report["physics"]``, with ``randomize.enabled=true``) points to, by the rules of
params/eval/failures.yaml:

- ``fell`` / ``left the region`` ... ``after a push`` (one began within ``push_window`` [s] (2 s) of
  the end), else ``, friction < 0.6`` (``low_friction``), else ``(other)`` (``(drift)`` for a
  departure);
- ``out of time`` (``, latency >= 7 ms`` where the command latency was that high);
- ``completed below full marks``, or the termination's own name (``diverged``, ``agent_error``,
  ...).

Each class also names the first rubric item the episode did not earn (``missed``): where it
stopped. These are correlations read from the report, not a diagnosis: a push 1 s before a fall
may not have caused it (the step logs do; docs/benchmarks.md, "Randomised physics").
"""

from dataclasses import dataclass
from typing import Any, ClassVar, Optional

from pr2_drake.params import Params


@dataclass
class FailureRules(Params):
    """See params/eval/failures.yaml (s, -, s)."""

    FILE: ClassVar[str] = "params/eval/failures.yaml"
    push_window: float = 2.0
    low_friction: float = 0.6
    high_latency: float = 0.007

    def check(self) -> None:
        if self.push_window < 0 or self.low_friction < 0 or self.high_latency < 0:
            raise ValueError(f"failure rules must be non-negative: {self}")


def _push_before_end(physics: dict, end: float, window: float) -> Optional[dict]:
    """The last push that began within ``window`` [s] before ``end`` (None: none)."""
    last = None
    for p in physics.get("pushes") or []:
        if end - window <= p["time"] <= end:
            last = p
    return last


def classify(report: dict[str, Any], rules: FailureRules) -> Optional[str]:
    """The failure class of one episode's report (None: full marks)."""
    if report["score"] >= report["max_score"]:
        return None
    end, why = report["sim_time"], report["termination"]
    physics = report.get("physics") or {}
    if why in ("fell", "left_region"):
        label = "fell" if why == "fell" else "left the region"
        friction = physics.get("friction")
        if _push_before_end(physics, end, rules.push_window) is not None:
            return f"{label} after a push"
        if friction is not None and friction < rules.low_friction:
            return f"{label}, friction < {rules.low_friction:g}"
        return f"{label} (other)" if why == "fell" else f"{label} (drift)"
    if why == "timeout":
        latency = physics.get("latency")
        if latency is not None and latency >= rules.high_latency - 1e-12:
            return f"out of time, latency >= {1000 * rules.high_latency:g} ms"
        return "out of time"
    if why == "completed":
        return "completed below full marks"
    return why


def first_missed(report: dict[str, Any], items: list[str]) -> Optional[str]:
    """The first of the rubric's ``items`` (in order) the episode did not earn."""
    earned = {e["item"] for e in report["items"]}
    return next((i for i in items if i not in earned), None)


def failures_by_class(reports: list[dict[str, Any]], items: list[str],
                      rules: Optional[FailureRules] = None) -> dict[str, list[dict]]:
    """{class: [{"seed", "missed", "time"}, ...]} over the episodes without full marks, the
    classes in order of their first seed."""
    rules = rules or FailureRules.load()
    out: dict[str, list[dict]] = {}
    for r in sorted(reports, key=lambda r: r["seed"]):
        label = classify(r, rules)
        if label is not None:
            out.setdefault(label, []).append(
                {"seed": r["seed"], "missed": first_missed(r, items), "time": r["sim_time"]})
    return out
