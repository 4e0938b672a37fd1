"""The learning envs' dense reward, per task (weights in params/learning/rewards.yaml).

Each step's reward is the sum of its terms (``info["reward_terms"]``): ``progress`` toward the
next rubric items (the decrease of the task's distance d, :data:`PROGRESS`), ``rubric`` (the
points earned), ``fall`` (the episode ended fell, left_region or diverged), and small costs on
``torque``, ``action_rate`` and base ``oscillation`` (see the YAML). ``reward="rubric"`` keeps
only the rubric points (the original sparse reward).

The distances d [m, rad] (privileged: read from the plant where needed), per task:
rocky road, slope: the base's horizontal distance to the goal centre; valve: the base's
horizontal distance beyond the task region, plus the valve angle still to turn to 45 deg;
steps and button: the base's distance along x to 0.3 m beyond the last riser, plus its
horizontal distance to the button beyond 0.45 m; object search: the base's horizontal
distance to the target object (until it is picked) plus the object's distance to the coffee
table's top; moving bar and tasks without an entry: 0 (the rubric points alone).
"""

from dataclasses import dataclass
from typing import Any, Callable, ClassVar

import numpy as np

from pr2_drake.params import Params
from pr2_drake.ports import EFFORT_ARMS, EFFORT_LEGS, P_WB, V_WB, W_WB
from pr2_drake.robot.params import load_robot_params

FAULTS = ("fell", "left_region", "diverged")


@dataclass
class RewardWeights(Params):
    """See params/learning/rewards.yaml."""

    FILE: ClassVar[str] = "params/learning/rewards.yaml"
    progress: float = 10.0
    rubric: float = 1.0
    fall: float = 10.0
    torque: float = 0.1
    action_rate: float = 0.05
    oscillation: float = 0.05

    def check(self) -> None:
        for name in ("progress", "rubric", "fall", "torque", "action_rate", "oscillation"):
            if getattr(self, name) < 0.0:
                raise ValueError(f"reward weight {name} must be >= 0, got {getattr(self, name)}")


def _xy(a, b) -> float:
    return float(np.hypot(a[0] - b[0], a[1] - b[1]))


def _to_goal(episode, body) -> float:
    return _xy(body[P_WB], episode.testbed.scene.priors["goal_center"])


def _valve(episode, body) -> float:
    tb, task = episode.testbed, episode.testbed.task
    s = task.spec.scene
    region = max(0.0, _xy(body[P_WB], s["task_region"]["center"]) - s["task_region"]["radius"])
    joint = tb.plant.get_joint(tb.scene.data["valve_joint"])
    left = max(0.0, np.radians(s["turn_goal_deg"]) - abs(joint.get_angle(episode.plant_context)))
    return region + left


def _steps_button(episode, body) -> float:
    pri = episode.testbed.scene.priors
    x_over = pri["step_start_x"] + pri["step_count"] * pri["step_depth"] + 0.3
    p = body[P_WB]
    return max(0.0, x_over - p[0]) + max(0.0, _xy(p, pri["button_center"]) - 0.45)


def _object_search(episode, body) -> float:
    tb = episode.testbed
    data, plant = tb.scene.data, tb.plant
    p_obj = plant.get_body(data["bodies"][data["target"]]).EvalPoseInWorld(
        episode.plant_context).translation()
    table = np.asarray(tb.scene.priors["coffee_table_center"], dtype=float)
    carry = float(np.linalg.norm(p_obj - table))
    held = tb.grasp.GetOutputPort("pick_state").Eval(
        tb.grasp.GetMyContextFromRoot(episode.context)).attached
    return carry + (0.0 if held else _xy(body[P_WB], p_obj))


#: Per task (registry name): d(episode, body_state) [m, rad] (see the module docstring).
PROGRESS: dict[str, Callable[[Any, np.ndarray], float]] = {
    "rocky_road": _to_goal, "slope": _to_goal, "valve": _valve,
    "steps_button": _steps_button, "object_search": _object_search}


class Reward:
    """The reward of one episode's steps (see the module docstring).

    Args:
        kind: "dense" or "rubric".
        weights: the dense reward's weights (default params/learning/rewards.yaml).
    """

    def __init__(self, kind: str = "dense", weights: RewardWeights | None = None):
        if kind not in ("dense", "rubric"):
            raise ValueError(f"reward must be 'dense' or 'rubric', got {kind!r}")
        self.kind = kind
        self.w = weights or RewardWeights.load()
        params = load_robot_params()
        self._peak = np.concatenate([params.effort_limits("arms"), params.effort_limits("legs")])
        self._distance = None
        self._last = (0.0, None, None)

    def reset(self, episode, action_size: int) -> None:
        """Start an episode (after its reset)."""
        task = episode.testbed.task
        self._distance = PROGRESS.get(task.name) if task is not None else None
        self._last = (episode.status.score, self._d(episode), np.zeros(action_size))

    def _d(self, episode) -> float:
        if self._distance is None:
            return 0.0
        body = episode.testbed.GetOutputPort("body_state").Eval(episode.tb_context)
        return float(self._distance(episode, body))

    def step(self, episode, action: np.ndarray) -> tuple[float, dict[str, float]]:
        """(reward, terms) of the step that just ended with ``action``."""
        status = episode.status
        score, d, last_action = self._last
        rubric = self.w.rubric * (status.score - score)
        if self.kind == "rubric":
            self._last = (status.score, d, action)
            return float(status.score - score), {"rubric": float(status.score - score)}
        tb = episode.testbed
        d_now = self._d(episode)
        body = tb.GetOutputPort("body_state").Eval(episode.tb_context)
        joints = tb.GetOutputPort("joint_state").Eval(episode.tb_context)
        effort = np.concatenate([joints[EFFORT_ARMS], joints[EFFORT_LEGS]]) / self._peak
        w = body[W_WB]
        terms = {
            "progress": self.w.progress * (d - d_now),
            "rubric": rubric,
            "fall": -self.w.fall if status.done and status.termination in FAULTS else 0.0,
            "torque": -self.w.torque * float(np.mean(np.nan_to_num(effort) ** 2)),
            "action_rate": -self.w.action_rate * float(np.mean((action - last_action) ** 2)),
            "oscillation": -self.w.oscillation * float(w[0] ** 2 + w[1] ** 2
                                                       + body[V_WB][2] ** 2),
        }
        self._last = (status.score, d_now, np.array(action, dtype=float))
        terms = {k: float(v) for k, v in terms.items()}
        return float(sum(terms.values())), terms
