"""The shared key and gamepad mapping of the person sessions (``benchmarks/sessions/keys.py``)."""

from __future__ import annotations

import math
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from strol_gym.benchmarks.sessions import keys
from strol_gym.benchmarks.sessions.keys import ArmPush, Intent, Pad, PushSizes
from strol_gym.envs.study.people import PushParams


def test_keys_name_axes_and_cancel():
    assert keys.arm_intent(["W"]) == Intent(away=1.0)
    assert keys.arm_intent(["a", "q"]) == Intent(right=-1.0, up=-1.0)
    assert keys.arm_intent(["w", "s"]) == Intent()  # one axis both ways: nothing
    assert keys.arm_intent(["d", "arrowright"]) == Intent(right=1.0)  # not twice as hard
    assert keys.arm_intent(["ArrowUp", "Shift"]) == Intent(away=1.0, harder=True)
    assert keys.arm_intent(["i", "l", "o", "x", "f1"]) == Intent(tilt=1.0, turn=1.0, roll=1.0)
    assert keys.car_intent(["arrowup", "arrowleft"]) == (1.0, -1.0)
    assert keys.car_intent(["arrowdown", "arrowup", "d"]) == (0.0, 1.0)


def test_a_key_push_is_the_simulated_users_push():
    """One source for the push's size: ``PushParams``'s defaults, whatever they become."""
    plain, person = PushSizes(), PushParams()
    assert (plain.force, plain.torque, plain.ramp) == (
        person.push_force,
        person.push_torque,
        person.ramp,
    )


