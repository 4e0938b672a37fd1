"""The task-6 object-search agent (:mod:`.agent`) and its parts, each usable alone.

- :mod:`.instruction`: sentence -> :class:`~.instruction.Instruction` (target, source, destination).
- :mod:`.perception`: head RGB-D frame + camera pose -> object position in world.
- :mod:`.navigation`: occupancy grid of the house, A* paths, a path-following velocity source.
- :mod:`.tables`: the public scene's tables, the side to stand at, the search order, poses.
- :mod:`.sequencer`, :mod:`.stages`, :mod:`.memory`: the stage machine, what each stage does,
  its parameters and memory; :mod:`.recovery`: what a stage does when it stalls or fails.
"""
