"""Kokone (2009 thesis, 22 DOF, SSC-32): the robot files and the thesis's worked examples.

The thesis's numbers come from ``../shared/reference/kokone-thesis.md`` (Examples 3 and 4,
Tables 4.1-4.3, 4.6). Lengths in the thesis are cm; our model is in m.
"""

from __future__ import annotations

import importlib.util
import math
import re

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wbc import load_robot
from wbc.exceptions import ModelError, ServoMapError
from wbc.paths import robots_dir
from wbc.pose_ik import StanceIK
from wbc.servos.ssc32 import PULSE_MAX, PULSE_MIN, Ssc32Channel, Ssc32Map

KOKONE = robots_dir() / "kokone"
CM = 0.01


@pytest.fixture(scope="module")
def gen():
    spec = importlib.util.spec_from_file_location("kokone_make_urdf", KOKONE / "make_urdf.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def kokone():
    return load_robot("kokone")


def thesis_dh(th, d, a, al):
    """The thesis's eq. 4.15, written again here (degrees), independent of the generator."""
    t, al = math.radians(th), math.radians(al)
    c, s, ca, sa = math.cos(t), math.sin(t), math.cos(al), math.sin(al)
    return np.array(
        [[c, -ca * s, sa * s, a * c], [s, ca * c, -sa * c, a * s], [0, sa, ca, d], [0, 0, 0, 1]]
    )


# Table 4.1 (d, a, alpha) and the hip frame A_mc of the thesis
TABLE_4_1 = [(0, 0, 90), (-4.3, 0, 90), (0, -6.1, 0), (0, -6.1, 0), (0, -3.3, 90), (0, -2.0, 0)]


def thesis_foot(theta, right: bool, hip=(0.0, 0.0, 21.8)) -> np.ndarray:
    """A_DPie / A_IPie = A_mc · A_td|ti · prod(A_i) (eqs. 4.31-4.36), in cm."""
    A = np.array([[0, 0, 1, hip[0]], [0, -1, 0, hip[1]], [1, 0, 0, hip[2]], [0, 0, 0, 1.0]])
    base = np.eye(4)
    base[1, 3] = 2.25 if right else -2.25
    A = A @ base
    for th, (d, a, al) in zip(theta, TABLE_4_1, strict=True):
        A = A @ thesis_dh(th, d, a, al)
    return A


def set_legs(robot, gen, q, right_theta, left_theta):
    for p, th in (("r", right_theta), ("l", left_theta)):
        for name, v in zip(gen.LEG_JOINTS, gen.dh_to_q(th), strict=True):
            q[robot.q_index(f"{p}_{name}")] = v
    return q


FOOT_R = np.array([[0, 0, 1], [0, -1, 0], [1, 0, 0.0]])  # the thesis's flat foot / hip rotation


# ---------------------------------------------------------------------- the robot files
def test_committed_files_equal_generator_output(gen):
    assert (KOKONE / "kokone.urdf").read_text() == gen.build_urdf()
    assert (KOKONE / "ssc32.toml").read_text() == gen.build_ssc32_map()
    assert (KOKONE / "poses.toml").read_text() == gen.build_poses()


def test_model_sizes_masses_servo_limits(kokone, gen):
    assert kokone.n_joints == 22
    assert kokone.total_mass == pytest.approx(1.2, abs=1e-9)  # thesis: ~1.2 kg (estimate split)
    for f in ("torso", "l_sole", "r_sole", "l_hand", "r_hand"):
        kokone.frame_id(f)
    assert np.allclose(kokone.v_max, math.radians(60) / 0.16)  # 0.16 s/60° (Table 3.1)
    assert np.allclose(kokone.model.effortLimit[6:], 4.2 * 9.80665 / 100)  # 4.2 kg·cm
    # height: the hip 21.8 cm up (4.3+6.1+6.1+3.3+2.0), the head box's top at 37 cm (thesis)
    q = kokone.configuration("straight")
    assert kokone.frame_placement(q, "torso").translation[2] == pytest.approx(0.218, abs=1e-12)
    head = kokone.frame_placement(q, "head")
    top = max(
        (head.rotation @ np.array(c) + head.translation)[2] + size[2] / 2
        for link in gen.head_links()
        if link.name == "head"
        for c, size, _ in link.boxes
    )
    assert top == pytest.approx(0.37, abs=1e-9)


def test_table_4_3_limits_in_our_angles(kokone, gen):
    table = [(45, 135), (45, 135), (45, 135), (-90, 0), (-45, 45), (-45, 45)]
    for p in "lr":
        for k, name in enumerate(gen.LEG_JOINTS):
            i = kokone.joint_index(f"{p}_{name}")
            dh = sorted(
                gen.q_to_dh(np.where(np.arange(6) == k, v, 0.0))[k]
                for v in (kokone.q_min[i], kokone.q_max[i])
            )
            assert dh == pytest.approx(table[k], abs=1e-9), (p, name)
    assert kokone.q_max[kokone.joint_index("l_knee")] == pytest.approx(math.pi / 2)  # flexion +


def test_straight_legs_put_the_soles_21_8_below_the_hip(kokone, gen):
    q = kokone.neutral()
    q[2] = 0.218
    set_legs(kokone, gen, q, (90, 90, 90, 0, 0, 0), (90, 90, 90, 0, 0, 0))
    for s, y in (("l_sole", 0.0225), ("r_sole", -0.0225)):
        M = kokone.frame_placement(q, s)
        assert np.allclose(M.translation, [0, y, 0], atol=1e-12)
        assert np.allclose(M.rotation, np.eye(3), atol=1e-12)


@settings(max_examples=25, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    st.lists(st.floats(0.0, 1.0), min_size=12, max_size=12),
    st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(18, 22)),
)
def test_urdf_equals_the_thesis_dh_chain_everywhere(kokone, gen, u, hip):
    """For any angles inside Table 4.3 and any hip position, our soles are the thesis's feet."""
    lo = np.array([r[0] for r in gen.DH_RANGE_DEG], dtype=float)
    hi = np.array([r[1] for r in gen.DH_RANGE_DEG], dtype=float)
    th = {s: lo + np.array(u[k * 6 : k * 6 + 6]) * (hi - lo) for k, s in enumerate("rl")}
    q = kokone.neutral()
    q[:3] = np.array(hip) * CM
    set_legs(kokone, gen, q, th["r"], th["l"])
    for frame, s, right in (("r_sole", "r", True), ("l_sole", "l", False)):
        A = thesis_foot(th[s], right, hip=hip)
        M = kokone.frame_placement(q, frame)
        assert np.allclose(A[:3, 3], M.translation / CM, atol=1e-9)
        assert np.allclose(A[:3, :3], M.rotation @ FOOT_R, atol=1e-12)
    assert kokone.within_limits(q, tol=1e-9)


