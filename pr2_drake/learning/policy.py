"""A trained command-level policy as an agent: ``pr2-drake run --agent ...`` runs it.

A policy file (``.npz``, written by :func:`save_policy`) holds a multilayer perceptron (the
weights and biases of its layers, tanh between them, as stable-baselines3's ``MlpPolicy``
builds it; the last layer is the action mean, taken as the action) and what it was trained
on: the observation keys it reads (``keys``, flattened in the order of
:class:`pr2_drake.learning.observe.Observer`), the task, and ``action_index``: which entry of
the command level's action each output drives (the others are 0).

:class:`PolicyAgent` is a Diagram of :class:`PolicyBlock` (the observation from the testbed's
ports every ``control_dt``, the MLP, the action held in between: discrete state) and
:class:`pr2_drake.learning.command.CommandLevel` (the task's controller), so it runs as any
System agent, in ``run``, ``eval`` and the sandbox of ``compete``. It needs numpy only (no
torch). Its observation keys must be public (``body``, ``joints``, ``target``, ``feedback``
where the task's feedback is public; not the valve angle).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Diagram, DiagramBuilder, LeafSystem

from pr2_drake.grasp import PickState
from pr2_drake.learning.observe import Observer
from pr2_drake.lifetime import weak_calc
from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE

PUBLIC_KEYS = ("body", "joints", "target", "feedback")


class MlpPolicy:
    """A tanh MLP: ``layers`` = [(W, b), ...]; act(x) = the last layer's output, clipped to
    [-1, 1]."""

    def __init__(self, layers: list[tuple[np.ndarray, np.ndarray]]):
        self.layers = [(np.asarray(W, dtype=np.float64), np.asarray(b, dtype=np.float64))
                       for W, b in layers]

    def act(self, x: np.ndarray) -> np.ndarray:
        h = np.asarray(x, dtype=np.float64)
        for W, b in self.layers[:-1]:
            h = np.tanh(W @ h + b)
        W, b = self.layers[-1]
        return np.clip(W @ h + b, -1.0, 1.0)


def save_policy(path: str | Path, layers, keys, task: str, action_index, action_names,
                control_dt: float) -> None:
    """Write a policy file (see the module docstring)."""
    arrays = {f"W{i}": np.asarray(W, np.float32) for i, (W, _) in enumerate(layers)}
    arrays.update({f"b{i}": np.asarray(b, np.float32) for i, (_, b) in enumerate(layers)})
    np.savez_compressed(path, keys=np.array(list(keys)), task=np.array(task),
                        action_index=np.asarray(action_index, int),
                        action_names=np.array(list(action_names)),
                        control_dt=np.array(float(control_dt)), **arrays)


def load_policy(path: str | Path) -> dict[str, Any]:
    """A policy file's contents: ``mlp`` (:class:`MlpPolicy`), ``keys``, ``task``,
    ``action_index``, ``action_names`` (the command level's, :class:`ActionLayout`),
    ``action_size``, ``control_dt``.

    Raises:
        ValueError: not a policy file (naming what is missing).
    """
    try:
        with np.load(path) as f:
            n = sum(1 for k in f.files if k.startswith("W"))
            layers = [(f[f"W{i}"], f[f"b{i}"]) for i in range(n)]
            out = {"mlp": MlpPolicy(layers), "keys": [str(k) for k in f["keys"]],
                   "task": str(f["task"]), "action_index": f["action_index"].astype(int),
                   "action_names": tuple(str(a) for a in f["action_names"]),
                   "control_dt": float(f["control_dt"])}
            out["action_size"] = len(out["action_names"])
    except (OSError, KeyError, ValueError) as e:
        raise ValueError(f"policy file {path}: {e}") from None
    if n == 0:
        raise ValueError(f"policy file {path}: no layers")
    bad = set(out["keys"]) - set(PUBLIC_KEYS)
    if bad:
        raise ValueError(f"policy file {path}: observation keys {sorted(bad)} are not public")
    return out


class PolicyBlock(LeafSystem):
    """Observation -> policy -> ``action`` (held for ``control_dt``; discrete state).

    Inputs: ``joint_state``, ``body_state``, ``pick_state``, ``task_feedback``. Output:
    ``action`` (``action_size``)."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, policy: dict[str, Any], observer: Observer):
        super().__init__()
        self._policy, self._observer = policy, observer
        self._js = self.DeclareVectorInputPort("joint_state", JOINT_STATE_SIZE)
        self._bs = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self._pick = self.DeclareAbstractInputPort("pick_state", AbstractValue.Make(PickState()))
        self._fb = self.DeclareAbstractInputPort("task_feedback", AbstractValue.Make(dict()))
        self._action = self.DeclareDiscreteState(policy["action_size"])
        self.DeclarePeriodicDiscreteUpdateEvent(policy["control_dt"], 0.0, self._update)
        self.DeclareVectorOutputPort(
            "action", policy["action_size"], weak_calc(self._calc),
            prerequisites_of_calc={self.discrete_state_ticket(self._action)})

    def _update(self, context, discrete_state) -> None:
        values = {"joint_state": self._js.Eval(context), "body_state": self._bs.Eval(context),
                  "pick_state": self._pick.Eval(context), "task_feedback": self._fb.Eval(context)}
        obs = self._observer.observe(values, (0.0, 0.0))
        x = np.concatenate([obs[k].reshape(-1) for k in self._policy["keys"]])
        action = np.zeros(self._policy["action_size"])
        action[self._policy["action_index"]] = self._policy["mlp"].act(x)
        discrete_state.get_mutable_vector(self._action).SetFromVector(action)

    def _calc(self, context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._action).get_value())


class PolicyAgent(Diagram):
    """A trained policy driving the task's controller (see the module docstring).

    Args:
        priors: the task's priors.
        task: the task (id or name); must be the policy's.
        policy: the policy file (``.npz``).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, priors: dict[str, Any], task=None, policy: str | None = None):
        super().__init__()
        from pr2_drake.learning.command import CommandLevel
        from pr2_drake.paths import resolve_user_path
        from pr2_drake.tasks import task_entry

        if policy is None:
            raise ValueError("PolicyAgent needs a policy file (agent_params: {policy: FILE})")
        p = load_policy(resolve_user_path(policy, "policy"))
        if task is None or task_entry(task).name != p["task"]:
            raise ValueError(f"policy {policy} was trained on task {p['task']}, not {task}")
        level = CommandLevel(task, priors, graspables="pick_left" in p["action_names"])
        if level.layout.names != p["action_names"]:
            raise ValueError(f"policy {policy}: actions {p['action_names']}, the command level "
                             f"of task {p['task']} has {level.layout.names}")
        builder = DiagramBuilder()
        block = builder.AddNamedSystem("policy", PolicyBlock(p, Observer(p["task"], priors)))
        level = builder.AddNamedSystem("command_level", level)
        builder.Connect(block.GetOutputPort("action"), level.GetInputPort("action"))
        for i in range(block.num_input_ports()):
            name = block.get_input_port(i).get_name()
            port = builder.ExportInput(block.get_input_port(i), name)
            if level.HasInputPort(name):
                builder.ConnectInput(port, level.GetInputPort(name))
        for i in range(level.num_input_ports()):
            name = level.get_input_port(i).get_name()
            if name != "action" and not block.HasInputPort(name):
                builder.ExportInput(level.get_input_port(i), name)
        for i in range(level.num_output_ports()):
            builder.ExportOutput(level.get_output_port(i), level.get_output_port(i).get_name())
        builder.BuildInto(self)
