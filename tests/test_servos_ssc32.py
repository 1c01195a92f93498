"""SSC-32 backend: command strings, channel map, and ``wbc deploy --backend ssc32``."""

from __future__ import annotations

import argparse
import math

import numpy as np
import pytest

from wbc.cli import deploy as deploy_cmd
from wbc.exceptions import ServoError, ServoMapError
from wbc.servos.emulator import Ssc32Emulator
from wbc.servos.ssc32 import (
    KOKONE_US_PER_DEG,
    Ssc32Bus,
    Ssc32Channel,
    Ssc32Map,
    move_command,
    off_command,
)


def test_move_command_strings():
    assert move_command([0, 5, 31], [1500, 500, 2500], 20) == b"#0P1500#5P500#31P2500T20\r"
    assert move_command([3], [1234]) == b"#3P1234\r"
    with pytest.raises(ServoError, match="channel 5 pulse 2501"):
        move_command([5], [2501])
    with pytest.raises(ServoError, match="pulse 499"):
        move_command([5], [499])
    with pytest.raises(ServoError, match="channel 32"):
        move_command([32], [1500])
    with pytest.raises(ServoError, match="time 70000"):
        move_command([1], [1500], 70000)
    assert off_command([0, 1, 17]) == b"#0L#1L#17L\r"


def test_default_map_uses_kokone_scale(robot):
    m = Ssc32Map.default(robot.joint_names, robot.servo_map.signs.astype(int))
    codec = m.codec()
    assert m.channel_numbers == list(range(18))
    assert np.allclose(codec.encode_float(np.zeros(18)), 1500)
    one_deg = codec.encode_float(np.full(18, math.radians(1.0))) - 1500
    assert np.allclose(np.abs(one_deg), KOKONE_US_PER_DEG)  # 0.075 deg per µs
    assert np.allclose(np.sign(one_deg), robot.servo_map.signs)


def _map_toml(robot, path, edit=lambda s: s):
    lines = ["[joints]"]
    for i, (j, s) in enumerate(zip(robot.joint_names, robot.servo_map.signs, strict=True)):
        lines.append(f"{j} = {{ channel = {31 - i}, sign = {int(s)}, us_per_deg = 11.111 }}")
    path.write_text(edit("\n".join(lines) + "\n"))
    return path


def test_map_from_file_and_bad_maps(robot, tmp_path):
    m = Ssc32Map.from_file(_map_toml(robot, tmp_path / "ok.toml"), robot.joint_names)
    assert m.channel_numbers == list(range(31, 13, -1))
    assert m.channels[0].us_per_deg == pytest.approx(11.111)
    bad = _map_toml(
        robot, tmp_path / "dup.toml", lambda s: s.replace("channel = 30", "channel = 31")
    )
    with pytest.raises(ServoMapError, match="duplicate channel 31"):
        Ssc32Map.from_file(bad, robot.joint_names)
    missing = _map_toml(robot, tmp_path / "miss.toml", lambda s: s.replace("r_elbow =", "r_elb ="))
    with pytest.raises(ServoMapError, match=r"missing \['r_elbow'\], unknown \['r_elb'\]"):
        Ssc32Map.from_file(missing, robot.joint_names)
    with pytest.raises(ServoMapError, match="center_us 3000"):
        Ssc32Map([Ssc32Channel("a", 0, 1, 3000.0)])
    with pytest.raises(ServoError, match="not an SSC-32 rate"):
        Ssc32Bus("/dev/null", m, baud=1_000_000)


def _run(port, recording, *extra):
    parser = argparse.ArgumentParser()
    deploy_cmd.add_arguments(parser)
    args = parser.parse_args([recording, "--backend", "ssc32", "--port", port, *extra])
    return deploy_cmd.run(args)


@pytest.fixture(scope="module")
def recording(robot, tmp_path_factory):
    from wbc.recording import Recording

    q0 = robot.configuration("walk_ready")
    t = np.linspace(0.0, 0.6, 31)
    q = np.tile(q0, (t.size, 1))
    q[:, robot.q_index("l_knee")] += 0.2 * np.sin(np.pi * t / 0.6) ** 2
    path = tmp_path_factory.mktemp("ssc") / "knee.npz"
    Recording(t, q, robot.joint_names).save(path)
    return str(path)


