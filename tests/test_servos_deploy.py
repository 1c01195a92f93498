"""``wbc deploy`` end to end: the real dynamixel-sdk port code against the AX-12A emulator.

Every run checks the emulator's record of goals: inside the URDF limits, never faster than the
servo speed over the time the goals were received, and each injected fault ends in the
configured safe stop with the servo and the reason reported. Bad input is refused before any
torque is enabled. The fault bound (fault -> last motion goal <= 100 ms at 50 Hz) is in
tests/test_servos_faults.py.
"""

from __future__ import annotations

import argparse
import math
import os
import signal

import numpy as np
import pytest

from wbc.cli import deploy as deploy_cmd
from wbc.cli import main as wbc_main
from wbc.recording import Recording
from wbc.servo_map import RAD_PER_TICK
from wbc.servos import CallableSource, DeployConfig, Deployment
from wbc.servos.dynamixel import DynamixelBus
from wbc.servos.emulator import AX12Emulator, Fault
from wbc.servos.protocol1 import (
    ADDR_CCW_ANGLE_LIMIT,
    ADDR_CW_ANGLE_LIMIT,
    ADDR_PUNCH,
    ADDR_RETURN_DELAY,
    ADDR_SHUTDOWN,
    ADDR_TORQUE_ENABLE,
    ADDR_TORQUE_LIMIT,
    AX12_MAX_SPEED,
    ERR_ANGLE_LIMIT,
    ERR_INPUT_VOLTAGE,
    ERR_OVERHEATING,
    ERR_OVERLOAD,
)
from wbc.servos.safety import HealthSchedule

# reply deadlines on the emulator's device clock and ticks on a paced clock (tests/conftest.py):
# a stall of the servos' process on a loaded machine is no timeout, and a stalled host plays
# every tick later instead of skipping it, so the watchdog runs with its production streak (3
# failures in a row) and a fault after N goal writes is always reached
pytestmark = pytest.mark.usefixtures("device_time", "paced_clock")

RATE = 100.0
# reply deadline: the emulator answers in well under 1 ms of device time (a real FTDI at
# latency 1 ms: 4.1 ms)
TIMEOUT_MS = 15.0
LATENCY = ["--reply-timeout-ms", str(TIMEOUT_MS)]
# emulator timestamps are taken when its process reads the packet: a stall of that process
# (seen: 7 ms on this shared machine) delays a stamp; goal speeds checked on those stamps
# allow one 50 Hz tick. A catch-up burst (goals 1.7 ms apart, each a full step) exceeds it
# within a few packets; the host's own send times are checked without it (--log).
STAMP_JITTER_S = 0.02


# ---------------------------------------------------------------- fixtures and helpers
@pytest.fixture()
def emulator(device_time):
    """``emulator(**options)``: an AX-12A bus emulator in its own process, like hardware (no
    GIL shared with the host), watched by the test's device clock (tests/conftest.py)."""
    return lambda **options: device_time.watch(AX12Emulator(process=True, **options))


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


def speeds(robot):
    """The servo speed of each joint in ticks/s (the limiter's)."""
    return np.minimum(robot.v_max, AX12_MAX_SPEED) / RAD_PER_TICK


def assert_speed_law(times, ticks, speed, jitter=0.0):
    """Between any two goals: |tick_b - tick_a| <= speed · (t_b - t_a + jitter) + 1 (the
    limiter's law; one tick is the command quantum). Checked on all pairs, so a burst of
    catch-up packets fails it."""
    t = np.asarray(times)
    c = np.asarray(ticks, dtype=float)
    dist = np.abs(c[None, :] - c[:, None])
    dt = np.abs(t[None, :] - t[:, None])
    excess = dist - (speed * (dt + jitter) + 1 + 1e-9)
    a, b = np.unravel_index(np.argmax(excess), excess.shape)
    assert excess[a, b] <= 0, f"goals {a}, {b}: {dist[a, b]:.0f} ticks in {dt[a, b] * 1e3:.2f} ms"


