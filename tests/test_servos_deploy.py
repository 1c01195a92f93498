"""``wbc deploy`` end to end: the real dynamixel-sdk port code against the AX-12A emulator.

Every run checks the emulator's record of goals: inside the URDF limits, within the per-tick
rate limit (from the servo speed), and each injected fault ends in the configured safe stop
with the servo and the reason reported. Bad input is refused before any torque is enabled.
"""

from __future__ import annotations

import argparse
import functools
import os
import signal

import numpy as np
import pytest

from wbc.cli import main as wbc_main
from wbc.recording import Recording
from wbc.servo_map import RAD_PER_TICK
from wbc.servos import deploy as deploy_cmd
from wbc.servos.deploy import CallableSource, DeployConfig, Deployment
from wbc.servos.dynamixel import (
    ADDR_CCW_ANGLE_LIMIT,
    ADDR_CW_ANGLE_LIMIT,
    ADDR_RETURN_DELAY,
    ADDR_TORQUE_ENABLE,
    ERR_ANGLE_LIMIT,
    ERR_INPUT_VOLTAGE,
    ERR_OVERHEATING,
    ERR_OVERLOAD,
    DynamixelBus,
)
from wbc.servos.emulator import AX12Emulator, Fault

RATE = 100.0
# the servos run in their own process, like hardware (no GIL shared with the SDK's busy loop)
Emulator = functools.partial(AX12Emulator, process=True)
# generous USB latency: packet timeouts of 2·50 + 2 ms keep a busy shared 2-core machine from
# producing spurious timeouts (a real FTDI at latency 1 ms would use --latency-ms 1)
LATENCY_MS = 50.0
LATENCY = ["--latency-ms", str(LATENCY_MS)]


# ---------------------------------------------------------------- fixtures and helpers
@pytest.fixture(scope="module")
def walk_ready_ticks(robot):
    sm = robot.servo_map
    return sm.ticks_by_id(sm.pose_ticks("walk_ready"))


def _smooth_motion(robot, duration=1.0, rate=50.0, amplitude=0.15):
    """Walk Ready plus a smooth sway of hips, knees, ankles and arms, zero speed at the ends."""
    q0 = robot.configuration("walk_ready")
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    s = amplitude * np.sin(np.pi * t / duration) ** 2
    names = ["l_hip_pitch", "r_hip_pitch", "l_knee", "r_knee", "l_elbow", "r_shoulder_roll"]
    signs = [-1, -1, 1, 1, 1, -1]
    q = np.tile(q0, (t.size, 1))
    for name, sign in zip(names, signs, strict=True):
        q[:, robot.q_index(name)] += sign * s
    assert all(robot.within_limits(row) for row in q)
    return t, q


@pytest.fixture(scope="module")
def recording(robot, tmp_path_factory):
    t, q = _smooth_motion(robot)
    path = tmp_path_factory.mktemp("deploy") / "sway.npz"
    Recording(t, q, robot.joint_names, meta={"what": "synthetic sway"}).save(path)
    return str(path)


def run_deploy(port, recording, *extra, capsys=None):
    parser = argparse.ArgumentParser()
    deploy_cmd.add_arguments(parser)
    argv = [
        *([recording] if recording else []),
        "--port",
        port,
        "--rate",
        str(RATE),
        *LATENCY,
        *extra,
    ]  # last wins
    rc = deploy_cmd.run(parser.parse_args(argv))
    out, err = capsys.readouterr() if capsys else ("", "")
    return rc, out, err


def max_steps(robot, rate=RATE):
    return np.floor(robot.v_max / rate / RAD_PER_TICK + 1e-9).astype(int)


def assert_goals_safe(emu, robot, initial, rate=RATE):
    """Every goal the servos received: inside the joint limits and within the rate limit."""
    sm = robot.servo_map
    step = max_steps(robot, rate)
    n = 0
    for sid, goals in emu.goals_by_id().items():
        i = sm.index_of_id(sid)
        ticks = np.array([g.tick for g in goals], dtype=float)
        q = sm.signs[i] * (ticks - sm.zero_ticks[i]) * RAD_PER_TICK
        assert np.all(q >= robot.q_min[i] - 1e-9), sid
        assert np.all(q <= robot.q_max[i] + 1e-9), sid
        assert np.all(np.abs(np.diff(np.r_[initial[sid], ticks])) <= step[i]), sid
        assert all(g.accepted for g in goals)
        n += len(goals)
    return n


