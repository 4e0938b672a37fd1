"""Task 6 reference agent: read the sentence, find the object with the head camera, carry it to
the coffee table.

:class:`ObjectSearchAgent` is a Diagram of a sequencer (:class:`ObjectSearchSequencer`) and the
walking controller with the arms in the whole-body QP (``WalkingController(arms="effort")``,
its QP at 125 Hz: params/controllers/walking_search.yaml, task 6's row), built like
:class:`pr2_drake.agents.valve.ValveAgent`. The sequencer is made of the search parts, each
replaceable on its own (constructor arguments of :class:`ObjectSearchSequencer`):

- ``parser`` (:class:`~.instruction.InstructionParser`, anything with ``parse(sentence)``):
  the ``instruction`` prior -> target object, source furniture/room, destination;
- ``detector`` (:class:`~.perception.ObjectDetector`, anything with ``find(rgb, depth, X_WC,
  target)``): the head camera frame (``rgbd`` input) -> the target's position in W;
- the map (:class:`~.mapping.HeightMap`, made from the head camera's depth as the robot
  goes) and :func:`~.navigation.plan_path` / :func:`~.navigation.follow_velocity`: walking
  between rooms on what the map shows, unknown floor counted free, planned again when the
  map shows the path blocked.

Stages (``stage`` output):

0. SCAN: turn on the spot (``scan_turn_deg``), mapping, the detector looking for the target
   in some frames (where it is seen: a hint);
1. NAVIGATE to a look pose ``look_distance`` before the most likely top of the map not yet
   searched (the tops the target was seen on; then those as high as the furniture the
   sentence names; then the nearest), facing it, on the side with the most free floor; no
   top left: walk to a frontier of the map (free floor next to unknown) and SCAN there;
2. LOOK: stand still, take a frame, run the detector; try the headings ``look_yaws_deg``
   (the camera is fixed on the base: the body turns); nothing found -> next top, except on a
   top the scan saw the target on: there another object can hide it from one side, so the
   robot first walks to the top's next side and looks again (``look_sides`` in all);
3. APPROACH: small steps onto a pick pose ``pick_standoff`` from the table edge, in line with
   the object (the hand's shoulder nearer it), facing the table; an object more than
   ``pick_reach`` from the hand's shoulder there is picked from the side (of the four)
   nearest it where there is floor (NAVIGATE round the table first); SETTLE until the gait
   stands;
4. REACH: the nearer hand rises in front of the body, moves over the grasp point
   (``pre_height`` above it) and down onto it: ``grasp_offset`` from the object's centre
   towards the shoulder, at least ``grasp_height`` above the centre (inside the 0.20 m pick
   distance, as near the shoulder as that allows), or, when another object seen with it would
   be nearly as near that point (``pick`` latches the nearest), higher over it or from
   another side (``grasp_margin``); PICK: ``pick`` until ``pick_state`` reports
   it attached (timeout: closer to the centre and try again, ``pick_tries`` in all; another
   object than the target attached: let go, step back and pick from the next side);
5. LIFT to the carry pose, NAVIGATE (holding it) to the coffee table, APPROACH the place
   pose from which, the arm as at the pick, the object is over the table's centre line
   ``place_inset`` inside its near edge (the base at least ``place_standoff`` from the edge),
   SETTLE;
6. PLACE: the hand goes back to where it held the object at the pick (relative to the base,
   so that the arm is as it was), moved by at most ``place_reach`` to where the place pose
   would hold the object (a base stopped short of it; an object held near the body, set
   ``place_inset`` inside), as high over this top as it was over that one plus
   ``place_clearance``; RELEASE; the hand goes up; step BACK; DONE. While placing, the hand
   targets carry the object's vertical in the hand frame (6-value targets): the whole-body QP
   keeps it vertical, so round objects are set down upright;
7. VERIFY: standing, the camera looks for the object (``verify_frames``): seen resting on the
   coffee table: DONE; seen on another top (it fell there): pick it up again and place it
   again (``place_retries``); on the floor (out of the arm's reach) or not seen: FAILED.

Recovery (:mod:`.recovery`, issue 29): an approach whose distance to its pose stops shrinking
(``approach_stall_time``; a gait that drifts sideways can step the other way than commanded)
settles where it stands when that pose serves (the object within ``reach_accept`` of the
shoulder; the held object ``place_margin`` inside the coffee table's edges), else a place turns
on the spot where that brings the object over the top, and both walk there again on a path
(``approach_retries`` in all); a walk circling near its goal (``walk_stall_time``)
ends there; no path to the coffee table: its other sides, then the map without its weak
obstacles (stray depth points); no path left to any other goal: the stage gives it up (next
top, next side, next frontier) instead of standing.

FAILED (standing, the reason in the memory's ``failure`` and the step log in its ``log``): not
found on any table, pick failed ``pick_tries`` times, no path to the destination, the object
fell from the hand, the place pose not reached, or the placed object not on the table.

A sentence that cannot be read (unknown object, no destination) ends the episode at its first
update with the parser's message (termination ``agent_error``, the message in the report), not
with a crash at build time. Only the public observation (``body_state``, ``joint_state``,
``pick_state``, ``rgbd``), the priors (``instruction``, ``object_models``,
``coffee_table_center``, ``coffee_table_size``), the arena and the camera, and what holds in
every house of the task, its own and every generated one (``scene.variation``): the names of
objects, furniture and rooms, the furniture's heights, the robot starting in the target's
room (see :mod:`.explore`) are used; no layout (walls, doorways, where furniture stands,
which table holds what) and no simulator ground truth. Parameters: params/agents/search.yaml,
search_mapping.yaml, search_navigation.yaml. Positions in m, world frame W.

The parts: :mod:`.sequencer` (ports, memory, one update), :mod:`.stages` (what each stage
does), :mod:`.explore` (scan, map, search order, replanning, exploring), :mod:`.recovery`
(stalls, failures, the check after a place), :mod:`.mapping` (the map), :mod:`.memory`
(parameters, stages, memory), :mod:`.tables` (tops and poses).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydrake.systems.framework import Diagram

from pr2_drake.agents.search.instruction import Instruction, InstructionError
from pr2_drake.agents.search.mapping import MappingParams
from pr2_drake.agents.search.memory import SearchAgentParams
from pr2_drake.agents.search.navigation import NavigationParams
from pr2_drake.agents.search.sequencer import ObjectSearchSequencer
from pr2_drake.agents.search.tables import Table
from pr2_drake.agents.sequencer import build_sequencer_agent


def destination_from_priors(priors: dict[str, Any]) -> Table:
    """The coffee table of the priors: ``coffee_table_center`` (top centre, x y z) and
    ``coffee_table_size`` (x, y) [m]."""
    c = [float(v) for v in priors["coffee_table_center"]]
    size = [float(v) for v in priors.get("coffee_table_size", (1.0, 0.6))]
    return Table("coffee_table", np.array(c[:2]), np.array(size), c[2])


def furniture_height(scene: dict, instruction: Instruction | None) -> float | None:
    """The top height [m] of the furniture the sentence names as the source (every piece of
    furniture keeps its height in every house of the task), or None."""
    if instruction is None or instruction.source_furniture is None:
        return None
    furniture = scene["furniture"].get(instruction.source_furniture)
    return None if furniture is None else float(furniture["height"])


class ObjectSearchAgent(Diagram):
    """Task 6 reference agent (see the module docstring).

    Input ports: ``joint_state``, ``body_state``, ``pick_state``, ``rgbd``. Output ports:
    ``legs_command``, ``arms_command`` (effort, from the whole-body QP), ``pick``,
    ``release``, ``velocity_command``, ``stage`` and ``camera_capture`` (the camera renders
    only while the sequencer looks).

    Args:
        priors: the task's priors (``instruction``, ``object_models``, ``coffee_table_*``).
        params: sequencer YAML (default params/agents/search.yaml).
        parser: replaces the rule-based :class:`InstructionParser` (``parse(sentence)``).
        detector: replaces the :class:`ObjectDetector` (``find(rgb, depth, X_WC, target)``).
        walking_params: overrides of params/controllers/walking.yaml for the walking
            controller (task 6's row: params/controllers/walking_search.yaml, the QP at
            125 Hz).
        navigation_params: overrides of params/agents/search_navigation.yaml (a partial
            YAML: only its entries change), e.g. ``--set
            agent_params.navigation_params=FILE``.
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, priors: dict[str, Any], params: str | None = None, parser=None,
                 detector=None, walking_params: str | None = None,
                 navigation_params: str | None = None):
        super().__init__()
        from pr2_drake.agents.search.instruction import InstructionParser
        from pr2_drake.agents.search.perception import (
            CameraIntrinsics,
            HeadCameraKinematics,
            ObjectDetector,
            object_models_from_priors,
        )
        from pr2_drake.tasks import get_task

        if "object_models" not in priors or "coffee_table_center" not in priors:
            raise ValueError(f"ObjectSearchAgent needs the task-6 priors (object_models, "
                             f"coffee_table_center, instruction); got {sorted(priors)}")
        spec = get_task(6).spec
        parser = parser or InstructionParser.from_task()
        instruction, error = None, ""
        try:
            instruction = parser.parse(priors.get("instruction", ""))
        except InstructionError as e:
            error = str(e)
        cam = spec.camera
        K = CameraIntrinsics.from_fov(int(cam["width"]), int(cam["height"]),
                                      float(cam["fov_y_deg"]))
        models = object_models_from_priors(priors)
        detector = detector or ObjectDetector(models, K)
        height = models[instruction.target].height if (
            instruction and instruction.target in models) else 0.1
        seq = ObjectSearchSequencer(
            instruction, destination_from_priors(priors), detector, height, K,
            1.0 / float(cam["fps"]), (spec.arena["min"], spec.arena["max"]),
            SearchAgentParams.load(params),
            NavigationParams.load(overrides=[navigation_params] if navigation_params else []),
            HeadCameraKinematics(),
            error, furniture_height(spec.scene, instruction), MappingParams.load())
        build_sequencer_agent(self, seq, self.controller(priors, walking_params))

    @staticmethod
    def controller(priors: dict[str, Any], walking_params: str | None = None, **_):
        """The walking controller this agent drives, its arms in the QP (the command-level
        learning envs drive the same one); other parameter files are ignored."""
        from pr2_drake.controllers.walking import WalkingController
        from pr2_drake.controllers.walking_params import WalkingParams

        wparams = WalkingParams.load(overrides=[walking_params] if walking_params else [])
        return WalkingController(wparams, arms="effort")