def assert_goals_safe(emu, robot, initial, speed=None, speed_law=True):
    """Every goal the servos received: inside the joint limits, accepted, and never faster
    than the joint's speed (ticks/s) on the emulator's own receive times."""
    sm = robot.servo_map
    speed = speeds(robot) if speed is None else np.broadcast_to(speed, (robot.n_joints,))
    n = 0
    for sid, goals in emu.goals_by_id().items():
        i = sm.index_of_id(sid)
        ticks = np.array([g.tick for g in goals], dtype=float)
        q = sm.signs[i] * (ticks - sm.zero_ticks[i]) * RAD_PER_TICK
        assert np.all(q >= robot.q_min[i] - 1e-9), sid
        assert np.all(q <= robot.q_max[i] + 1e-9), sid
        if speed_law:
            assert_speed_law([g.time for g in goals], ticks, speed[i], STAMP_JITTER_S)
        if ticks.size:  # the first goal is the present position (read at start-up)
            assert abs(ticks[0] - initial[sid]) <= 1, sid
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
    emulator, robot, recording, walk_ready_ticks, tmp_path, capsys
):
    start = dict(walk_ready_ticks)
    start[14] += 25  # l_knee and r_elbow away from the first pose: soft start needed
    start[5] -= 20
    log = tmp_path / "log.npz"
    with emulator(positions=start) as emu:
        rc, out, err = run_deploy(emu.port, recording, "--read", "--log", str(log), capsys=capsys)
    assert rc == 0, err
    assert emu.error is None
    n_goals = assert_goals_safe(emu, robot, start)
    # start-up settings: angle limits from the joint limits, return delay 0, and the servo
    # map's [settings] (the config the simulator reads): alarm shutdown, compliance, punch,
    # torque limit; torque on
    sm = robot.servo_map
    st = sm.settings
    lim = DynamixelBus("x", sm)
    lo, hi = lim.codec.safe_range(robot.q_min, robot.q_max, robot.joint_names)
    assert len(set(st.compliance_slope)) > 1  # per-joint values, not one constant
    for i, sid in enumerate(sm.ids):
        s = emu.servo(int(sid))
        assert (s.word(ADDR_CW_ANGLE_LIMIT), s.word(ADDR_CCW_ANGLE_LIMIT)) == (lo[i], hi[i])
        assert s.table[ADDR_RETURN_DELAY] == 0
        assert s.table[ADDR_SHUTDOWN] == st.alarm_shutdown
        assert list(s.table[26:30]) == [st.compliance_margin[i]] * 2 + [st.compliance_slope[i]] * 2
        assert s.word(ADDR_PUNCH) == st.punch[i]
        assert s.word(ADDR_TORQUE_LIMIT) == st.torque_limit[i]
        assert s.table[ADDR_TORQUE_ENABLE] == 1  # --at-end hold
    assert "completed: soft start" in out
    assert "adapter round trip (PING, 18 replies)" in out
    assert "bus round trips:" in out
    assert "achieved" in out and "jitter" in out and "tracking error" in out
    assert "no goal was clamped" in out
    data = np.load(log)
    phase = data["phase"]
    soft, play = int(np.sum(phase == 0)), int(np.sum(phase == 1))
    assert f"completed: soft start {soft} ticks" in out
    # the soft start at 0.5 rad/s = 97.7 ticks/s: the knee's 25 ticks take at least 0.235 s
    # (24 ticks after the first soft goal, which may already carry one)
    t_soft = data["t"][phase == 0]
    assert t_soft[-1] - t_soft[0] >= 23 / (0.5 / RAD_PER_TICK)
    # one start goal + soft start + playback (101 slots at 100 Hz, minus any skipped), 18 each
    skipped = int(out.split("ticks skipped")[0].rsplit("(", 1)[1])
    assert play <= 101 <= play + skipped  # a skip may jump past the end
    assert n_goals == 18 * (1 + soft + play)
    # never faster than the rate (a slow, loaded machine may be slower: see the benchmark)
    times = np.array(emu.sync_goal_times)
    assert (times.size - 2) / (times[-1] - times[1]) < RATE * 1.01, out
    # the host's own log of goal times: the soft start never faster than 0.5 rad/s (+1 tick)
    soft_speed = 0.5 / RAD_PER_TICK
    for j in range(18):
        assert_speed_law(data["t"][phase == 0], data["goal"][phase == 0, j], soft_speed)
        assert_speed_law(data["t"], data["goal"][:, j], speeds(robot)[j])
    # the last goals are the recording's last pose
    last = {g.servo_id: g.tick for g in emu.goals}
    assert [last[int(i)] for i in sm.ids] == list(sm.pose_ticks("walk_ready"))
    assert data["goal"].shape == (soft + play, 18)
    # present positions logged (a reply may be lost on a loaded machine: the watchdog
    # tolerates up to 2 in a row, so the log can hold a rare NaN)
    assert np.isfinite(data["present"]).mean() > 0.95
    assert data["rtt"].size >= 18 * play


