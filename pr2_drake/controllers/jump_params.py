"""Parameters of the jump controller, loaded from params/controllers/jumping.yaml.

Units: m, s, N; heights are CoM heights above the soles. (No ``from __future__ import
annotations``: ``yaml_load_typed`` reads the field types.)
"""

from dataclasses import dataclass, field
from typing import ClassVar

from pr2_drake.controllers.planning.centroidal_mpc import MpcParams
from pr2_drake.controllers.walking_params import ObjectiveGains
from pr2_drake.params import Params


@dataclass
class JumpParams(Params):
    """See params/controllers/jumping.yaml."""

    FILE: ClassVar[str] = "params/controllers/jumping.yaml"
    crouch_time: float = 0.5
    crouch_hold: float = 0.1
    crouch_height: float = 0.42
    takeoff_height: float = 0.54
    landing_height: float = 0.54
    absorb_height: float = 0.46
    tuck_height: float = 0.10
    tuck_time: float = 0.10
    extend_time: float = 0.12
    stance_width: float = 0.22
    landing_min_time: float = 0.35
    landing_settle_speed: float = 0.05
    recovery_time: float = 0.5
    takeoff_timeout: float = 0.06
    touchdown_height: float = 0.004
    max_apex: float = 0.30
    max_speed: float = 1.0
    min_lead: float = 0.2
    com: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(100.0, 20.0, 300.0))
    com_launch_weight: float = 1000.0
    landing: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(120.0, 30.0, 300.0))
    landing_xy: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(30.0, 10.0, 300.0))
    joint_limit_horizon: float = 0.02
    angular_momentum: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(0.0, 10.0, 10.0))
    launch_angular_momentum_weight: float = 100.0
    launch_pelvis_scale: float = 0.03
    launch_cop_back: float = 0.03
    launch_lean_max: float = 0.04
    soles: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(600.0, 50.0, 1000.0))
    soles_rot: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(300.0, 35.0, 100.0))
    load_ramp: float = 0.02
    mpc: MpcParams = field(default_factory=MpcParams)

    def check(self) -> None:
        if not self.crouch_height < self.takeoff_height:
            raise ValueError("jumping: crouch_height must be below takeoff_height")