# ---------------------------------------------------------------------- Example 3 (FK)
def test_example_3_forward_kinematics(kokone, gen):
    """Table 4.2 angles, hip lowered to 20.8: A_DPie and A_IPie as printed, to 1e-4 cm."""
    right, left = (90, 90, 134, -64, 20, 0), (90, 90, 113, -46, 23, 0)
    q = kokone.neutral()
    q[2] = 0.208
    set_legs(kokone, gen, q, right, left)
    printed = {"r_sole": (2.1511, -2.25, 1.0799), "l_sole": (0.0, 2.25, -0.0302)}
    # the thesis prints A_IPie's z as 0; the exact value is -0.0302 (kokone-thesis.md §2.6)
    for frame, p in printed.items():
        M = kokone.frame_placement(q, frame)
        assert np.allclose(M.translation / CM, p, atol=1e-4), frame
        assert np.allclose(M.rotation, np.eye(3), atol=1e-12)  # flat: foot R = hip R
    # the thesis's own matrices (an independent product of eq. 4.15) agree with our URDF
    for frame, th, right_leg in (("r_sole", right, True), ("l_sole", left, False)):
        A = thesis_foot(th, right_leg, hip=(0, 0, 20.8))
        M = kokone.frame_placement(q, frame)
        assert np.allclose(A[:3, 3], M.translation / CM, atol=1e-9)
        assert np.allclose(A[:3, :3], M.rotation @ FOOT_R, atol=1e-12)