def test_write_only_playback_at_50_hz_ends_with_torque_off(
    emulator, robot, recording, walk_ready_ticks, capsys
):
    with emulator(positions=walk_ready_ticks) as emu:
        parser = argparse.ArgumentParser()
        deploy_cmd.add_arguments(parser)
        args = parser.parse_args(
            [recording, "--port", emu.port, "--rate", "50", *LATENCY, "--at-end", "torque-off"]
        )
        rc = deploy_cmd.run(args)
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert_goals_safe(emu, robot, walk_ready_ticks)
    skipped = int(out.split("ticks skipped")[0].rsplit("(", 1)[1])
    # start goals + 51 slots, none caught up (a skip may jump past the end)
    assert emu.sync_goal_writes - 1 <= 51 <= emu.sync_goal_writes - 1 + skipped
    assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in emu.servos.values())
    assert "completed" in out
    h = HealthSchedule(18, 50.0, max_failures=3)  # the production streak
    assert f"health: {h.polls_per_tick} servos checked per tick" in out


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
    emulator, robot, recording, walk_ready_ticks, capsys, fault, on_fault, extra, expected
):
    # the 15 ms deadline on device time: a stall of the emulator's process (150 ms seen on the
    # 2-core CI machine) is no other servo's false timeout that stops the run first
    with emulator(positions=walk_ready_ticks, faults=[fault]) as emu:
        rc, _, err = run_deploy(emu.port, recording, "--rate", "50", "--on-fault", on_fault,
                                *extra, capsys=capsys)  # fmt: skip
    assert emu.error is None
    assert rc == deploy_cmd.EXIT_SAFE_STOP
    label = expected.split(":")[0]
    if on_fault == "torque-off" and fault.kind != "error_bits":
        # the servo cannot answer: its torque-off is sent (broadcast, then to it) but never
        # confirmed, and the report says so
        assert f"SAFE STOP (torque-off (not confirmed: {label})): {expected}" in err
    else:
        assert f"SAFE STOP ({on_fault}): {expected}" in err
    assert_goals_safe(emu, robot, walk_ready_ticks)
    # motion stopped soon after the fault: at 50 Hz each servo is checked every 2 ticks
    # (--read: every tick) and 3 failed checks trip, so at most 3 more goal writes
    assert fault.after_goals <= emu.sync_goal_writes <= fault.after_goals + 3
    others = [s for sid, s in emu.servos.items() if sid != fault.servo_id]
    if on_fault == "torque-off":
        assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in others)
    else:
        assert all(s.table[ADDR_TORQUE_ENABLE] == 1 for s in others)


