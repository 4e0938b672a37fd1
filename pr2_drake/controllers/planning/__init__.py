"""The planners: from a command to the plan of one tick (:mod:`pr2_drake.controllers.plan`).

- :mod:`.gait`: the walking planner (gait state machine, CoM/DCM laws) that fills the plan;
- :mod:`.footsteps`: footstep planners (velocity, fixed footholds) behind one interface;
- :mod:`.terrain`: the terrain model the footstep planner asks for foothold heights;
- :mod:`.swing`, :mod:`.step_adjust`, :mod:`.com_plan`: swing trajectories, landing point and
  time from the capture point, the ZMP-preview CoM plan;
- :mod:`.step_over`, :mod:`.tread_steps`: footsteps kept off obstacles, and onto treads;
- :mod:`.jump_planner`, :mod:`.centroidal_mpc`: a jump's phases and its launch MPC.

Nothing here knows the QP or the objectives that track the plan.
"""