def test_named_poses(kokone):
    crouch = kokone.configuration("stand")
    assert kokone.stand_pose == "crouch"
    assert kokone.frame_placement(crouch, "torso").translation[2] == pytest.approx(0.208)
    for s in ("l_sole", "r_sole"):
        M = kokone.frame_placement(crouch, s)
        assert np.allclose(M.rotation, np.eye(3), atol=1e-12) and abs(M.translation[2]) < 1e-12
    hip = kokone.frame_placement(crouch, "torso").translation
    assert np.allclose(
        kokone.frame_placement(crouch, "l_sole").translation[:2], hip[:2] + [0, 0.0225]
    )
    assert kokone.within_limits(crouch)
    ex3 = kokone.configuration("example3")
    r = (
        kokone.frame_placement(ex3, "r_sole").translation
        - kokone.frame_placement(ex3, "l_sole").translation
    )
    assert r / CM == pytest.approx([2.1511, -4.5, 1.0799 + 0.0302], abs=1e-4)


# ---------------------------------------------------------------------- Example 4 (IK)
# Fig. 4.9's labels (deg); Table 4.6 prints Table 4.2 with theta_d5 negated instead
FIG_4_9 = {"r": (90, 90, 135, -28, -16, 0), "l": (90, 90, 79, -9, 21, 0)}
TABLE_4_6 = {"r": (90, 90, 134, -64, -20, 0), "l": (90, 90, 113, -46, 23, 0)}


def example_4_targets():
    T = lambda x, y, z: pin.SE3(np.eye(3), np.array([x, y, z]) * CM)  # noqa: E731
    return {"torso": T(1, 0, 21.3), "r_sole": T(7, -2.25, 1.5), "l_sole": T(-2.3, 2.25, 0)}


def planar_leg(hip_x, hip_z, foot_x, foot_z):
    """Closed-form sagittal leg with a flat foot (an independent oracle): hip pitch axis 4.3
    below the hip, ankle pitch axis 5.3 above the sole, thigh = shank = 6.1; DH angles."""
    dx, dz = foot_x - hip_x, (foot_z + 5.3) - (hip_z - 4.3)
    r = math.hypot(dx, dz)
    knee = math.acos((r * r - 2 * 6.1**2) / (2 * 6.1**2))  # flexion, >= 0
    lean = math.atan2(dx, -dz)  # hip->ankle line, forward positive
    hip = lean + knee / 2  # thigh forward of the line by half the flexion
    return (90, 90, 90 + math.degrees(hip), -math.degrees(knee), math.degrees(knee - hip), 0)


def test_example_4_inverse_kinematics(kokone, gen):
    targets = example_4_targets()
    ik = StanceIK(kokone)
    res = ik.solve(targets, kokone.configuration("stand"))
    assert res.converged
    assert ik.residual(res.q, targets) < 1e-9  # metres and radians
    assert kokone.within_limits(res.q)
    got = {
        p: gen.q_to_dh([res.q[kokone.q_index(f"{p}_{n}")] for n in gen.LEG_JOINTS]) for p in "rl"
    }
    # the answer is Fig. 4.9's (its labels are whole degrees) ...
    for p in "rl":
        assert np.allclose(got[p], FIG_4_9[p], atol=1.0), (p, got[p])
    # ... and the closed-form planar leg's, to 1e-6 degrees
    assert np.allclose(got["r"], planar_leg(1, 21.3, 7, 1.5), atol=1e-6)
    assert np.allclose(got["l"], planar_leg(1, 21.3, -2.3, 0), atol=1e-6)


def test_table_4_6_is_wrong():
    """The printed Table 4.6 does not reach Example 4's targets (it is Table 4.2 with the
    sign of theta_d5 flipped): the right foot lands 7.37 cm from its target and tilted 40°,
    the left one 3.33 cm from its target."""
    targets = example_4_targets()
    hip = (1.0, 0.0, 21.3)
    for p, frame, right, miss in (("r", "r_sole", True, 7.37), ("l", "l_sole", False, 3.33)):
        table = thesis_foot(TABLE_4_6[p], right, hip)
        fig = thesis_foot(FIG_4_9[p], right, hip)
        goal = targets[frame].translation / CM
        assert np.linalg.norm(table[:3, 3] - goal) == pytest.approx(miss, abs=0.005)  # cm
        assert np.linalg.norm(fig[:3, 3] - goal) < 0.25  # the figure's whole degrees: close
    tilt = math.degrees(
        math.acos((np.trace(FOOT_R.T @ thesis_foot(TABLE_4_6["r"], True, hip)[:3, :3]) - 1) / 2)
    )
    assert tilt == pytest.approx(40.0, abs=0.01)