def test_transient_faults_are_tolerated(emulator, robot, recording, walk_ready_ticks, capsys):
    # early in the 1 s motion (~100 goal writes at 100 Hz), so that every fault fires even
    # when a loaded machine makes the deployment skip ticks
    faults = [
        Fault("timeout", 7, after_goals=10, count=2),  # 2 < 3 consecutive
        Fault("late", 6, after_goals=15, count=2, delay_s=0.03),  # 2 late, then on time
        Fault("bad_checksum", 8, after_goals=20, count=1),
        Fault("garbage", 4, after_goals=5, count=2, data=b"\x00\x13\x37"),  # 2 < 3 in a row
    ]
    with emulator(positions=walk_ready_ticks, faults=faults) as emu:
        rc, _, err = run_deploy(emu.port, recording, "--read", capsys=capsys)
    assert rc == 0, err
    assert_goals_safe(emu, robot, walk_ready_ticks)
    assert {f.kind for _, f, _ in emu.fault_log} == {"timeout", "bad_checksum", "garbage", "late"}


def test_ctrl_c_ends_in_the_safe_stop(emulator, robot, recording, walk_ready_ticks, capsys):
    """A real SIGINT to this process, sent by the servos' process at the 20th goal write."""
    me = os.getpid()
    press = {20: lambda: os.kill(me, signal.SIGINT)}
    with emulator(positions=walk_ready_ticks, on_goal_write=press) as emu:
        rc, _, err = run_deploy(
            emu.port, recording, "--read", "--on-fault", "torque-off", capsys=capsys
        )
    assert rc == deploy_cmd.EXIT_INTERRUPTED, err
    assert "SAFE STOP (torque-off): operator: interrupted (Ctrl-C)" in err
    assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in emu.servos.values())
    assert_goals_safe(emu, robot, walk_ready_ticks)
    assert 20 <= emu.sync_goal_writes <= 21  # stopped at the next tick boundary


# ---------------------------------------------------------------- a live source
def test_live_source_is_clamped_and_rate_limited(emulator, robot, walk_ready_ticks):
    q0 = robot.configuration("walk_ready")[7:]
    j = robot.joint_index("r_knee")

    def wild(tick, t):
        if tick >= 60:
            return None
        q = q0.copy()  # 0.3 rad beyond the upper limit, then beyond the lower one
        q[j] = robot.q_max[j] + 0.3 if tick < 20 else robot.q_min[j] - 0.3
        return q

    lines = []
    with emulator(positions=walk_ready_ticks) as emu:
        bus = DynamixelBus(emu.port, robot.servo_map, reply_timeout_ms=TIMEOUT_MS)
        source = CallableSource(wild, q0, robot.joint_names)
        result = Deployment(bus, source, robot, DeployConfig(rate=RATE), lines.append).run()
    assert result.completed
    assert_goals_safe(emu, robot, walk_ready_ticks)
    knee = np.array([g.tick for g in emu.goals_by_id()[13]])
    ticks = result.limits.ticks  # 60 slots, minus any the loop skipped
    assert ticks <= 60 <= ticks + result.timing.missed
    assert result.limits.clamped[j] == ticks and result.limits.clamped.sum() == ticks
    assert result.limits.worst_excess[j] == pytest.approx(0.3)
    assert result.limits.rate_limited[j] > 0
    lo, hi = bus.cmd_lo[j], bus.cmd_hi[j]
    assert knee.min() == lo and knee.max() == hi  # reached both limits, never beyond


def test_nan_from_a_live_source_ends_in_the_safe_stop(emulator, robot, walk_ready_ticks):
    q0 = robot.configuration("walk_ready")[7:]

    def broken(tick, t):
        q = q0.copy()
        if tick >= 10:
            q[robot.joint_index("l_ankle_roll")] = np.nan
        return q

    with emulator(positions=walk_ready_ticks) as emu:
        bus = DynamixelBus(emu.port, robot.servo_map, reply_timeout_ms=TIMEOUT_MS)
        source = CallableSource(broken, q0, robot.joint_names)
        result = Deployment(
            bus, source, robot, DeployConfig(rate=RATE, on_fault="torque-off"), lambda s: None
        ).run()
    assert not result.completed and result.stop_action == "torque-off"
    tick = int(result.trip.reason.split("bad target at tick ")[1].split(":")[0])
    assert 10 <= tick <= 10 + result.timing.missed
    assert "l_ankle_roll" in result.trip.reason
    assert emu.sync_goal_writes == 1 + tick - result.timing.missed  # start goals, ticks < tick
    assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in emu.servos.values())