# the board emulator is a second process: its replies are judged on its device time, the ticks
# on a paced clock (tests/conftest.py), with the production deadline (50 ms) and streak (3)
@pytest.mark.usefixtures("paced_clock")
def test_deploy_on_ssc32_sends_safe_pulses(robot, recording, tmp_path, capsys, device_time):
    map_path = str(_map_toml(robot, tmp_path / "map.toml"))
    with device_time.watch(Ssc32Emulator(process=True)) as board:
        rc = _run(board.port, recording, "--ssc32-map", map_path, "--rate", "50")
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert "positions cannot be read" in out  # no soft start without feedback: said so
    m = Ssc32Map.from_file(map_path, robot.joint_names)
    codec = m.codec()
    speed = np.minimum(robot.v_max, Ssc32Bus.servo_speed) * np.abs(codec.scale)  # us/s
    by_channel = {c.channel: i for i, c in enumerate(m.channels)}
    moves = [ln for ln in board.lines if ln.startswith(b"#")]
    skipped = int(out.split("ticks skipped")[0].rsplit("(", 1)[1])
    assert len(moves) - 1 <= 31 <= len(moves) - 1 + skipped  # start pose, then 31 slots
    assert all(ln.endswith(b"T20") for ln in moves)
    pulses: dict[int, list] = {}
    for p in board.pulses:
        pulses.setdefault(p.channel, []).append(p)
    assert set(pulses) == set(by_channel)
    for ch, records in pulses.items():
        i = by_channel[ch]
        v = np.array([p.pulse for p in records], dtype=float)
        t = np.array([p.time for p in records])
        q = codec.decode(np.broadcast_to(v[:, None], (v.size, 18)))[:, i]
        assert np.all(q >= robot.q_min[i] - 1e-9) and np.all(q <= robot.q_max[i] + 1e-9)
        # never faster than the servo: |dv| <= speed · (dt + 20 ms stamp jitter) + 1 us
        dv, dt = np.abs(v[:, None] - v[None, :]), np.abs(t[:, None] - t[None, :])
        assert np.all(dv <= speed[i] * (dt + 0.02) + 1 + 1e-9)
        assert np.all((v >= 500) & (v <= 2500))


@pytest.mark.usefixtures("paced_clock")  # silence still times out on the device clock
def test_dead_ssc32_board_ends_in_torque_off(robot, recording, tmp_path, capsys, device_time):
    map_path = str(_map_toml(robot, tmp_path / "map.toml"))
    with device_time.watch(Ssc32Emulator(process=True, silent_after=10)) as board:
        rc = _run(board.port, recording, "--ssc32-map", map_path, "--on-fault", "torque-off")
    _, err = capsys.readouterr()
    assert rc == deploy_cmd.EXIT_SAFE_STOP
    assert "SAFE STOP (torque-off): ssc32 bus: 3 consecutive failed exchanges (timeout)" in err
    assert board.lines[-1] == off_command(range(31, 13, -1))[:-1]
    assert 10 <= board.moves <= 10 + 3


def test_ssc32_wrong_baud_is_refused(robot, recording, capsys):
    with Ssc32Emulator(process=True, baud=115200) as board:
        rc = _run(board.port, recording, "--baud", "9600")
    assert rc == deploy_cmd.EXIT_REFUSED
    assert "no SSC-32 answered VER" in capsys.readouterr().err
    assert board.pulses == []
    assert _run("/dev/null", recording, "--read") == deploy_cmd.EXIT_REFUSED
    assert "ssc32 backend cannot read servo positions" in capsys.readouterr().err


def test_dry_run_shows_the_ssc32_figures(tmp_path, capsys):
    """The SSC-32 dry run: the SSC-32 bus budget (as --plan) and board health, not the
    Dynamixel per-servo figures."""
    from wbc import load_robot
    from wbc.cli import main
    from wbc.recording import Recording

    kokone = load_robot("kokone")
    t = np.arange(0.0, 0.2, 0.02)
    path = tmp_path / "k.npz"
    Recording(t, np.tile(kokone.configuration("stand"), (t.size, 1)), kokone.joint_names).save(path)
    assert main(["deploy", str(path), "--robot", "kokone", "--bus", "ssc32", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "bus budget (write-only, 115200 baud): 173 B and 1 replies per tick = 16.02 ms" in out
    assert "health: one board query per tick (no per-servo status" in out
    assert "servos checked per tick" not in out


def test_ssc32_garbage_answers_are_failed_exchanges(robot, monkeypatch):
    bus = Ssc32Bus("/dev/null", Ssc32Map.default(robot.joint_names))
    for reply, comm in (
        (b".", "ok"),
        (b"+", "ok"),
        (b"\x00\x13\x37", "corrupt"),
        (None, "timeout"),
    ):
        monkeypatch.setattr(bus, "_query", lambda text, until=None, r=reply: r)
        assert bus.poll(0).comm == comm


def test_ssc32_query_looks_once_more_after_its_deadline(robot, monkeypatch):
    """A host stalled past the reply deadline still takes the reply waiting on the port (the
    last look comes after the deadline, as the Dynamixel exchange's); silence still fails."""

    class Port:
        def __init__(self, data):
            self.data = data

        def reset_input_buffer(self):
            pass

        def write(self, text):
            pass

        def read(self, n):
            out, self.data = self.data, b""
            return out

    bus = Ssc32Bus("/dev/null", Ssc32Map.default(robot.joint_names))
    for waiting, want in ((b".", b"."), (b"", None)):
        bus.ser = Port(waiting)
        times = iter([0.0, 1.0, 1.0])  # the deadline from 0 s; the first look at 1 s, past it
        monkeypatch.setattr(Ssc32Bus, "reply_clock", staticmethod(lambda t=times: next(t)))
        assert bus._query(b"Q\r") == want
