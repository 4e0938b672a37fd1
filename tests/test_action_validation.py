"""Every bad action given to Env.step is a ValueError naming the key and the fault, raised
before anything is applied; the environment then steps normally. Also the camera bounds."""

import re

import numpy as np
import pytest

from pr2_drake.agents.standing import StandingAgent
from pr2_drake.camera import CameraSettings
from pr2_drake.env import Env
from pr2_drake.observation import parse_action
from pr2_drake.ports import JointGroupCommand, real_vector, validate_command

Z8, Z10 = np.zeros(8), np.zeros(10)
MARK = np.full(10, 7.0)  # a valid legs effort that must not reach the plant with a bad action


def legs(values=Z10, **keys):
    return {"legs": {"ctrl_mode": "effort", "joint_values": values, **keys}}


def arms(values=Z8, **keys):
    return {"arms": {"ctrl_mode": "position", "joint_values": values, **keys}}


class Weird:
    """An object numpy cannot make numbers of."""


BIG_INT = [10**400] * 10

# (id, action, regex the message must match: the key path and the fault)
BAD = [
    # -- the action itself
    ("not-a-dict", [("legs", Z10)], r"action: expected a dict"),
    ("none-action", None, r"action: expected a dict"),
    ("unknown-key", {"legz": {}}, r"action: unknown keys \['legz'\]"),
    ("unknown-int-key", {1: 2, "x": 3}, r"action: unknown keys \['x', 1\]"),
    # -- a group entry
    ("legs-list", {"legs": [0.0] * 10}, r"action\['legs'\]: expected a dict"),
    ("legs-array", {"legs": Z10}, r"action\['legs'\]: expected a dict"),
    ("arms-str", {"arms": "position"}, r"action\['arms'\]: expected a dict"),
    ("legs-unknown-key", legs(gain=1), r"action\['legs'\]: unknown keys \['gain'\]"),
    ("arms-damping-typo", arms(damping=Z8), r"action\['arms'\]: unknown keys \['damping'\]"),
    ("legs-no-values", {"legs": {"ctrl_mode": "effort"}}, r"action\['legs'\]\['joint_values'\] is missing"),
    # -- joint_values: None, text, bytes
    ("values-none", legs(None), r"action\['legs'\]\['joint_values'\] is None"),
    ("values-str", legs("0" * 10), r"\['joint_values'\] is not numeric: got str"),
    ("values-num-strings", legs(["1.0"] * 10), r"\['joint_values'\] is not numeric: got text"),
    ("values-np-strings", legs(np.array(["1"] * 10)), r"\['joint_values'\] is not numeric: got text"),
    ("values-bytes", legs(b"0123456789"), r"\['joint_values'\] is not numeric: got bytes"),
    ("values-bytes-list", legs([b"1"] * 10), r"\['joint_values'\] is not numeric: got text"),
    # -- joint_values: not real numbers
    ("values-complex", legs(np.zeros(10, complex)), r"action\['legs'\]\['joint_values'\] is complex"),
    ("values-complex-list", legs([1j] * 10), r"\['joint_values'\] is complex"),
    ("values-object-array", legs(np.zeros(10, object)), r"\['joint_values'\] is not numeric: an object array"),
    ("values-none-entries", legs([None] * 10), r"\['joint_values'\] is not numeric: an object array"),
    ("values-mixed-none", legs([0.0] * 9 + [None]), r"\['joint_values'\] is not numeric"),
    ("values-objects", legs([Weird()] * 10), r"\['joint_values'\] is not numeric"),
    ("values-dict", legs({"a": 1}), r"\['joint_values'\] is not numeric"),
    ("values-set", legs(set(range(10))), r"\['joint_values'\] is not numeric"),
    ("values-generator", legs(x for x in range(10)), r"\['joint_values'\] is not numeric"),
    ("values-bools", legs([True] * 10), r"\['joint_values'\] is not numeric: booleans"),
    ("values-bool-array", legs(np.ones(10, bool)), r"\['joint_values'\] is not numeric: booleans"),
    ("values-one-bool", legs([0.0] * 9 + [True]), r"\['joint_values'\] is not numeric: booleans"),
    ("values-np-bool", legs([0.0] * 9 + [np.bool_(False)]), r"\['joint_values'\] is not numeric: booleans"),
    ("values-datetime", legs(np.array(["2020-01-01"] * 10, "datetime64[D]")), r"\['joint_values'\] is not numeric"),
    # -- joint_values: wrong shape
    ("values-short", legs(np.zeros(3)), r"action\['legs'\]\['joint_values'\] must have 10 entries, got shape \(3,\)"),
    ("values-long", arms(np.zeros(10)), r"action\['arms'\]\['joint_values'\] must have 8 entries, got shape \(10,\)"),
    ("values-empty", legs([]), r"\['joint_values'\] must have 10 entries, got shape \(0,\)"),
    ("values-scalar", legs(0.0), r"\['joint_values'\] must have 10 entries, got shape \(\)"),
    ("values-np-scalar", legs(np.float64(1.0)), r"\['joint_values'\] must have 10 entries, got shape \(\)"),
    ("values-nested", legs([[0.0] * 10]), r"\['joint_values'\] must have 10 entries, got shape \(1, 10\)"),
    ("values-column", legs(np.zeros((10, 1))), r"\['joint_values'\] must have 10 entries, got shape \(10, 1\)"),
    ("values-matrix", legs(np.zeros((2, 5))), r"\['joint_values'\] must have 10 entries, got shape \(2, 5\)"),
    ("values-ragged", legs([[0.0] * 5, [0.0] * 4]), r"\['joint_values'\] is not a numeric vector of shape \(10,\)"),
    # -- joint_values: not finite
    ("values-inf", legs([np.inf] * 10), r"action\['legs'\]\['joint_values'\] contains NaN or inf"),
    ("values-nan", arms([0.0] * 7 + [np.nan]), r"action\['arms'\]\['joint_values'\] contains NaN or inf"),
    ("values-neg-inf-f32", legs(np.full(10, -np.inf, np.float32)), r"\['joint_values'\] contains NaN or inf"),
    ("values-overflow-literal", legs([1e300] * 9 + [float("1e309")]), r"\['joint_values'\] contains NaN or inf"),
    ("values-huge-int", legs(BIG_INT), r"\['joint_values'\] has a value beyond the float range"),
    ("values-one-huge-int", legs([0] * 9 + [-(10**309)]), r"\['joint_values'\] has a value beyond the float range"),
    ("values-longdouble-overflow", legs(np.full(10, np.longdouble("1e400"))), r"\['joint_values'\] (has a value beyond the float range|contains NaN or inf)"),
    # -- ctrl_mode
    ("mode-unknown", arms(ctrl_mode="pos"), r"action\['arms'\]\['ctrl_mode'\]: unknown mode 'pos'"),
    ("mode-torque", legs(ctrl_mode="torque"), r"action\['legs'\]\['ctrl_mode'\]: unknown mode 'torque'"),
    ("mode-upper", legs(ctrl_mode="EFFORT"), r"\['ctrl_mode'\]: unknown mode 'EFFORT'"),
    ("mode-none", legs(ctrl_mode=None), r"action\['legs'\]\['ctrl_mode'\]: mode must be a str"),
    ("mode-int", legs(ctrl_mode=2), r"\['ctrl_mode'\]: mode must be a str"),
    ("mode-array", legs(ctrl_mode=np.array(["effort"])), r"\['ctrl_mode'\]: mode must be a str.*ndarray"),
    ("mode-bytes", legs(ctrl_mode=b"effort"), r"\['ctrl_mode'\]: mode must be a str.*bytes"),
    ("mode-list", legs(ctrl_mode=["effort"]), r"\['ctrl_mode'\]: mode must be a str.*list"),
    # -- stiffness / dampings
    ("stiffness-negative", arms(stiffness=-np.ones(8)), r"action\['arms'\]\['stiffness'\] must be non-negative"),
    ("stiffness-one-negative", arms(stiffness=[1.0] * 7 + [-1e-9]), r"\['stiffness'\] must be non-negative"),
    ("stiffness-short", arms(stiffness=np.ones(3)), r"\['stiffness'\] must have 8 entries, got shape \(3,\)"),
    ("stiffness-nan", arms(stiffness=[np.nan] * 8), r"\['stiffness'\] contains NaN or inf"),
    ("stiffness-inf", arms(stiffness=[np.inf] * 8), r"\['stiffness'\] contains NaN or inf"),
    ("stiffness-str", arms(stiffness="100"), r"\['stiffness'\] is not numeric"),
    ("stiffness-complex", arms(stiffness=np.ones(8, complex)), r"\['stiffness'\] is complex"),
    ("stiffness-scalar", arms(stiffness=100.0), r"\['stiffness'\] must have 8 entries, got shape \(\)"),
    ("stiffness-huge-int", arms(stiffness=[10**400] * 8), r"\['stiffness'\] has a value beyond the float range"),
    ("dampings-negative", arms(dampings=-np.ones(8)), r"action\['arms'\]\['dampings'\] must be non-negative"),
    ("dampings-nan", legs(ctrl_mode="velocity", dampings=[np.nan] * 10), r"action\['legs'\]\['dampings'\] contains NaN or inf"),
    ("dampings-bools", arms(dampings=[True] * 8), r"\['dampings'\] is not numeric: booleans"),
    ("dampings-nested", arms(dampings=[[1.0] * 8]), r"\['dampings'\] must have 8 entries, got shape \(1, 8\)"),
    ("dampings-object", arms(dampings=np.ones(8, object)), r"\['dampings'\] is not numeric: an object array"),
    # -- JointGroupCommand objects given directly
    ("cmd-values-none", {"legs": JointGroupCommand("effort", None)}, r"action\['legs'\]: values is None"),
    ("cmd-mode-array", {"legs": JointGroupCommand(np.array("effort"), Z10)}, r"action\['legs'\]: mode must be a str"),
    ("cmd-mode-unknown", {"legs": JointGroupCommand("torque", Z10)}, r"action\['legs'\]: unknown mode 'torque'"),
    ("cmd-short", {"arms": JointGroupCommand("position", Z10)}, r"action\['arms'\]: values must have 8 entries"),
    ("cmd-complex", {"legs": JointGroupCommand("effort", np.zeros(10, complex))}, r"action\['legs'\]: values is complex"),
    ("cmd-strings", {"legs": JointGroupCommand("effort", ["1"] * 10)}, r"action\['legs'\]: values is not numeric"),
    ("cmd-huge-int", {"legs": JointGroupCommand("effort", BIG_INT)}, r"action\['legs'\]: values has a value beyond the float range"),
    ("cmd-neg-stiffness", {"arms": JointGroupCommand("position", Z8, -np.ones(8))}, r"action\['arms'\]: stiffness must be non-negative"),
    ("cmd-nan-damping", {"arms": JointGroupCommand("position", Z8, None, [np.nan] * 8)}, r"action\['arms'\]: damping contains NaN or inf"),
    # -- pick
    ("pick-unknown", {"pick": "third_hand"}, r"action\['pick'\]: expected 'left_hand', 'right_hand' or None, got 'third_hand'"),
    ("pick-array", {"pick": np.array(["left_hand"])}, r"action\['pick'\]: expected .* got ndarray"),
    ("pick-0d-array", {"pick": np.array("left_hand")}, r"action\['pick'\]: expected .* got ndarray"),
    ("pick-list", {"pick": ["left_hand"]}, r"action\['pick'\]: expected .* got list"),
    ("pick-true", {"pick": True}, r"action\['pick'\]: expected .* got bool"),
    ("pick-false", {"pick": False}, r"action\['pick'\]: expected .* got bool"),
    ("pick-bytes", {"pick": b"left_hand"}, r"action\['pick'\]: expected .* got bytes"),
    ("pick-int", {"pick": 1}, r"action\['pick'\]: expected .* got int"),
    ("pick-case", {"pick": "Left_Hand"}, r"action\['pick'\]: expected .* got 'Left_Hand'"),
    # -- release
    ("release-str", {"release": "yes"}, r"action\['release'\]: expected a bool, got str"),
    ("release-int", {"release": 1}, r"action\['release'\]: expected a bool, got int"),
    ("release-float", {"release": 0.0}, r"action\['release'\]: expected a bool, got float"),
    ("release-array", {"release": np.array([True])}, r"action\['release'\]: expected a bool, got ndarray"),
    ("release-list", {"release": [True]}, r"action\['release'\]: expected a bool, got list"),
    # -- camera_capture
    ("capture-int", {"camera_capture": 0},
     r"action\['camera_capture'\]: expected a bool, got int"),
    ("capture-str", {"camera_capture": "off"},
     r"action\['camera_capture'\]: expected a bool, got str"),
    ("capture-array", {"camera_capture": np.array([False])},
     r"action\['camera_capture'\]: expected a bool, got ndarray"),
    # -- a good group beside a bad key: nothing may be applied (all checked first)
    ("good-legs-bad-pick", {**legs(MARK), "pick": np.array(["left_hand"])}, r"action\['pick'\]"),
    ("good-legs-bad-release", {**legs(MARK), "release": "no"}, r"action\['release'\]"),
    ("good-legs-bad-capture", {**legs(MARK), "camera_capture": 1.0},
     r"action\['camera_capture'\]"),
    ("good-legs-bad-arms", {**legs(MARK), **arms(None)}, r"action\['arms'\]\['joint_values'\] is None"),
    ("good-legs-bad-arms-mode", {**legs(MARK), **arms(ctrl_mode="pos")}, r"action\['arms'\]\['ctrl_mode'\]"),
]
assert len({case[0] for case in BAD}) == len(BAD) >= 50


