"""Parts of the task-6 object-search agent, each usable alone.

- :mod:`.instruction`: sentence -> :class:`~.instruction.Instruction` (target, source, destination).
- :mod:`.perception`: head RGB-D frame + camera pose -> object position in world.
- :mod:`.navigation`: occupancy grid of the house, A* paths, a path-following velocity source.
"""