# ---------------------------------------------------------------------- SSC-32 map
def test_ssc32_map_covers_every_joint_inside_the_pulse_range(kokone):
    m = Ssc32Map.from_file(KOKONE / "ssc32.toml", kokone.joint_names)
    assert m.baudrate == 115200
    codec = m.codec()
    # 0.075 deg per µs (thesis §4.6.2)
    assert np.allclose(np.abs(codec.scale), 180 / math.pi / 0.075, rtol=1e-6)
    for q in (kokone.q_min, kokone.q_max):
        p = codec.encode_float(q)
        assert np.all(p >= PULSE_MIN - 1e-6) and np.all(p <= PULSE_MAX + 1e-6)
    assert len(set(m.channel_numbers)) == 22
    assert m.range_warnings(kokone.q_min, kokone.q_max) == []
    # a knee centred at 1500 µs would lose 30° of its 0..90° (1500 + 1200 > 2500): said so
    knee = [c.joint for c in m.channels].index("r_knee")
    chans = list(m.channels)
    chans[knee] = Ssc32Channel("r_knee", chans[knee].channel, 1, 1500.0)
    (w,) = Ssc32Map(chans, "test").range_warnings(kokone.q_min, kokone.q_max)
    assert "r_knee (channel 3) limits map to 1500..2700 µs" in w


def test_ssc32_map_us_per_rad_and_bad_keys(tmp_path):
    f = tmp_path / "m.toml"
    f.write_text("[joints]\na = { channel = 1, us_per_rad = 600.0 }\n")
    m = Ssc32Map.from_file(f, ["a"])
    assert m.channels[0].us_per_deg == pytest.approx(600 * math.pi / 180)
    f.write_text("[joints]\na = { channel = 1, us_per_rad = 600.0, us_per_deg = 10 }\n")
    with pytest.raises(ServoMapError, match="us_per_deg or us_per_rad, not both"):
        Ssc32Map.from_file(f, ["a"])
    f.write_text("[bus]\nbaudrate = 1000000\n[joints]\na = { channel = 1 }\n")
    with pytest.raises(ServoMapError, match=r"\[bus\] baudrate 1000000 not in"):
        Ssc32Map.from_file(f, ["a"])


# ---------------------------------------------------------------------- walking and SSC-32
@pytest.fixture(scope="module")
def short_walk(kokone, tmp_path_factory):
    """Kokone's key-pose walk (crouch, CoM over the right foot, left half step) at 0.4 s per
    pose, tracked by the kinematic benchmark's strict hierarchy (``walk_strict``), saved as a
    recording."""
    from wbc.bench.trajectories import robot_options
    from wbc.stacks import load_stack
    from wbc.walking.keyposes import KeyPoseParams, keypose_walk
    from wbc.walking.loop import StackController, run
    from wbc.walking.reference import StandingState

    kw = robot_options(kokone, "keyposes")
    start = StandingState.from_robot(kokone, kokone.configuration("stand"))
    params = KeyPoseParams(n_cycles=0, pose_time=0.4, dt=0.02)
    ref = keypose_walk(start, params, kw["foot"], kw["legs"], min_clearance=0.004)
    rec = run(StackController(load_stack("walk_strict", kokone)), kokone, ref)
    path = tmp_path_factory.mktemp("kokone") / "keyposes.npz"
    rec.save(path)
    return ref, rec, str(path)


def test_keypose_walk_is_statically_stable_and_tracked(kokone, short_walk):
    ref, rec, _ = short_walk
    assert ref.gait == "static" and len(ref.meta["key_poses"]) == 4
    assert ref.com_margin().min() >= 0.005 - 1e-9  # CoM >= 5 mm inside the support polygon
    # the lifted sole is the left one, 1.2 cm up at pose 3, down half a stride ahead at pose 4
    assert ref.meta["key_poses"][2]["lifted"] == "left"
    assert ref.meta["key_poses"][3]["left"] == pytest.approx([0.02, 0.0225, 0.0], abs=1e-12)
    assert np.max(np.abs(rec["com"] - ref.com)) < 1e-4  # tracked to 0.1 mm
    q = rec.q[:, 7:]
    assert np.all(q >= kokone.q_min - 1e-9) and np.all(q <= kokone.q_max + 1e-9)