def torque_enabled_ever(emu) -> bool:
    return any(
        w.address <= ADDR_TORQUE_ENABLE < w.address + len(w.data)
        and w.data[ADDR_TORQUE_ENABLE - w.address] == 1
        for w in emu.writes
    )


# ---------------------------------------------------------------- nominal playback
def test_playback_with_reads_soft_start_and_settings(
    robot, recording, walk_ready_ticks, tmp_path, capsys
):
    start = dict(walk_ready_ticks)
    start[14] += 25  # l_knee and r_elbow away from the first pose: soft start needed
    start[5] -= 20
    log = tmp_path / "log.npz"
    with Emulator(positions=start) as emu:
        rc, out, err = run_deploy(emu.port, recording, "--read", "--log", str(log), capsys=capsys)
    assert rc == 0, err
    assert emu.error is None
    n_goals = assert_goals_safe(emu, robot, start)
    # start-up settings: angle limits from the joint limits, return delay 0, torque on
    lim = DynamixelBus("x", robot.servo_map)
    lo, hi = lim.codec.safe_range(robot.q_min, robot.q_max, robot.joint_names)
    for i, sid in enumerate(robot.servo_map.ids):
        s = emu.servo(int(sid))
        assert (s.word(ADDR_CW_ANGLE_LIMIT), s.word(ADDR_CCW_ANGLE_LIMIT)) == (lo[i], hi[i])
        assert s.table[ADDR_RETURN_DELAY] == 0
        assert s.table[ADDR_TORQUE_ENABLE] == 1  # --at-end hold
    assert "completed: soft start 25 ticks" in out
    assert "achieved" in out and "jitter" in out and "tracking error" in out
    assert "no goal was clamped" in out
    # one start goal + 25 soft-start ticks + 101 playback ticks, 18 servos each
    assert n_goals == 18 * (1 + 25 + 101)
    # never faster than the rate (a slow, loaded machine may be slower: see the benchmark)
    times = np.array(emu.sync_goal_times)
    assert (times.size - 2) / (times[-1] - times[1]) < RATE * 1.01, out
    # the soft start moved at the soft speed (0.5 rad/s -> 1 tick per tick at 100 Hz)
    knee = [g.tick for g in emu.goals_by_id()[14]][:27]
    assert np.all(np.abs(np.diff(knee)) <= 1)
    # the last goals are the recording's last pose
    last = {g.servo_id: g.tick for g in emu.goals}
    assert [last[int(i)] for i in robot.servo_map.ids] == list(
        robot.servo_map.pose_ticks("walk_ready")
    )
    data = np.load(log)
    assert data["goal"].shape == (25 + 101, 18)
    # present positions logged (a reply may be lost on a loaded machine: the watchdog
    # tolerates up to 2 in a row, so the log can hold a rare NaN)
    assert np.isfinite(data["present"]).mean() > 0.95


def test_write_only_playback_at_50_hz_ends_with_torque_off(
    robot, recording, walk_ready_ticks, capsys
):
    with Emulator(positions=walk_ready_ticks) as emu:
        parser = argparse.ArgumentParser()
        deploy_cmd.add_arguments(parser)
        args = parser.parse_args(
            [recording, "--port", emu.port, "--rate", "50", *LATENCY, "--at-end", "torque-off"]
        )
        assert deploy_cmd.run(args) == 0
    assert_goals_safe(emu, robot, walk_ready_ticks, rate=50.0)
    assert emu.sync_goal_writes == 1 + 51
    assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in emu.servos.values())
    assert "completed" in capsys.readouterr().out


