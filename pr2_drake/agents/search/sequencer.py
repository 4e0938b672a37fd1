"""ObjectSearchSequencer: the task-6 stage machine: its ports, its memory (in its Context) and
one update; what each stage does is :mod:`pr2_drake.agents.search.stages` (search, pick, carry,
place), :mod:`pr2_drake.agents.search.explore` (scan, map, explore) and
:mod:`pr2_drake.agents.search.recovery` (stalls and failures: the recovery paths).
"""

from __future__ import annotations

from typing import Optional

import numpy as np
from pydrake.common.value import AbstractValue

from pr2_drake.agents.search.explore import ExploreStages
from pr2_drake.agents.search.instruction import Instruction, InstructionError
from pr2_drake.agents.search.mapping import HeightMap, MappingParams
from pr2_drake.agents.search.memory import SearchAgentParams, SearchMemory, Stage
from pr2_drake.agents.search.navigation import NavigationParams
from pr2_drake.agents.search.perception import CameraIntrinsics
from pr2_drake.agents.search.recovery import RecoveryStages
from pr2_drake.agents.search.stages import ORDER, SearchStages
from pr2_drake.agents.search.tables import Table
from pr2_drake.agents.sequencer import Now, TaskSequencer
from pr2_drake.agents.walk_to_goal import yaw_from_quaternion
from pr2_drake.camera import RgbdFrame
from pr2_drake.grasp import PickState
from pr2_drake.lifetime import weak_calc
from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE, P_WB, QUAT_WB


class ObjectSearchSequencer(SearchStages, ExploreStages, RecoveryStages, TaskSequencer):
    """Stages of the search and transport (see :mod:`pr2_drake.agents.search.agent`).

    Inputs: ``body_state``, ``joint_state``, ``pick_state``, ``rgbd`` (RgbdFrame),
    ``walker_status``. Outputs: ``velocity_command`` (3), ``hand_targets`` ([left, right]),
    ``pick`` (str), ``release`` (bool), ``stage`` (1), ``camera_capture`` (bool: whether the
    next camera sample renders: every one in LOOK, some while scanning and walking for the
    map, none otherwise). Memory: :class:`SearchMemory` (:meth:`memory` of a context).

    Args:
        instruction: the parsed sentence, or None with ``error`` the parser's message (the
            first update raises it).
        destination: the top to put the object on (the coffee table of the priors).
        detector: ``find(rgb, depth, X_WC, target) -> Detection | None`` (or ``detect``).
        object_height: the target's height [m] (its model): the hand clears its top when it
            comes from above.
        camera: the head camera's intrinsics and ``camera_period`` its sample period [s].
        arena: (lo, hi) corners (x, y) of the area mapped [m].
        expected_height: the top height [m] of the furniture the sentence names (searched
            first), or None.
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, instruction: Optional[Instruction], destination: Table, detector,
                 object_height: float, camera: CameraIntrinsics, camera_period: float,
                 arena, params: SearchAgentParams | None = None,
                 nav: NavigationParams | None = None, camera_kinematics=None,
                 error: str = "", expected_height: Optional[float] = None,
                 mapping: MappingParams | None = None):
        super().__init__()
        from pr2_drake.controllers.model import WholeBodyModel

        self.p = params or SearchAgentParams()
        self.nav = nav or NavigationParams()
        self.instruction = instruction
        self.error = error
        self.detector = detector
        self.kin = camera_kinematics
        self.object_height = float(object_height)
        self.destination = destination
        self.expected_height = expected_height
        self.mp = mapping or MappingParams()
        self.K, self.camera_period = camera, float(camera_period)
        known = HeightMap.empty(arena[0], arena[1], self.mp.resolution)
        known = known.with_box(destination.center, destination.size, destination.height)
        self.model = WholeBodyModel()  # forward kinematics of the observed state (scratch)
        self.model.update(self.model.q_nominal, np.zeros(self.model.nv))
        # The shoulders in the base frame (the nominal pose has the base at the origin).
        self.p_BS = [self.model.shoulder_position(side).copy() for side in (0, 1)]
        self._bs = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self._js = self.DeclareVectorInputPort("joint_state", JOINT_STATE_SIZE)
        self._pick_state = self.DeclareAbstractInputPort("pick_state",
                                                         AbstractValue.Make(PickState()))
        h, w = camera.height, camera.width
        blank = RgbdFrame(np.zeros((h, w, 3), np.uint8), np.zeros((h, w), np.float32))
        self._rgbd = self.DeclareAbstractInputPort("rgbd", AbstractValue.Make(blank))
        after_update = self.declare_sequencer(SearchMemory(map=known), self.p.period,
                                              grasp=True)
        self.DeclareAbstractOutputPort("camera_capture", lambda: AbstractValue.Make(False),
                                       weak_calc(self._calc_capture),
                                       prerequisites_of_calc=after_update)
        self.DeclareAbstractOutputPort("camera_capture_color", lambda: AbstractValue.Make(True),
                                       weak_calc(self._calc_capture_color),
                                       prerequisites_of_calc=after_update)

    def step(self, context, m: SearchMemory) -> None:
        t = context.get_time()
        if self.instruction is None:
            raise InstructionError(f"ObjectSearchAgent cannot read the instruction: "
                                   f"{self.error}")
        bs = self._bs.Eval(context)
        js = self._js.Eval(context)
        self.model.update(*self.model.state_from_ports(js, bs))
        p_WB = bs[P_WB]
        now = Now(t, p_WB, yaw_from_quaternion(bs[QUAT_WB]), self.walker_standing(context),
                  t - m.t_stage, self._pick_state.Eval(context))
        m.pick = ""
        m.release = False
        if m.frames == 0 and m.frame_time < 0:
            m.map = m.map.with_free_disc(p_WB, self.mp.footprint_radius)
        self._integrate(m, now, context)
        for stages, name in ORDER:
            if m.stage in stages:
                getattr(self, name)(m, now, context)

    def _detect(self, m: SearchMemory, context) -> Optional[np.ndarray]:
        """The target's centre p_WO in this frame, or None; ``m.others`` gets the other
        objects' centres when the detector lists every object (``detect``)."""
        frame = self._rgbd.Eval(context)
        if frame.depth.size == 0:
            return None
        return self._find(m, frame, self._camera_pose(context))

    # ---- outputs -----------------------------------------------------------------------------
    def _calc_targets(self, context, output) -> None:
        m = self.memory(context)
        targets = [None if x is None else np.array(x) for x in m.targets]
        side = m.hand
        if (m.up_H is not None and targets[side] is not None
                and m.stage in (Stage.PLACE, Stage.RELEASE)):
            targets[side] = np.r_[targets[side], m.up_H]  # set down upright
        output.set_value(targets)

    def _calc_capture(self, context, output) -> None:
        output.set_value(bool(self.memory(context).capture))

    def _calc_capture_color(self, context, output) -> None:
        output.set_value(bool(self.memory(context).capture_color))
