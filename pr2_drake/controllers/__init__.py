"""Built-in controllers as Drake LeafSystems (standing, walking, arm posture).

Each controller is a :class:`pydrake.systems.framework.LeafSystem` with the testbed's port names
(see :mod:`pr2_drake.ports`). The walking controller is also callable in process, without a
Diagram, through ``WalkingController().command(obs, vx, vy, yaw_rate)``, which shares the same
implementation.
"""
