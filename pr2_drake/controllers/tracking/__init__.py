"""Tracking a plan: objectives that add QP rows, the whole-body QP, the hand-force estimate.

- :mod:`.objectives`: walking's tracking objectives (CoM, pelvis, sole contacts, swing sole,
  hands, posture), each adding rows (J, desired acceleration, weight) to the QP cost;
- :mod:`.jump_objectives`: the rows a jump adds (3-D CoM, angular momentum, both soles);
- :mod:`.qp`: the whole-body QP (task-space inverse dynamics with contact forces);
- :mod:`.hand_force`: the force on a held hand, from the arm's torque residual.
"""