def test_module_imports_no_window_library():
    code = (
        "import sys, strol_gym.benchmarks.sessions.keys\n"
        "bad = [m for m in ('pygame', 'glfw', 'mujoco.viewer') if m in sys.modules]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize("azimuth", [0.0, 90.0, 150.0, -60.0])
@pytest.mark.parametrize("elevation", [-20.0, -60.0])
def test_axes_are_mujocos_camera(azimuth, elevation):
    """right and away are MuJoCo's free camera's right and forward, the latter laid flat."""
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    data = mujoco.MjData(model)
    cam = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(model, cam)
    cam.azimuth, cam.elevation = azimuth, elevation
    head, fwd, up, right = (np.zeros(3) for _ in range(4))
    mujoco.mjv_cameraFrame(head, fwd, up, right, data, cam)
    frame = keys.camera_axes(azimuth)
    flat = np.array([fwd[0], fwd[1], 0.0]) / math.hypot(fwd[0], fwd[1])
    np.testing.assert_allclose(frame[:, 0], right, atol=1e-9)
    np.testing.assert_allclose(frame[:, 1], flat, atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(frame), 1.0)
    assert keys.azimuth_of(fwd) == pytest.approx(azimuth)


def test_azimuth_of_refuses_a_camera_looking_down():
    with pytest.raises(ValueError, match="straight up or down"):
        keys.azimuth_of([0.0, 0.0, -1.0])
    with pytest.raises(ValueError, match="forward"):
        keys.azimuth_of([1.0, float("nan"), 0.0])


def _turned(v, torque, eps=1e-3):
    """``v`` after a small rotation about ``torque``'s axis (by the right-hand rule)."""
    return v + eps * np.cross(torque, v)


def test_torque_keys_turn_the_cup_as_named():
    az = 150.0
    right, away, up = keys.camera_axes(az).T
    _, tilt = keys.to_world(keys.arm_intent(["i"]), az)
    assert np.dot(_turned(up, tilt) - up, away) > 0  # the top tips away
    _, roll = keys.to_world(keys.arm_intent(["o"]), az)
    assert np.dot(_turned(up, roll) - up, right) > 0  # the top rolls right
    _, turn = keys.to_world(keys.arm_intent(["l"]), az)
    assert np.dot(_turned(away, turn) - away, right) > 0  # the front turns right
    force, _ = keys.to_world(keys.arm_intent(["d", "e"]), az)
    np.testing.assert_allclose(force, right + up)


def test_push_ramps_like_a_hand_and_lets_go():
    push = ArmPush(reflex_force=100.0, reflex_torque=10.0)
    w_key = keys.arm_intent(["w"])
    sizes = [push.step(w_key, 0.05, 0.0).size for _ in range(6)]
    np.testing.assert_allclose(sizes, [10, 20, 30, 40, 40, 40])
    wrench = push.step(w_key, 0.05, 90.0)  # the camera turned: the push turns with it
    np.testing.assert_allclose(wrench.force, [0.0, 40.0, 0.0], atol=1e-9)
    assert wrench.torque_size == 0.0
    down = [push.step(Intent(), 0.05, 90.0) for _ in range(5)]
    np.testing.assert_allclose([w.size for w in down], [30, 20, 10, 0, 0])
    np.testing.assert_allclose(down[0].force, [0.0, 30.0, 0.0], atol=1e-9)  # same direction
    np.testing.assert_allclose(down[-1].force, 0.0)


def test_push_stays_below_the_reflex_unless_harder():
    push = ArmPush(reflex_force=45.0, reflex_torque=5.0)
    both = keys.arm_intent(["a", "i"])
    for _ in range(40):
        w = push.step(both, 0.05, 0.0)
    assert w.size == pytest.approx(0.8 * 45.0) and w.torque_size == pytest.approx(0.8 * 5.0)
    assert np.linalg.norm(w.force) == pytest.approx(w.size)
    harder = keys.arm_intent(["a", "i", "shift"])
    for _ in range(40):
        w = push.step(harder, 0.05, 0.0)
    assert w.harder and w.size == pytest.approx(1.25 * 45.0)
    assert w.torque_size == pytest.approx(1.25 * 5.0)
    assert push.ceiling(False) == pytest.approx((36.0, 4.0))  # a drag's cap
    assert push.ceiling(True) == pytest.approx((56.25, 6.25))
    no_reflex = ArmPush()
    for _ in range(10):
        w = no_reflex.step(keys.arm_intent(["q"]), 0.05, 0.0)
    np.testing.assert_allclose(w.force, [0.0, 0.0, -40.0], atol=1e-9)


def test_push_checks_its_arguments():
    with pytest.raises(ValueError, match=r"PushSizes\.below"):
        PushSizes(below=1.0)
    with pytest.raises(ValueError, match=r"PushSizes\.force"):
        PushSizes(force=float("nan"))
    with pytest.raises(ValueError, match=r"PushSizes\.harder"):
        PushSizes(harder=0.9)
    with pytest.raises(ValueError, match="reflex_force"):
        ArmPush(reflex_force=0.0)
    with pytest.raises(ValueError, match="dt"):
        ArmPush().step(Intent(), -0.1, 0.0)


def test_car_correction_is_a_max_times_the_held_share():
    a_max = np.array([5.0, 0.02])
    up = keys.car_intent(["arrowup"])
    none = keys.car_intent([])
    np.testing.assert_allclose(keys.car_correction([up] * 4, a_max), [5.0, 0.0])
    np.testing.assert_allclose(keys.car_correction([up, up, none, none], a_max), [2.5, 0.0])
    right = keys.car_intent(["arrowright"])
    np.testing.assert_allclose(keys.car_correction([right], a_max), [0.0, 0.02])
    np.testing.assert_allclose(keys.car_correction([], a_max), [0.0, 0.0])


def test_gamepad_standard_mapping():
    still = Pad.of([0.1, -0.1, 0.0, 0.0], [])
    assert keys.pad_arm_intent(still) == Intent()  # inside the dead zone
    forward = Pad.of([0.0, -1.0, 0.0, 0.0], [0.0] * 17)
    assert keys.pad_arm_intent(forward) == Intent(away=1.0)
    buttons = [0.0] * 17
    buttons[keys.RB], buttons[keys.RT], buttons[keys.DPAD_LEFT] = 1.0, 0.9, 1.0
    pad = Pad.of([0.575, 0.0, -1.0, 1.0], buttons)
    got = keys.pad_arm_intent(pad)
    assert got.right == pytest.approx(0.5) and got.up == 1.0 and got.harder
    assert (got.turn, got.tilt, got.roll) == (-1.0, -1.0, -1.0)
    assert keys.pad_car_intent(Pad.of([1.0, 0.0], [0.0] * 8)) == (0.0, 1.0)
    trig = [0.0] * 8
    trig[keys.LT] = 1.0
    assert keys.pad_car_intent(Pad.of([0.0, 0.0], trig)) == (-1.0, 0.0)
    assert keys.pad_car_intent(Pad.of([0.0, float("nan")], [True])) == (0.0, 0.0)


def test_sdl_controller_reads_as_the_standard_mapping():
    pad = keys.pad_from_sdl(
        {"leftx": 32767, "lefty": -32767, "triggerright": 32767},
        {"rightshoulder": True, "dpad_right": True},
    )
    intent = keys.pad_arm_intent(pad)
    assert intent == Intent(right=1.0, away=1.0, up=1.0, roll=1.0, harder=True)
    assert keys.pad_car_intent(pad) == (1.0, 1.0)