@pytest.mark.parametrize("error", [RuntimeError("solver crashed"), SystemExit(1)])
def test_an_exception_in_the_loop_ends_in_the_safe_stop_with_the_log(
    emulator, robot, walk_ready_ticks, tmp_path, error
):
    """Anything raised in the loop (a crashed live controller, even SystemExit) takes the
    safe stop: torque off verified per servo, the log written, the reason in one line."""
    q0 = robot.configuration("walk_ready")[7:]

    def crashing(tick, t):
        if tick >= 10:
            raise error
        return q0

    log = tmp_path / "log.npz"
    config = DeployConfig(rate=RATE, on_fault="torque-off", log_path=str(log))
    with emulator(positions=walk_ready_ticks) as emu:
        bus = DynamixelBus(emu.port, robot.servo_map, reply_timeout_ms=TIMEOUT_MS)
        source = CallableSource(crashing, q0, robot.joint_names)
        result = Deployment(bus, source, robot, config, lambda s: None).run()
    assert result.stop_action == "torque-off"
    assert str(result.trip) == f"deploy: {type(error).__name__}: {error}"
    assert result.exit_code == deploy_cmd.EXIT_SAFE_STOP
    assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in emu.servos.values())
    assert np.load(log)["goal"].shape[0] == emu.sync_goal_writes - 1


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


def test_wrong_baud_is_refused(emulator, recording, walk_ready_ticks, capsys):
    with emulator(positions=walk_ready_ticks) as emu:  # servos at 1 Mbps
        rc, _, err = run_deploy(
            emu.port, recording, "--baud", "57600", "--latency-ms", "1", capsys=capsys
        )
    _refused(emu, rc, err, "no servo answered")
    assert "at 57600 baud (the servo map says 1000000)" in err
    rc, _, err = run_deploy("/dev/null", recording, "--baud", "300000", capsys=capsys)
    _refused(None, rc, err, "300000 is not an AX-12A rate")


def test_missing_servo_at_start_is_refused(emulator, recording, walk_ready_ticks, capsys):
    with emulator(positions=walk_ready_ticks, faults=[Fault("missing", 13)]) as emu:
        rc, _, err = run_deploy(emu.port, recording, capsys=capsys)
    _refused(emu, rc, err, "no reply to PING from id 13 (r_knee)")


def test_duplicate_id_on_the_bus_is_refused(emulator, recording, walk_ready_ticks, capsys):
    with emulator(positions=walk_ready_ticks, duplicate_ids=[11]) as emu:
        rc, _, err = run_deploy(emu.port, recording, capsys=capsys)
    _refused(emu, rc, err, "garbled reply to PING from id 11 (r_hip_pitch)")


