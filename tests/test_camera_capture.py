"""Capture on demand: the head camera renders at a sample only when its ``capture`` input (the
testbed's ``camera_capture``) asks for it, and at every sample when nothing is connected; the
task-6 agent asks only while it looks; ``capture_color`` False renders depth only;
``camera_capture`` as an Env action."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from pr2_drake.camera import CameraSettings, RgbdFrame, RgbdSampler

W, H = 8, 6


def _images(value: int):
    color, depth = ImageRgba8U(W, H), ImageDepth32F(W, H)
    color.mutable_data[:] = value
    depth.mutable_data[:] = float(value)
    return color, depth


def _sampler(capture=None):
    """A 10 Hz sampler on fixed images (value 1); ``capture`` fixed unless None."""
    sampler = RgbdSampler(W, H, 10.0)
    ctx = sampler.CreateDefaultContext()
    _show(sampler, ctx, 1)
    if capture is not None:
        sampler.GetInputPort("capture").FixValue(ctx, capture)
    return sampler, ctx


def _show(sampler, ctx, value: int) -> None:
    color, depth = _images(value)
    sampler.GetInputPort("color_image").FixValue(ctx, color)
    sampler.GetInputPort("depth_image_32f").FixValue(ctx, depth)


def _frame(sampler, ctx) -> RgbdFrame:
    return sampler.GetOutputPort("rgbd").Eval(ctx)


def _count_renders(sampler) -> list:
    """Wrap the sampler's render (the only place the image ports are evaluated): returns the
    list the render times are appended to."""
    times = []
    render = sampler._render

    def counted(context, state, *color):
        times.append(context.get_time())
        render(context, state, *color)

    sampler._render = counted
    return times


@pytest.mark.parametrize("capture", [None, True])
def test_unconnected_or_true_captures_every_sample(capture):
    sampler, ctx = _sampler(capture)
    renders = _count_renders(sampler)
    sim = Simulator(sampler, ctx)
    sim.Initialize()
    _show(sampler, ctx, 2)
    sim.AdvanceTo(0.35)
    frame = _frame(sampler, ctx)
    assert frame.time == pytest.approx(0.3)
    assert np.all(frame.color == 2) and np.all(frame.depth == 2.0)
    assert renders == pytest.approx([0.0, 0.0, 0.1, 0.2, 0.3])  # initialization, then t = 0


def test_false_renders_nothing_and_keeps_the_frame():
    sampler, ctx = _sampler(False)
    renders = _count_renders(sampler)
    sim = Simulator(sampler, ctx)
    sim.Initialize()  # the initialization capture stays
    first = _frame(sampler, ctx)
    assert first.time == 0.0 and np.all(first.color == 1)
    _show(sampler, ctx, 2)  # the scene changes
    sim.AdvanceTo(0.35)
    kept = _frame(sampler, ctx)
    assert renders == [0.0]
    assert kept.time == 0.0 and np.all(kept.color == 1) and np.all(kept.depth == 1.0)
    sampler.GetInputPort("capture").FixValue(ctx, np.bool_(True))  # numpy bools too
    sim.AdvanceTo(0.45)
    assert renders == pytest.approx([0.0, 0.4])
    frame = _frame(sampler, ctx)
    assert frame.time == pytest.approx(0.4) and np.all(frame.color == 2)
    sampler.capture_always = True  # the video recorder's override
    sampler.GetInputPort("capture").FixValue(ctx, False)
    sim.AdvanceTo(0.55)
    assert renders == pytest.approx([0.0, 0.4, 0.5])


def test_capture_color_false_renders_depth_only():
    sampler, ctx = _sampler(True)
    sampler.GetInputPort("capture_color").FixValue(ctx, False)
    sim = Simulator(sampler, ctx)
    sim.Initialize()  # the initialization renders colour
    assert np.all(_frame(sampler, ctx).color == 1)
    _show(sampler, ctx, 2)
    sim.AdvanceTo(0.15)
    frame = _frame(sampler, ctx)
    assert frame.time == pytest.approx(0.1) and np.all(frame.depth == 2.0)
    assert frame.color.shape == (0, 0, 3) and frame.color.dtype == np.uint8
    sampler.GetInputPort("capture_color").FixValue(ctx, True)
    sim.AdvanceTo(0.25)
    assert np.all(_frame(sampler, ctx).color == 2)
    sampler.GetInputPort("capture_color").FixValue(ctx, False)
    sampler.capture_always = True  # the video recorder wants colour in every frame
    _show(sampler, ctx, 3)
    sim.AdvanceTo(0.35)
    assert np.all(_frame(sampler, ctx).color == 3)


def test_the_capture_port_holds_a_bool():
    sampler, ctx = _sampler(None)
    with pytest.raises(TypeError):
        sampler.GetInputPort("capture").FixValue(ctx, "no")


def test_frame_copies_keep_the_time_and_old_frames_read_zero():
    import copy
    import pickle

    frame = RgbdFrame(np.ones((2, 2, 3), np.uint8), np.ones((2, 2), np.float32), 1.5)
    assert copy.deepcopy(frame).time == 1.5
    assert pickle.loads(pickle.dumps(frame)).time == 1.5
    old = RgbdFrame.__new__(RgbdFrame)  # as unpickled from before the field existed
    old.__dict__.update(color=frame.color, depth=frame.depth)
    assert old.time == 0.0


def _env_with_camera():
    from pr2_drake.env import Env
    from pr2_drake.scenario import Scenario

    cam = CameraSettings(enabled=True, width=32, height=24, fps=10.0, quality="low")
    return Env(scenario=Scenario(camera=cam, seconds=math.inf), control_dt=0.05)


def test_env_action_camera_capture():
    from pr2_drake.env import InvalidAction

    env = _env_with_camera()
    assert env.testbed.HasInputPort("camera_capture")
    obs = env.observation()
    assert obs["cam"]["time"] == 0.0
    with pytest.raises(InvalidAction, match=r"action\['camera_capture'\]: expected a bool"):
        env.step({"camera_capture": "no"})
    assert env.time == 0.0
    for _ in range(4):  # False: no new frame (the legs are limp: no more than 0.35 s)
        _, _, obs = env.step({"camera_capture": False})
    assert env.time == pytest.approx(0.2) and obs["cam"]["time"] == 0.0
    for _ in range(3):  # absent: every sample again (0.2 and 0.3)
        _, _, obs = env.step({})
    assert env.time == pytest.approx(0.35) and obs["cam"]["time"] == pytest.approx(0.3)



def test_testbed_exports_camera_capture_only_with_the_camera():
    from pr2_drake.testbed import Testbed, TestbedConfig

    assert not Testbed(TestbedConfig()).HasInputPort("camera_capture")


def test_sequencer_asks_for_frames_to_map_and_to_look():
    """Every camera sample while it looks, every 2nd while it scans, every 4th while it walks
    (the map), none while it approaches, reaches or places; colour in the frames the
    detector may see (scanning; a look's last frames before it detects), not while it
    approaches."""
    from pr2_drake.agents.search.memory import Stage
    from tests.test_search_agent import StubDetector, searching, sequencer

    def captures(sim, seq, ctx, t0, t1):
        out, t = [], t0
        color.append(None)  # a new run: no stage before its first update
        while t < t1 - 1e-9:
            t += 0.02
            sim.AdvanceTo(t)
            m = seq.memory(ctx)
            out.append((round(t, 2), m.stage, bool(seq.GetOutputPort("camera_capture").Eval(ctx))))
            color.append((m.stage, bool(seq.GetOutputPort("camera_capture_color").Eval(ctx))))
        return out

    color = []  # (stage, colour asked) at each update
    seq, ctx = sequencer(detector=StubDetector(np.array([2.3, 2.7, 0.63])))
    seq.GetInputPort("body_state").FixValue(ctx, _body(2.0, 1.0, 0.0))
    from pydrake.systems.analysis import Simulator

    scan = captures(Simulator(seq, ctx), seq, ctx, 0.0, 1.0)  # a fresh sequencer scans
    assert {stage for _, stage, _ in scan} == {Stage.SCAN}
    asked = [t for t, _, c in scan if c]  # one sample in two: every 0.2 s
    assert len(asked) == 5 and np.allclose(np.diff(asked), 0.2, atol=0.021)
    seq, ctx = sequencer(detector=StubDetector(np.array([2.3, 2.7, 0.63])))
    sim = searching(seq, ctx, 2.0, 2.5 - 0.55, math.pi / 2)  # at the desk's look pose
    seen = captures(sim, seq, ctx, 0.0, 1.5)
    look = [t for t, stage, _ in seen if stage == Stage.LOOK]
    asked = [t for t, stage, c in seen if stage == Stage.LOOK and c]  # every sample: 0.1 s
    assert len(asked) >= round((look[-1] - look[0]) / 0.1) - 1
    assert np.allclose(np.diff(asked), 0.1, atol=0.021)
    assert Stage.APPROACH in {stage for _, stage, _ in seen}
    assert not any(c for _, stage, c in seen if stage == Stage.APPROACH)
    # An update decides from the stage it starts in: the stage the update before ended in.
    decided = [(a[0], b[1]) for a, b in zip(color, color[1:]) if a is not None and b is not None]
    assert {c for stage, c in decided if stage == Stage.SCAN} == {True}
    # A look: depth only while it settles, colour from shortly before its detection.
    look_color = [c for stage, c in decided if stage == Stage.LOOK]
    assert not look_color[0] and look_color[-1]
    assert {c for stage, c in decided if stage == Stage.APPROACH} == {False}


def _body(x: float, y: float, yaw: float) -> np.ndarray:
    from pr2_drake.ports import BODY_STATE_SIZE

    bs = np.zeros(BODY_STATE_SIZE)
    bs[:7] = [x, y, 0.57, math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
    return bs


def test_task6_agent_renders_only_while_it_looks(tmp_path):
    """Seed 0 from before the desk (as the closed-loop pick test, no scan but its first
    frame): the camera renders at the initialization and at the samples in LOOK up to the
    detection, never after it."""
    from tests._search_sim import desk_episode
    from pr2_drake.agents.search.memory import Stage

    params = tmp_path / "search.yaml"
    params.write_text("scan_turn_deg: 0.0\n")
    ep, agent = desk_episode(3.0, str(params))
    seq = agent.GetSubsystemByName("sequencer")
    seq_context = seq.GetMyContextFromRoot(ep.context)
    renders = []
    sampler = ep.testbed.GetSubsystemByName("head_camera_sampler")
    render = sampler._render

    def counted(context, state, *color):
        renders.append((context.get_time(), seq.memory(seq_context).stage))
        render(context, state, *color)

    sampler._render = counted
    ep.initialize()
    ep.advance_to(2.5)
    m = seq.memory(seq_context)
    assert m.p_WO is not None and m.stage != Stage.LOOK, m.log  # found, moved on
    t_found = float(next(line for line in m.log if "found" in line).split()[0])
    t_look = float(next(line for line in m.log if "-> LOOK" in line).split()[0])
    times = [t for t, _ in renders]
    assert times[0] == 0.0 and len(times) >= 5
    assert all(t_look <= t <= t_found + 1e-9 for t in times[1:]), (renders, m.log)
    assert all(stage == Stage.LOOK for _, stage in renders[1:])
    frame = ep.testbed.GetOutputPort("rgbd").Eval(ep.tb_context)
    assert frame.time == pytest.approx(times[-1])  # the last frame is kept afterwards


def test_video_recorder_makes_the_camera_render_every_sample(tmp_path):
    from pr2_drake.episode import Episode
    from pr2_drake.scenario import Scenario
    from pr2_drake.video import add_camera_recorder

    cam = CameraSettings(enabled=True, width=16, height=12, fps=10.0, quality="low")
    box = {}

    def wire(b, tb):
        box["rec"] = add_camera_recorder(b, tb, tmp_path / "head.mp4")
        return None

    ep = Episode(Scenario(camera=cam, seconds=1.0), wire)
    assert ep.testbed.GetSubsystemByName("head_camera_sampler").capture_always
    box["rec"].close()


def test_sandboxed_system_agent_sends_camera_capture_back():
    """The sandbox child answers a System agent's ``camera_capture`` output with the action
    (the parent's Env applies it like the other keys)."""
    from pr2_drake.agents.search.agent import ObjectSearchAgent
    from pr2_drake.compete.child import SystemRunner
    from pr2_drake.testbed import Testbed, TestbedConfig

    priors = dict(Testbed(TestbedConfig(task=6, seed=0,
                                        camera=CameraSettings(enabled=False))).scene.priors)
    runner = SystemRunner(ObjectSearchAgent(priors))
    assert runner.ports_out["camera_capture"].get_name() == "camera_capture"