# ---------------------------------------------------------------- faults -> safe stop
FAULTS = [
    # fault, --on-fault, extra args, expected text
    (
        Fault("timeout", 7, after_goals=15),
        "hold",
        [],
        "id 7 (r_hip_yaw): 3 consecutive failed exchanges (timeout)",
    ),
    (
        Fault("bad_checksum", 12, after_goals=15),
        "torque-off",
        [],
        "id 12 (l_hip_pitch): 3 consecutive failed exchanges (corrupt)",
    ),
    (
        Fault("error_bits", 3, after_goals=15, bits=ERR_OVERLOAD),
        "hold",
        [],
        "id 3 (r_shoulder_roll): error bits 0x20 (overload)",
    ),
    (
        Fault("error_bits", 14, after_goals=15, bits=ERR_OVERHEATING),
        "torque-off",
        [],
        "id 14 (l_knee): error bits 0x04 (overheating); 75 degC",
    ),
    (
        Fault("error_bits", 9, after_goals=15, bits=ERR_INPUT_VOLTAGE),
        "hold",
        [],
        "id 9 (r_hip_roll): error bits 0x01 (input_voltage)",
    ),
    (
        Fault("error_bits", 16, after_goals=15, bits=ERR_ANGLE_LIMIT),
        "torque-off",
        ["--read"],
        "id 16 (l_ankle_pitch): error bits 0x02 (angle_limit)",
    ),
    (
        Fault("missing", 10, after_goals=15),
        "torque-off",
        ["--read"],
        "id 10 (l_hip_roll): 3 consecutive failed exchanges (timeout): servo missing",
    ),
    (
        Fault("garbage", 5, after_goals=15, data=b"\xff\xff\x05\x04\x00"),
        "hold",
        ["--read"],
        "id 5 (r_elbow): 3 consecutive failed exchanges (corrupt)",
    ),
]


@pytest.mark.parametrize(
    ("fault", "on_fault", "extra", "expected"),
    FAULTS,
    ids=[f"{f.kind}-{f.servo_id}" for f, *_ in FAULTS],
)
def test_fault_ends_in_the_safe_stop(
    robot, recording, walk_ready_ticks, capsys, fault, on_fault, extra, expected
):
    with Emulator(positions=walk_ready_ticks, faults=[fault]) as emu:
        rc, _, err = run_deploy(emu.port, recording, "--on-fault", on_fault, *extra, capsys=capsys)
    assert emu.error is None
    assert rc == deploy_cmd.EXIT_SAFE_STOP
    assert f"SAFE STOP ({on_fault}): {expected}" in err
    assert_goals_safe(emu, robot, walk_ready_ticks)
    # motion stopped soon after the fault: within one polling round (18 ticks) + 3 tries
    assert fault.after_goals <= emu.sync_goal_writes <= fault.after_goals + 18 + 3
    others = [s for sid, s in emu.servos.items() if sid != fault.servo_id]
    if on_fault == "torque-off":
        assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in others)
    else:
        assert all(s.table[ADDR_TORQUE_ENABLE] == 1 for s in others)


def test_transient_faults_are_tolerated(robot, recording, walk_ready_ticks, capsys):
    faults = [
        Fault("timeout", 7, after_goals=20, count=2),  # 2 < 3 consecutive
        Fault("bad_checksum", 8, after_goals=40, count=1),
        Fault("garbage", 4, after_goals=10, data=b"\x00\x13\x37"),  # no header: skipped
    ]
    with Emulator(positions=walk_ready_ticks, faults=faults) as emu:
        rc, _, err = run_deploy(emu.port, recording, "--read", capsys=capsys)
    assert rc == 0, err
    assert_goals_safe(emu, robot, walk_ready_ticks)
    assert {f.kind for _, f, _ in emu.fault_log} == {"timeout", "bad_checksum", "garbage"}


def test_ctrl_c_ends_in_the_safe_stop(robot, recording, walk_ready_ticks, capsys):
    """A real SIGINT to this process, sent by the servos' process at the 20th goal write."""
    me = os.getpid()
    press = {20: lambda: os.kill(me, signal.SIGINT)}
    with Emulator(positions=walk_ready_ticks, on_goal_write=press) as emu:
        rc, _, err = run_deploy(
            emu.port, recording, "--read", "--on-fault", "torque-off", capsys=capsys
        )
    assert rc == deploy_cmd.EXIT_INTERRUPTED, err
    assert "SAFE STOP (torque-off): operator: interrupted (Ctrl-C)" in err
    assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in emu.servos.values())
    assert_goals_safe(emu, robot, walk_ready_ticks)
    assert 20 <= emu.sync_goal_writes <= 21  # stopped at the next tick boundary