def _deploy(argv):
    import argparse

    from wbc.cli import deploy as deploy_cmd

    parser = argparse.ArgumentParser()
    deploy_cmd.add_arguments(parser)
    return deploy_cmd.run(parser.parse_args(argv))


def test_kokone_walk_on_the_ssc32_emulator(kokone, short_walk, capsys, device_time, paced_clock):
    """``wbc deploy --robot kokone --bus ssc32``: the robot folder's map, every pulse inside
    500..2500 µs and inside the joint limits, one group move per tick with T = the tick, the
    per-tick step within the servo speed; the safety layer lists what it cannot check. The
    board's 50 ms reply deadline and the 3-failure streak are the production defaults, on the
    emulator's device time, the ticks on a paced clock (tests/conftest.py): its process starved
    by a loaded machine is no dead board, and a stalled host skips no tick."""
    from wbc.servos.emulator import Ssc32Emulator

    _, _, recording = short_walk
    rate = 50
    with device_time.watch(Ssc32Emulator(process=True)) as board:
        rc = _deploy(
            [recording, "--robot", "kokone", "--bus", "ssc32", "--port", board.port,
             "--rate", str(rate)]
        )  # fmt: skip
    out, err = capsys.readouterr()
    assert rc == 0, out + err
    for what in ("positions cannot be read", "cannot check that a servo is connected"):
        assert what in out
    m = Ssc32Map.from_file(KOKONE / "ssc32.toml", kokone.joint_names)
    codec = m.codec()
    moves = [ln for ln in board.lines if ln.startswith(b"#")]
    # start pose + 1.2 s at 50 Hz; a tick the loaded machine ran late is skipped, never sent
    # in a burst, and the deployment reports it: every slot is either sent or reported skipped
    skipped = re.search(r"\((\d+) ticks skipped, never caught up\)", out)
    assert skipped is not None, out
    missed = int(skipped.group(1))
    assert missed <= 10, out  # a few late ticks, not a loop that cannot keep its rate
    assert len(moves) + missed >= 1 + 60
    tick_ms = 1000 // rate
    assert all(ln.endswith(f"T{tick_ms}".encode()) for ln in moves)  # T = one tick
    by_channel = {c.channel: i for i, c in enumerate(m.channels)}
    pulses: dict[int, list] = {}
    for p in board.pulses:
        assert p.move_ms == tick_ms
        pulses.setdefault(p.channel, []).append((p.time, p.pulse))
    assert set(pulses) == set(by_channel)
    step = np.floor(kokone.v_max / rate * np.abs(codec.scale) + 1e-9)
    for ch, values in pulses.items():
        i = by_channel[ch]
        v = np.array([pw for _, pw in values], dtype=float)
        assert np.all((v >= PULSE_MIN) & (v <= PULSE_MAX))
        q = (v - codec.offset[i]) / codec.scale[i]
        assert np.all(q >= kokone.q_min[i] - 1e-9) and np.all(q <= kokone.q_max[i] + 1e-9)
        assert np.all(np.abs(np.diff(v)) <= step[i])
    # the moves arrive one tick apart (median; a loaded machine delays single ticks)
    times = np.array([t for t, _ in pulses[m.channels[0].channel]])
    assert 0.5 * tick_ms / 1000 <= np.median(np.diff(times)) <= 2.0 * tick_ms / 1000


def test_kokone_dry_run_from_the_command_line(short_walk, capsys):
    _, _, recording = short_walk
    rc = _deploy([recording, "--robot", "kokone", "--bus", "ssc32", "--dry-run"])
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert "on dry-run ssc32" in out and "cannot check" in out and "completed" in err + out


def test_bioloid_closed_form_ik_refuses_kokone_with_a_pointer(kokone):
    from wbc.ik import leg_ik

    with pytest.raises(ModelError, match=r"closed form is the Bioloid's.*StanceIK"):
        leg_ik(kokone, "left", pin.SE3.Identity())


def test_robot_check_accepts_the_kokone_folder():
    """``wbc robot check robots/kokone``: no error; the SSC-32 map is checked in place of a
    Dynamixel servo map."""
    from wbc.robot_folder import check_folder

    findings = check_folder(KOKONE)
    assert not [f for f in findings if f.level == "error"]
    assert any(f.level == "ok" and "ssc32.toml" in f.message for f in findings)