def test_servo_outside_its_limits_at_start_is_refused(
    emulator, recording, walk_ready_ticks, capsys
):
    start = dict(walk_ready_ticks)
    start[14] = 400  # l_knee limits are 512..953 ticks
    with emulator(positions=start) as emu:
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
def test_bad_trajectories_are_refused(
    emulator, robot, walk_ready_ticks, tmp_path, capsys, value, text
):
    t, q = _smooth_motion(robot)
    q[7, robot.q_index("l_knee")] = value
    path = tmp_path / "bad.npz"
    Recording(t, q, robot.joint_names).save(path)
    with emulator(positions=walk_ready_ticks) as emu:
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
    assert wbc_main(["deploy", "--plan"]) == 0  # default 50 Hz
    out = capsys.readouterr().out
    assert "1 x SYNC_WRITE goal position: 62 B = 0.620 ms each" in out
    # health READs of 8 bytes (up to 10 in their varied forms): 8 + 6 + 10 bytes
    assert "10 x READ health poll (8-10 B): 24 B = 0.240 ms each" in out
    assert "18 x READ present position (2-4 B): 18 B = 0.180 ms each" in out
    rates = [float(x.split()[0]) for x in out.split("= max ")[1:]]
    write_wire, write_usb, read_wire, read_usb = rates
    assert write_wire > read_wire and write_usb > read_usb
    read_tick = (62 + 18 * 18) * 10 / 1e6 + 18 * (22e-6 + 1e-3)
    assert read_usb == pytest.approx(1 / read_tick, rel=0.01)
    assert write_wire == pytest.approx(1 / ((62 + 10 * 24) * 1e-5 + 10 * 22e-6), rel=0.01)
    # the schedule and the bound it gives, and the overload at 50 Hz with --read
    assert "every servo checked at least every 2 ticks" in out
    assert "silence or late replies (3 in a row) within 80 ms" in out
    proposed = math.floor(0.8 / read_tick)  # the highest whole rate using <= 80 % of a tick
    assert proposed == 35
    assert "warning: write + read at 50 Hz overloads the bus (111 % > 80 %)" in out
    assert f"propose --rate {proposed}" in out
    assert out.count("warning:") == 1  # write-only fits (66 %)
    assert wbc_main(["deploy", "--plan", "--rate", str(proposed)]) == 0
    assert "warning: write + read" not in capsys.readouterr().out


# ---------------------------------------------------------------- live controller
def test_live_controller_plays_through_the_safety_layer(
    emulator, robot, walk_ready_ticks, tmp_path, capsys
):
    """`wbc deploy --live walk --open-loop`: the walk stack solved tick by tick, goals sent
    to the bus (the closed loop, the default, reads every servo each tick: tests/test_sim_cli
    runs it on the simulated robot)."""
    log = tmp_path / "live.npz"
    with emulator(positions=walk_ready_ticks) as emu:
        rc, out, err = run_deploy(
            emu.port,
            None,
            "--live",
            "walk",
            "--open-loop",
            "--trajectory",
            "thesis_step",
            "--log",
            str(log),
            # the solver runs in this process and can starve the emulator's process for tens
            # of ms (more while numba compiles): no timeout on device time
            capsys=capsys,
        )
    assert rc == 0, err
    assert "live walk on thesis_step" in out
    assert "live solves: 0 of " in out and "held), 0 relaxed" in out  # (every tick counted)
    # the solver runs in this process: its work can starve the emulator's process, whose
    # receive stamps then bunch up; the speed law is checked on the host's send times, and
    # the servos received exactly the goals logged
    n_goals = assert_goals_safe(emu, robot, walk_ready_ticks, speed_law=False)
    data = np.load(log)
    by_id = emu.goals_by_id()
    for j, sid in enumerate(robot.servo_map.ids):
        assert [g.tick for g in by_id[int(sid)]][1:] == list(data["goal"][:, j]), (sid, out)
        assert_speed_law(data["t"], data["goal"][:, j], speeds(robot)[j])
    # the 3 s step at 100 Hz: slots played or skipped (the solver may overrun a 10 ms tick;
    # then the step follows the wall clock, never catching up in a burst)
    skipped = int(out.split("ticks skipped")[0].rsplit("(", 1)[1])
    assert data["goal"].shape[0] + skipped >= 300, out
    assert n_goals == 18 * (1 + data["goal"].shape[0]), out


def test_real_time_priority_where_permitted_and_says_so_when_not(recording, monkeypatch, capsys):
    before = os.sched_getscheduler(0)
    rc, out, _ = run_deploy("", recording, "--dry-run", "--rt-priority", capsys=capsys)
    assert rc == 0
    assert "note: real-time priority: SCHED_FIFO 50" in out or "not permitted" in out
    assert os.sched_getscheduler(0) == before  # restored for the caller

    def refuse(*args):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    rc, out, _ = run_deploy("", recording, "--dry-run", "--rt-priority", "20", capsys=capsys)
    assert rc == 0
    assert "--rt-priority: not permitted (Operation not permitted); running at normal" in out