# ---------------------------------------------------------------- a live source
def test_live_source_is_clamped_and_rate_limited(robot, walk_ready_ticks):
    q0 = robot.configuration("walk_ready")[7:]
    j = robot.joint_index("r_knee")

    def wild(tick, t):
        if tick >= 60:
            return None
        q = q0.copy()  # 0.3 rad beyond the upper limit, then beyond the lower one
        q[j] = robot.q_max[j] + 0.3 if tick < 20 else robot.q_min[j] - 0.3
        return q

    lines = []
    with Emulator(positions=walk_ready_ticks) as emu:
        bus = DynamixelBus(emu.port, robot.servo_map, latency_timer_ms=LATENCY_MS)
        source = CallableSource(wild, q0, robot.joint_names)
        result = Deployment(bus, source, robot, DeployConfig(rate=RATE), lines.append).run()
    assert result.completed
    assert_goals_safe(emu, robot, walk_ready_ticks)
    knee = np.array([g.tick for g in emu.goals_by_id()[13]])
    assert result.limits.clamped[j] == 60 and result.limits.clamped.sum() == 60
    assert result.limits.worst_excess[j] == pytest.approx(0.3)
    assert result.limits.rate_limited[j] > 0
    lo, hi = bus.cmd_lo[j], bus.cmd_hi[j]
    assert knee.min() == lo and knee.max() == hi  # reached both limits, never beyond


def test_nan_from_a_live_source_ends_in_the_safe_stop(robot, walk_ready_ticks):
    q0 = robot.configuration("walk_ready")[7:]

    def broken(tick, t):
        q = q0.copy()
        if tick == 10:
            q[robot.joint_index("l_ankle_roll")] = np.nan
        return q

    with Emulator(positions=walk_ready_ticks) as emu:
        bus = DynamixelBus(emu.port, robot.servo_map, latency_timer_ms=LATENCY_MS)
        source = CallableSource(broken, q0, robot.joint_names)
        result = Deployment(
            bus, source, robot, DeployConfig(rate=RATE, on_fault="torque-off"), lambda s: None
        ).run()
    assert not result.completed and result.stop_action == "torque-off"
    assert "bad target at tick 10" in result.trip.reason
    assert "l_ankle_roll" in result.trip.reason
    assert emu.sync_goal_writes == 1 + 10  # the start goals, then ticks 0..9
    assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in emu.servos.values())


# ---------------------------------------------------------------- refused before torque
def _refused(emu, rc, err, text):
    assert rc == deploy_cmd.EXIT_REFUSED
    assert "refused before any torque was enabled" in err
    assert text in err
    if emu is not None:
        assert not torque_enabled_ever(emu)
        assert emu.goals == []


def test_unknown_port_is_refused(recording, capsys):
    rc, _, err = run_deploy("/dev/ttyNOPE0", recording, capsys=capsys)
    _refused(None, rc, err, "unknown port '/dev/ttyNOPE0'")


def test_wrong_baud_is_refused(recording, walk_ready_ticks, capsys):
    with Emulator(positions=walk_ready_ticks) as emu:  # servos at 1 Mbps
        rc, _, err = run_deploy(
            emu.port, recording, "--baud", "57600", "--latency-ms", "1", capsys=capsys
        )
    _refused(emu, rc, err, "no servo answered")
    assert "at 57600 baud (the servo map says 1000000)" in err
    rc, _, err = run_deploy("/dev/null", recording, "--baud", "300000", capsys=capsys)
    _refused(None, rc, err, "300000 is not an AX-12A rate")


def test_missing_servo_at_start_is_refused(recording, walk_ready_ticks, capsys):
    with Emulator(positions=walk_ready_ticks, faults=[Fault("missing", 13)]) as emu:
        rc, _, err = run_deploy(emu.port, recording, capsys=capsys)
    _refused(emu, rc, err, "no reply to PING from id 13 (r_knee)")


def test_duplicate_id_on_the_bus_is_refused(recording, walk_ready_ticks, capsys):
    with Emulator(positions=walk_ready_ticks, duplicate_ids=[11]) as emu:
        rc, _, err = run_deploy(emu.port, recording, capsys=capsys)
    _refused(emu, rc, err, "garbled reply to PING from id 11 (r_hip_pitch)")


