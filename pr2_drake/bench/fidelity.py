"""``pr2-drake bench fidelity``: the same episode at two physics steps, side by side.

    pr2-drake bench fidelity [--plants 0.002:similar,0.004:similar] [--tasks 1,2,3,4,5,6]
                             [--seed 0] [--seconds S] [--json PATH]

For each task, the default agent's episode on ``--seed`` runs once per plant setting: a physics
step [s] and optionally Drake's contact approximation (``plant.time_step``,
``plant.contact_approximation``; the default: the 2 ms step the walking tasks had before
issue 27's last round, against the 4 ms one they have now, both "similar"; issue 27's first
comparison was ``0.001:lagged,0.002:similar``; everything else as ``pr2-drake run``). A simulator monitor records, at
every physics step, the contact forces on the robot (point contacts: the largest single contact
force and the sum over the robot's contacts, magnitudes [N]; a discrete solver's contact force
is its impulse over one step, so the peak over a step grows as the step shrinks: the sum is
also given averaged over 10 ms windows, comparable across steps), and every 10 ms of simulated
time the robot's centre of mass and both soles' origins in W. Printed per task and step: the
outcome (score, termination, simulated time), the peak forces, and against the first step
over the time both episodes lasted: the largest deviation of the CoM and of the soles [cm]
and the first time the CoM deviates by more than 1 cm. (Walking is a chaotic process: two
step sizes drift apart over tens of seconds, as two seeds do; the outcomes and the
deviation over the first seconds say whether the physics changed.) The robot weighs about
340 N.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace

import numpy as np

GRID = 0.01  # [s] trajectory samples
FEET = ("l_sole", "r_sole")


class Recorder:
    """Simulator monitor: contact-force peaks each step, CoM and soles on the 10 ms grid."""

    def __init__(self):
        self.t, self.com, self.soles = [], [], []
        self.peak_single = self.peak_total = 0.0
        self.totals: list[tuple[float, float]] = []  # (t, sum of robot contact forces)
        self.episode = None

    def attach(self, episode) -> None:
        self.episode = episode
        tb = episode.testbed
        self._plant, self._robot = tb.plant, tb.robot
        self._robot_bodies = {int(i) for i in tb.plant.GetBodyIndices(tb.robot)}
        self._soles = [tb.plant.GetFrameByName(f, tb.robot).index() for f in FEET]
        self._contacts = tb.GetOutputPort("contact_results")
        episode.simulator.set_monitor(self._monitor)
        self._sample(episode.time)

    def _monitor(self, root_context):
        from pydrake.systems.framework import EventStatus

        ep = self.episode
        results = self._contacts.Eval(ep.tb_context)
        total = 0.0
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)
            if int(info.bodyA_index()) in self._robot_bodies or int(
                    info.bodyB_index()) in self._robot_bodies:
                f = float(np.linalg.norm(info.contact_force()))
                total += f
                self.peak_single = max(self.peak_single, f)
        self.peak_total = max(self.peak_total, total)
        t = root_context.get_time()
        self.totals.append((t, total))
        k = round(t / GRID)
        if abs(t - k * GRID) < 1e-7 and (not self.t or k * GRID > self.t[-1] + 1e-9):
            self._sample(k * GRID)
        return EventStatus.Succeeded()

    def peak_window(self, window: float = GRID) -> float:
        """Largest mean of the summed contact force over ``window`` seconds [N]."""
        if not self.totals:
            return 0.0
        t, f = np.array(self.totals).T
        dt = np.diff(t, prepend=t[0] - (t[1] - t[0] if len(t) > 1 else 0.0))
        impulse = np.concatenate([[0.0], np.cumsum(f * dt)])
        n = max(1, int(round(window / np.median(dt))))
        if len(f) < n:
            return float(impulse[-1] / max(t[-1] - t[0], 1e-9))
        return float(np.max(impulse[n:] - impulse[:-n]) / (n * np.median(dt)))

    def _sample(self, t: float) -> None:
        plant, ctx = self._plant, self.episode.plant_context
        self.t.append(round(t, 6))
        self.com.append(plant.CalcCenterOfMassPositionInWorld(ctx, [self._robot]).copy())
        self.soles.append(np.concatenate([
            plant.get_frame(f).CalcPoseInWorld(ctx).translation() for f in self._soles]))


def run_one(task: int, seed: int, time_step: float, seconds: float | None,
            approximation: str | None = None) -> dict:
    """The default agent's episode of ``task`` at ``time_step`` (and ``approximation``, None:
    the default), recorded."""
    from pr2_drake.episode import Episode
    from pr2_drake.run import run_episode
    from pr2_drake.scenario import PlantSettings, Scenario

    rec = Recorder()
    original = Episode.initialize

    def initialize(self):
        status = original(self)
        rec.attach(self)
        return status

    Episode.initialize = initialize
    try:
        plant = replace(PlantSettings(), time_step=time_step)
        if approximation:
            plant = replace(plant, contact_approximation=approximation)
        scenario = Scenario(task=task, seed=seed, seconds=seconds, plant=plant)
        report = run_episode(scenario)
    finally:
        Episode.initialize = original
    return dict(report=report, t=np.array(rec.t), com=np.array(rec.com),
                soles=np.array(rec.soles), peak_single=rec.peak_single,
                peak_total=rec.peak_total, peak_10ms=rec.peak_window())


def compare(ref: dict, other: dict) -> dict:
    """Largest CoM and sole deviations [m] over the common time, first time CoM > 1 cm."""
    common = sorted(set(ref["t"].tolist()) & set(other["t"].tolist()))
    ia = np.searchsorted(ref["t"], common)
    ib = np.searchsorted(other["t"], common)
    d_com = np.linalg.norm(ref["com"][ia] - other["com"][ib], axis=1)
    d_soles = np.maximum(
        np.linalg.norm(ref["soles"][ia, :3] - other["soles"][ib, :3], axis=1),
        np.linalg.norm(ref["soles"][ia, 3:] - other["soles"][ib, 3:], axis=1))
    over = np.nonzero(d_com > 0.01)[0]
    return dict(span=common[-1] if common else 0.0, com=float(d_com.max(initial=0.0)),
                soles=float(d_soles.max(initial=0.0)),
                com_1cm_at=float(common[over[0]]) if len(over) else math.nan)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="pr2-drake bench fidelity", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--plants", default="0.002:similar,0.004:similar",
                   help="comma list of STEP[:APPROXIMATION], the first the reference")
    p.add_argument("--tasks", default="1,2,3,4,5,6")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--seconds", type=float, default=None,
                   help="simulated seconds (default: until the episode ends)")
    p.add_argument("--json", default=None, help="write the table here")
    a = p.parse_args(argv)
    from pr2_drake.testbed import CONTACT_APPROXIMATIONS

    try:
        plants = [(float(x.split(":")[0]), x.split(":")[1] if ":" in x else None)
                  for x in a.plants.split(",")]
        tasks = [int(t) for t in a.tasks.split(",")]
    except ValueError:
        p.error("--plants is a comma list of STEP[:APPROXIMATION], --tasks of task ids")
    if len(plants) < 2 or not all(0 < s <= 0.02 for s, _ in plants):
        p.error("--plants needs two or more steps in (0, 0.02] s")
    bad = [ap for _, ap in plants if ap is not None and ap not in CONTACT_APPROXIMATIONS]
    if bad:
        p.error(f"--plants: unknown contact approximation {bad[0]!r}; choose from "
                f"{', '.join(CONTACT_APPROXIMATIONS)}")
    rows = []
    print(f"{'task':>4s} {'plant':>14s} {'outcome':>28s} {'peak 1 contact':>14s} "
          f"{'peak sum':>9s} {'sum 10ms':>9s} {'CoM dev':>8s} {'sole dev':>8s} {'CoM >1cm at':>11s} "
          f"{'over':>6s}")
    for task in tasks:
        runs = [run_one(task, a.seed, s, a.seconds, ap) for s, ap in plants]
        for (s, ap), run in zip(plants, runs):
            r = run["report"]
            dev = compare(runs[0], run)
            outcome = f"{r['score']:g}/{r['max_score']:g} {r['termination']} {r['sim_time']:.2f} s"
            at = "-" if math.isnan(dev["com_1cm_at"]) else f"{dev['com_1cm_at']:.2f} s"
            name = f"{s * 1e3:g} ms {ap or ''}"
            print(f"{task:4d} {name:>14s} {outcome:>28s} {run['peak_single']:12.0f} N "
                  f"{run['peak_total']:7.0f} N {run['peak_10ms']:7.0f} N {100 * dev['com']:6.2f}cm "
                  f"{100 * dev['soles']:6.2f}cm {at:>11s} {dev['span']:5.1f}s", flush=True)
            rows.append(dict(task=task, seed=a.seed, time_step=s, approximation=ap, score=r["score"],
                             max_score=r["max_score"], termination=r["termination"],
                             sim_time=r["sim_time"], peak_single=run["peak_single"],
                             peak_total=run["peak_total"], peak_10ms=run["peak_10ms"],
                             com_dev=dev["com"],
                             sole_dev=dev["soles"], com_1cm_at=dev["com_1cm_at"],
                             span=dev["span"]))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