def _long_recording(robot, path, n):
    t = np.arange(n) * 0.02
    q = np.tile(robot.configuration("walk_ready"), (n, 1))
    j = robot.q_index("l_knee")
    q[:, j] += 0.1 * np.sin(t)  # inside the limits: walk_ready's knee is bent
    Recording(t, q, robot.joint_names).save(path)
    return t, q


def test_playback_streams_long_recordings(robot, tmp_path):
    """The deploy source reads the file a chunk at a time: its peak memory does not grow with
    the recording's length (10 x longer: same peak), and it gives the targets of the
    in-memory source."""
    import tracemalloc

    from wbc.recording import RecordingReader
    from wbc.servos.sources import RecordingSource, StreamedRecordingSource

    peaks = []
    for n in (10_000, 100_000):
        path = tmp_path / f"long{n}.npz"
        _long_recording(robot, path, n)
        tracemalloc.start()
        source = StreamedRecordingSource(RecordingReader(path), robot)
        ticks = 0
        while source(ticks * 25, ticks * 25 * 0.02 + 0.003) is not None:
            ticks += 1
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        assert ticks == n // 25  # played to the end
    assert peaks[1] < 1.5 * peaks[0], peaks  # (the in-memory source: ~10x)
    assert peaks[1] < 8e6
    # the same targets as the in-memory source, across chunk boundaries
    path = tmp_path / "long10000.npz"
    streamed = StreamedRecordingSource(RecordingReader(path, chunk_rows=100), robot)
    whole = RecordingSource(Recording.load(path), robot)
    for k in range(0, 2000, 3):
        assert np.array_equal(streamed(k, k * 0.0137), whole(k, k * 0.0137))
    assert np.array_equal(streamed.first(), whole.first())
    assert streamed.duration == whole.duration


def test_streamed_recording_refuses_a_bad_row_naming_its_tick(robot, tmp_path):
    from wbc.exceptions import TrajectoryError
    from wbc.recording import RecordingReader
    from wbc.servos.sources import StreamedRecordingSource

    t, q = _long_recording(robot, tmp_path / "a.npz", 1000)
    q[777, robot.q_index("r_knee")] = np.nan
    Recording(t, q, robot.joint_names).save(tmp_path / "bad.npz")
    with pytest.raises(TrajectoryError, match=r"tick 777 \(t = 15.540 s\): joint r_knee is nan"):
        StreamedRecordingSource(RecordingReader(tmp_path / "bad.npz", chunk_rows=64), robot)


def test_the_servos_bus_watchdog_is_armed_once_torque_is_on(robot):
    """The hook of servos with a bus watchdog (Protocol 2.0's address 98): armed after torque
    enable with 10 ticks (>= 200 ms); the AX-12A has none (False: nothing said)."""
    from wbc.servos.bus import DryRunBus
    from wbc.servos.protocol1 import ax_codec

    class Armed(DryRunBus):
        armed = None

        def arm_watchdog(self, timeout_s):
            self.armed = (timeout_s, self.torque)
            return True

    q0 = robot.configuration("walk_ready")[7:]
    codec = ax_codec(robot.servo_map)
    bus = Armed(codec, [str(i) for i in robot.servo_map.ids], np.rint(codec.encode_float(q0)))
    lines = []
    source = CallableSource(lambda tick, t: None if tick > 2 else q0, q0, robot.joint_names)
    assert Deployment(bus, source, robot, DeployConfig(rate=25.0), lines.append).run().completed
    assert bus.armed == (pytest.approx(0.4), True)
    assert "note: servo bus watchdog armed: 400 ms" in lines
    ax = DynamixelBus("/dev/null", robot.servo_map)
    assert ax.arm_watchdog(0.2) is False
