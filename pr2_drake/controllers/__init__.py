"""Built-in controllers: parts that show the design, and the compositions that use them.

One control tick flows planning -> plan -> tracking:

- :mod:`.planning`: the planners that turn a command (velocity, jump, hand targets) into a
  plan: gait state machine, footsteps, the terrain model, swing, step adjustment, CoM plan,
  stepping over obstacles and onto treads, the jump planner and its centroidal MPC;
- :mod:`.plan`: the plan of one tick (:class:`~.plan.WholeBodyPlan`, :class:`~.plan.JumpPlan`):
  active contacts and the references to track;
- :mod:`.tracking`: the tracking objectives that turn the plan into QP rows, the whole-body QP,
  and the hand-force estimate;
- shared by both: the robot model (:mod:`.model`), planar rotations (:mod:`.frames`) and the
  parameters (:mod:`.walking_params`, :mod:`.jump_params`; YAML in params/controllers/).

The compositions are Drake LeafSystems with the testbed's port names (:mod:`pr2_drake.ports`):
:mod:`.whole_body` (planner + objectives + QP, plain Python), :mod:`.walking`
(``WalkingController``), :mod:`.jumping` (``JumpController``), :mod:`.standing` and
:mod:`.posture`. Each is also callable in process without a Diagram
(``WalkingController().command(obs, vx, vy, yaw_rate)``), sharing the same implementation.
"""
