"""What an episode leaves besides its report: a Meshcat replay (HTML) and the head camera's video.

:func:`pr2_drake.run.run_episode` uses these; each is usable alone with an
:class:`pr2_drake.episode.Episode`.
"""

from __future__ import annotations

import logging
from pathlib import Path

from pydrake.geometry import Meshcat
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.episode import Wiring
from pr2_drake.testbed import Testbed


def quiet_meshcat() -> Meshcat:
    """A Meshcat for recording only: Drake's "listening at http://..." line is not printed
    (nobody was asked to open that viewer)."""
    log = logging.getLogger("drake")
    level = log.level
    log.setLevel(logging.WARNING)
    try:
        return Meshcat()
    finally:
        log.setLevel(level)


def frame_robot(meshcat: Meshcat, testbed: Testbed) -> None:
    """Point Meshcat's camera at the robot's start and the task's region (the replay opens
    there instead of at Meshcat's default view)."""
    from pr2_drake.viz import overview_eye_target

    eye, target = overview_eye_target(testbed)
    meshcat.SetCameraPose(eye, target)


def write_replay(meshcat: Meshcat, path: str | Path) -> None:
    """Stop Meshcat's recording (started with ``meshcat.StartRecording()``) and write it to
    ``path`` as one self-contained HTML file."""
    meshcat.StopRecording()
    meshcat.PublishRecording()
    Path(path).write_text(meshcat.StaticHtml())


def with_camera_recorder(wire: Wiring | None, path: str | None, depth: bool,
                         box: list) -> Wiring | None:
    """``wire`` plus a :class:`pr2_drake.video.CameraRecorder` of the head camera writing to
    ``path`` (an mp4; ``depth``: the depth beside the colour), appended to ``box``; ``wire``
    itself when ``path`` is None. Close the recorder when the episode is over."""
    if path is None:
        return wire

    def wire_and_record(builder: DiagramBuilder, testbed: Testbed):
        from pr2_drake.video import add_camera_recorder

        blocks = wire(builder, testbed) if wire is not None else None
        box.append(add_camera_recorder(builder, testbed, path, depth))
        return blocks

    return wire_and_record