def test_servo_outside_its_limits_at_start_is_refused(recording, walk_ready_ticks, capsys):
    start = dict(walk_ready_ticks)
    start[14] = 400  # l_knee limits are 512..953 ticks
    with Emulator(positions=start) as emu:
        rc, _, err = run_deploy(emu.port, recording, capsys=capsys)
    _refused(emu, rc, err, "id 14 (l_knee) at 400 ticks, limits 512..953")


def _write_map(path, robot, edit):
    text = (robot.urdf_path.parent / "servos.toml").read_text()
    path.write_text(edit(text))
    return str(path)


def test_inconsistent_servo_maps_are_refused(robot, recording, tmp_path, capsys):
    missing = _write_map(
        tmp_path / "a.toml", robot, lambda s: s.replace("r_elbow          = { id = 5,", "# ")
    )
    rc, _, err = run_deploy("/dev/null", recording, "--servo-map", missing, capsys=capsys)
    _refused(None, rc, err, "missing joints ['r_elbow']")
    dup = _write_map(tmp_path / "b.toml", robot, lambda s: s.replace("id = 5,", "id = 7,"))
    rc, _, err = run_deploy("/dev/null", recording, "--servo-map", dup, capsys=capsys)
    _refused(None, rc, err, "duplicate servo id 7")
    flipped = _write_map(
        tmp_path / "c.toml",
        robot,
        lambda s: s.replace("{ id = 14, sign = 1,", "{ id = 14, sign = -1,"),
    )
    rc, _, err = run_deploy("/dev/null", recording, "--servo-map", flipped, capsys=capsys)
    _refused(None, rc, err, "pose 'walk_ready' puts l_knee (id 14) at -1.3871 rad")


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (np.nan, "tick 7 (t = 0.140 s): joint l_knee is nan"),
        (3.0, "tick 7 (t = 0.140 s): joint l_knee = 3.0000 rad is above its upper limit"),
    ],
)
def test_bad_trajectories_are_refused(robot, walk_ready_ticks, tmp_path, capsys, value, text):
    t, q = _smooth_motion(robot)
    q[7, robot.q_index("l_knee")] = value
    path = tmp_path / "bad.npz"
    Recording(t, q, robot.joint_names).save(path)
    with Emulator(positions=walk_ready_ticks) as emu:
        rc, _, err = run_deploy(emu.port, str(path), capsys=capsys)
    _refused(emu, rc, err, text)
    assert emu.packets == 0  # refused before the port was even opened


# ---------------------------------------------------------------- dry run and plan
def test_dry_run_needs_no_port(recording, capsys):
    rc = wbc_main(["deploy", recording, "--dry-run", "--rate", "100"])
    out = capsys.readouterr().out
    assert rc == 0
    assert "on dry-run" in out and "completed" in out and "achieved" in out


def test_plan_prints_the_bus_budget(capsys):
    assert wbc_main(["deploy", "--plan"]) == 0
    out = capsys.readouterr().out
    assert "1 x SYNC_WRITE goal position: 62 B = 0.620 ms each" in out
    assert "18 x READ present position (2 B): 16 B = 0.160 ms each" in out
    rates = [float(x.split()[0]) for x in out.split("= max ")[1:]]
    write_wire, write_usb, read_wire, read_usb = rates
    assert write_wire > read_wire and write_usb > read_usb
    assert read_usb == pytest.approx(1 / (350e-5 + 18 * 22e-6 + 18e-3), rel=0.01)
    assert write_wire == pytest.approx(1 / (84e-5 + 22e-6), rel=0.01)


# ---------------------------------------------------------------- live controller
def test_live_controller_plays_through_the_safety_layer(robot, walk_ready_ticks, capsys):
    """`wbc deploy --live walk`: the walk stack solved tick by tick, goals sent to the bus."""
    with Emulator(positions=walk_ready_ticks) as emu:
        rc, out, err = run_deploy(
            emu.port, None, "--live", "walk", "--trajectory", "thesis_step", capsys=capsys
        )
    assert rc == 0, err
    assert "live walk on thesis_step" in out
    n_goals = assert_goals_safe(emu, robot, walk_ready_ticks)
    assert n_goals >= 18 * 250  # the 3 s step at 100 Hz, every servo