@pytest.fixture(scope="module")
def env():
    return Env(task=None, seed=0)


@pytest.fixture(scope="module")
def agent():
    return StandingAgent()


def _testbed_context(env):
    episode = getattr(env, "episode", None)
    if episode is not None:
        return episode.tb_context
    return env.simulator.get_context()  # an Env that owns its simulator directly


def _legs_command(env) -> JointGroupCommand:
    return env.testbed.GetInputPort("legs_command").Eval(_testbed_context(env))


def _good_step(env, agent) -> None:
    """One step with the standing action: time advances by control_dt, the robot stands."""
    if env.status.done:
        env.reset()
    obs = env.observation()
    t0 = env.time
    done, _, obs = env.step(agent.next_action(obs))
    assert not done, env.status.termination
    assert env.time == pytest.approx(t0 + env.control_dt)
    assert np.all(np.isfinite(obs["agent"]["joint_state"]["legs_positions"]))
    assert obs["agent"]["body_state"]["world_pos"][2] > 0.5


@pytest.mark.parametrize("action, message", [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_bad_action_is_refused_before_anything_is_applied(env, agent, action, message):
    _good_step(env, agent)
    before = _legs_command(env)
    mode, values, t = before.mode, np.array(before.values), env.time
    with pytest.raises(ValueError, match=message):
        env.step(action)
    after = _legs_command(env)
    assert after.mode == mode and np.array_equal(after.values, values)
    assert env.time == t
    _good_step(env, agent)


@pytest.mark.parametrize("action, message", [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_parse_action_refuses_the_same(action, message):
    with pytest.raises(ValueError, match=message):
        parse_action(action)


GOOD = [
    ("empty", {}),
    ("ints", legs([0] * 10)),
    ("int-array", legs(np.zeros(10, np.int32))),
    ("uint-array", legs(np.zeros(10, np.uint8))),
    ("float32", legs(np.zeros(10, np.float32))),
    ("float16", legs(np.zeros(10, np.float16))),
    ("tuple", legs(tuple([0.0] * 10))),
    ("np-scalars", legs([np.float32(0.0)] * 5 + [np.int64(0)] * 5)),
    ("huge-finite-effort", legs([1e300] * 10)),  # clamped to the peak torque downstream
    ("default-mode", {"legs": {"joint_values": np.zeros(10)}}),
    ("np-str-mode", legs(ctrl_mode=np.str_("effort"))),
    ("gains-none", arms(stiffness=None, dampings=None)),
    ("gains-ints", arms(stiffness=[100] * 8, dampings=[0] * 8)),
    ("velocity", legs(ctrl_mode="velocity", dampings=np.ones(10, np.float32))),
    ("np-bool-release", {"release": np.bool_(True)}),
    ("release-none", {"release": None}),
    ("pick-none", {"pick": None, "release": False}),
    ("pick-empty", {"pick": ""}),
    ("pick-np-str", {"pick": np.str_("right_hand")}),
    ("groups-none", {"arms": None, "legs": None}),
    ("command-object", {"legs": JointGroupCommand("effort", [0] * 10)}),
    ("capture-false", {"camera_capture": False}),  # no camera (task None): changes nothing
    ("capture-np-bool", {"camera_capture": np.bool_(True)}),
    ("capture-none", {"camera_capture": None}),
]


@pytest.mark.parametrize("action", [c[1] for c in GOOD], ids=[c[0] for c in GOOD])
def test_good_edge_cases_are_accepted(action):
    parsed = parse_action(action)
    assert set(parsed) == {"arms", "legs", "pick", "release", "camera_capture"}
    assert type(parsed["pick"]) is str and type(parsed["release"]) is bool
    assert type(parsed["camera_capture"]) is bool
    assert parsed["camera_capture"] == bool(action.get("camera_capture", True) in (None, True))
    for group, n in (("arms", 8), ("legs", 10)):
        cmd = parsed[group]
        if action.get(group) is None:
            assert cmd is None
            continue
        assert type(cmd.mode) is str
        for arr in (cmd.values, cmd.stiffness, cmd.damping):
            assert arr is None or (arr.dtype == np.float64 and arr.shape == (n,))


def test_good_edge_cases_step(env, agent):
    for name, action in GOOD:
        if "pick" in action and action["pick"]:
            continue  # a pick with no object in reach is harmless, but keep the hands free
        env.reset()
        _good_step(env, agent)
        done, _, obs = env.step(action)
        assert not done, name
        assert np.all(np.isfinite(obs["agent"]["joint_state"]["legs_applied_effort"])), name
    env.reset()


def test_pick_reaches_the_port_as_a_plain_str(env):
    env.reset()
    env.step({"pick": np.str_("left_hand")})
    value = env.testbed.GetInputPort("pick").Eval(_testbed_context(env))
    assert type(value) is str and value == "left_hand"
    env.reset()


@pytest.mark.parametrize(
    "cmd, message",
    [
        (JointGroupCommand("effort", None), "legs_command: values is None"),
        (JointGroupCommand(np.array(["effort"]), Z10), "legs_command: mode must be a str"),
        (JointGroupCommand(None, Z10), "legs_command: mode must be a str"),
        (JointGroupCommand("torque", Z10), "legs_command: unknown mode 'torque'"),
        (JointGroupCommand("effort", np.zeros(9)), "legs_command: values must have 10 entries"),
        (JointGroupCommand("effort", np.zeros((10, 1))), r"values must have 10 entries, got shape \(10, 1\)"),
        (JointGroupCommand("effort", np.zeros(10, complex)), "legs_command: values is complex"),
        (JointGroupCommand("effort", np.zeros(10, object)), "legs_command: values is not numeric"),
        (JointGroupCommand("effort", ["0.0"] * 10), "legs_command: values is not numeric"),
        (JointGroupCommand("effort", BIG_INT), "legs_command: values has a value beyond the float range"),
        (JointGroupCommand("effort", [np.nan] * 10), "legs_command: values contains NaN or inf"),
        (JointGroupCommand("position", Z10, -np.ones(10)), "legs_command: stiffness must be non-negative"),
        (JointGroupCommand("position", Z10, None, [np.inf] * 10), "legs_command: damping contains NaN or inf"),
        (JointGroupCommand("position", Z10, "1" * 10), "legs_command: stiffness is not numeric"),
        ("effort", "legs_command: expected a JointGroupCommand"),
    ],
)
def test_validate_command_names_port_and_fault(cmd, message):
    with pytest.raises(ValueError, match=message):
        validate_command("legs_command", cmd, 10)


def test_validate_command_accepts_and_keeps_good_commands():
    for cmd in (JointGroupCommand.effort(np.ones(10)),
                JointGroupCommand("effort", [1] * 10),
                JointGroupCommand("position", np.zeros(10, np.float32), [100] * 10, np.ones(10)),
                JointGroupCommand("velocity", Z10, None, np.zeros(10))):
        assert validate_command("legs_command", cmd, 10) is cmd
    v = np.ones(10)
    assert real_vector(v, 10, "v") is v  # the common case: no copy


# -- camera settings ---------------------------------------------------------------------------

@pytest.mark.parametrize(
    "changes, message",
    [
        ({"width": 3841}, r"camera.width must be in \[8, 3840\] pixels .*3840x2160\), got 3841"),
        ({"height": 2161}, r"camera.height must be in \[8, 2160\] pixels .*3840x2160\), got 2161"),
        ({"width": 100000, "height": 100000}, r"camera.width must be in \[8, 3840\]"),
        ({"width": 7}, r"camera.width must be in \[8, 3840\]"),
        ({"height": 0}, r"camera.height must be in \[8, 2160\]"),
        ({"width": -640}, r"camera.width must be in \[8, 3840\]"),
        ({"width": 640.5}, r"camera.width must be an integer number of pixels"),
        ({"height": "480"}, r"camera.height must be an integer number of pixels"),
        ({"width": True}, r"camera.width must be an integer number of pixels"),
        ({"fps": 0}, r"camera.fps must be a finite number with 0 < fps <= 1000"),
        ({"fps": -10.0}, r"camera.fps must be a finite number with 0 < fps <= 1000"),
        ({"fps": float("nan")}, r"camera.fps"),
        ({"fps": float("inf")}, r"camera.fps"),
        ({"fps": 1e6}, r"camera.fps .*<= 1000"),
        ({"fps": "10"}, r"camera.fps"),
        ({"quality": "ultra"}, r"camera.quality must be one of \('low', 'medium', 'high'\), got 'ultra'"),
        ({"quality": None}, r"camera.quality must be one of"),
        ({"quality": np.array(["low"])}, r"camera.quality must be one of"),
        ({"fov_y_deg": 0.0}, r"camera.fov_y_deg .*0 < fov_y_deg < 170"),
        ({"fov_y_deg": 180.0}, r"camera.fov_y_deg"),
        ({"z_near": 0.0}, r"camera.z_near"),
        ({"z_far": float("inf")}, r"camera.z_far"),
        ({"z_near": 5.0, "z_far": 1.0}, r"camera.z_near must be below camera.z_far"),
        ({"enabled": "yes"}, r"camera.enabled must be a bool"),
    ],
)
def test_camera_settings_refuse_bad_values_naming_the_field(changes, message):
    with pytest.raises(ValueError, match=message) as info:
        CameraSettings(**{"enabled": True, **changes}).validate()
    field = next(iter(changes))
    assert re.search(rf"camera\.{field}\b", str(info.value))


@pytest.mark.parametrize(
    "changes",
    [{}, {"width": 3840, "height": 2160}, {"width": 8, "height": 8}, {"width": np.int64(320)},
     {"fps": 1000}, {"fps": 5}, {"fps": np.float32(30.0)}, {"quality": "high"},
     {"z_near": 0.01, "z_far": 100}],
)
def test_camera_settings_accept_the_bounds(changes):
    CameraSettings(enabled=True, **changes).validate()
