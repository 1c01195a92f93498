"""wbc.drive: command files, the Walker on a bus through the deployment, the keyboard's
keys, ``wbc drive``'s refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wbc.cli import main
from wbc.drive.commands import Command, CommandScript, integrate, load_commands, random_commands
from wbc.drive.teleop import Keyboard
from wbc.drive.walker import Walker
from wbc.exceptions import ConfigurationError, InfeasibleError
from wbc.recording import SUPPORT_DOUBLE
from wbc.servos.bus import DryRunBus
from wbc.servos.protocol1 import ax_codec
from wbc.stacks import load_stack
from wbc.walking import GaitTiming, SwingParams
from wbc.walking.engine import EngineParams, VelocityLimits
from wbc.walking.loop import StackController

LEGS_ONLY = EngineParams(
    timing=GaitTiming(), swing=SwingParams(apex=0.015), zmp_offset=(0.0, 0.0285), transfer=1.0
)
LIMITS = VelocityLimits(0.08, 0.06, 0.03, 0.5)


def test_commands_file(tmp_path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(
        "[[command]]\nduration = 2\nvx = 0.05\n[[command]]\nduration = 1.5\nwz = -0.2\n"
    )
    cmds = load_commands(path)
    assert cmds == [Command(2.0, 0.05), Command(1.5, 0.0, 0.0, -0.2)]
    script = CommandScript(cmds)
    assert script.at(1.0) == cmds[0] and script.at(2.5) == cmds[1] and script.at(3.6) is None
    for text, match in (
        ("[[command]]\nvx = 0.1\n", "command 1 needs a duration"),
        ("[[command]]\nduration = 1\nvz = 0.1\n", r"command 1 has unknown keys \['vz'\]"),
        ("[[command]]\nduration = 1\n[[command]]\nduration = -1\n", "command 2 duration"),
        ("[[command]]\nduration = 1\nvx = 'fast'\n", "command 1 vx = 'fast'"),
        ("[[command]]\nduration = 1\nvx = nan\n", "command 1 vx = nan"),
        ("speed = 1\n", r"unknown keys \['speed'\]"),
        ("", "no \\[\\[command\\]\\] tables"),
        ("[[command]\n", "not valid TOML"),
    ):
        path.write_text(text)
        with pytest.raises(ConfigurationError, match=match) as info:
            load_commands(path)
        assert str(path) in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(ConfigurationError, match="not found"):
        load_commands(tmp_path / "missing.toml")


def test_integrate_is_the_exact_body_motion() -> None:
    """The closed form equals a fine Euler integration of ṗ = R(θ) v, θ̇ = ωz."""
    cmds = [Command(2.0, 0.05, 0.01, 0.3), Command(1.0, 0.0, -0.02), Command(3.0, 0.04, 0, -0.5)]
    p, th = np.zeros(2), 0.0
    dt = 1e-4
    for c in cmds:
        for _ in range(round(c.duration / dt)):
            R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
            p = p + dt * R @ np.array([c.vx, c.vy])
            th += dt * c.wz
    got, yaw = integrate(cmds)
    assert np.allclose(got, p, atol=1e-4) and yaw == pytest.approx(th)


def test_random_commands_stay_inside_the_envelope() -> None:
    lim = (0.08, 0.06, 0.03, 0.5)
    cmds = random_commands(np.random.default_rng(3), lim, 30.0)
    assert sum(c.duration for c in cmds) == pytest.approx(30.0)
    assert all(2.0 - 1e-9 <= c.duration <= 5.0 for c in cmds[:-1])
    for c in cmds:
        fwd = lim[0] if c.vx >= 0 else lim[1]
        assert abs(c.vx) / fwd + abs(c.vy) / lim[2] + abs(c.wz) / lim[3] <= 1.0 + 1e-9


class _Clock:
    """Simulated time for the deployment: the test runs as fast as the computer allows."""

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += max(seconds, 0.0)


def test_walker_plays_commands_through_the_deployment(robot) -> None:
    """A Walker as the deployment's source on ideal servos (a dry-run bus): it starts, walks
    the commanded way, stops on its closing step, and every goal stays inside the joint
    limits; the deployment completes when the walker is closed."""
    codec = ax_codec(robot.servo_map)
    q0 = robot.configuration("stand")
    bus = DryRunBus(codec, robot.joint_names, np.rint(codec.encode_float(q0[7:])))
    bus.clock = _Clock()
    walker = Walker(robot, StackController(load_stack("walk", robot, solver="weighted")), None,
                    params=LEGS_ONLY, limits=LIMITS, window=None)  # fmt: skip
    goals = []

    def steer(t: float) -> None:
        if t < 1.6:
            walker.command(0.06, 0.0, 0.0)
            walker.start()
        elif t < 1.7:
            walker.stop()
        elif not walker.walking:
            walker.close()
        goals.append(walker.q[7:].copy())

    walker.before_tick = steer
    result = walker.deployment(bus, out=lambda _line: None).run()
    assert result.completed
    assert walker.engine.steps_taken >= 3 and walker.failed_solves == 0
    g = np.array(goals)
    assert np.all(g >= robot.q_min - 1e-9) and np.all(g <= robot.q_max + 1e-9)
    left = walker.engine.feet["left"]
    assert left.x > 0.03  # it walked forward
    assert walker.command(1.0, 0.0, 0.0) == pytest.approx((0.08, 0.0, 0.0))


class _FakeWalker:
    limits = LIMITS

    def __init__(self) -> None:
        self.calls: list = []

    def command(self, *v):
        self.calls.append(("command", v))
        return v

    def start(self):
        self.calls.append(("start",))

    def stop(self):
        self.calls.append(("stop",))


def test_keyboard_keys_steer_the_walker(capsys) -> None:
    kb = Keyboard()
    w = _FakeWalker()
    assert kb.apply("gww", w)
    assert w.calls[0] == ("start",)
    assert w.calls[-1] == ("command", pytest.approx((0.04, 0.0, 0.0)))
    assert kb.apply("dq", w)
    assert w.calls[-1] == ("command", pytest.approx((0.04, -0.0075, 0.125)))
    assert kb.apply(" ", w) and w.calls[-1] == ("command", (0.0, 0.0, 0.0))
    assert not kb.apply("x", w) and w.calls[-1] == ("stop",)


def test_drive_refuses_bad_arguments(tmp_path, capsys) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[[command]]\nduration = 0\n")
    for argv, match in (
        (["drive", "--sim", "--commands", str(bad)], "command 1 duration = 0.0"),
        (["drive", "--view", "--commands", str(bad)], "--view shows the simulator"),
        (["drive", "--commands", str(bad)], "give --sim or --port"),
        (["drive", "--sim", "--commands", str(bad), "--keyboard"], "not several"),
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert match in err and "\n" not in err, err


@pytest.mark.parametrize("closed", [True, False])
def test_walker_corrects_the_feed_forward_from_the_encoders(robot, closed) -> None:
    """With the compliance feed-forward, the closed-loop Walker rescales it per servo from
    the encoders (EncoderCorrection): on ideal servos (a dry-run bus: present = goal, no
    deflection) the learnt scales drop below 1 while it walks; open loop (or
    ``correct=False``) the model's feed-forward is played as it is."""
    codec = ax_codec(robot.servo_map)
    q0 = robot.configuration("stand")
    bus = DryRunBus(codec, robot.joint_names, np.rint(codec.encode_float(q0[7:])))
    bus.clock = _Clock()
    walker = Walker(robot, StackController(load_stack("walk", robot, solver="weighted")), None,
                    params=LEGS_ONLY, limits=LIMITS, window=None, compensate=0.5,
                    closed=closed)  # fmt: skip

    def steer(t: float) -> None:
        walker.command(0.04, 0.0, 0.0)
        walker.start()
        if t > 1.5:
            walker.close()

    walker.before_tick = steer
    dep = walker.deployment(bus, out=lambda _line: None)
    assert dep.run().completed
    correction = dep.source.correction
    if not closed:
        assert correction is None
        return
    assert correction is not None
    assert (correction.window, correction.rate) == (1.0, 3.0)  # DRIVE_CORRECTION
    assert np.min(correction.scale) < 0.9  # learnt: the dry-run servos do not deflect
    assert np.all(correction.scale >= correction.s_min)


def _sagging_walk(robot, on_tick=None, **options):
    """A walker on the spot for 3 s whose present positions sag from its goals (a left hip
    roll 0.15 rad off: each landing measured 24 mm from its plan); ``on_tick(walker)`` after
    each tick."""
    from wbc.bench.solvers import registry

    walker = Walker(robot, registry("physics")["hqp-daqp"].make(robot), None, **options)
    sag = np.zeros(robot.n_joints)
    sag[robot.joint_names.index("l_hip_roll")] = 0.15
    walker.present = lambda: walker.q[7:] + sag
    walker.command(0.0, 0.0, 0.0)
    walker.start()
    for _ in range(300):
        walker.tick()
        if on_tick is not None:
            on_tick(walker)
    assert walker.engine.steps_taken >= 4
    assert len(walker.engine.landing_errors) >= 2  # the measured landings were taken
    assert min(walker.engine.landing_errors) > 0.02
    return walker


def test_measured_landings_leave_the_contacts_solvable(robot) -> None:
    """Leg odometry measures each landing from the encoders; on compliant servos the
    present positions sag from the goals (24 mm here). Anchored at the measured landing in
    a double support (main's behaviour before 2026-12-05 08:35 UTC), every double
    support's hard level was infeasible (30 failed solves of 300 ticks); the stance contact
    now moves toward it in single support only, and even at once and all the way
    (``contact_rate`` and ``contact_reach`` unbounded) no solve fails. A solve that fails is
    counted per cause and reported (the robot holds its goals)."""
    from wbc.drive.walker import failure_cause, failure_lines

    walker = _sagging_walk(robot)  # the default
    assert walker.failed_solves == 0, dict(walker.failure_causes)
    assert failure_lines(walker) == []
    jump = _sagging_walk(robot, contact_reach=math.inf, contact_rate=math.inf)
    assert jump.failed_solves == 0, dict(jump.failure_causes)
    error = InfeasibleError(
        "hard level 0 is infeasible: cannot satisfy contact_support (residual 0.00202) "
        "together with self_collision (active)"
    )
    assert failure_cause(error, "double") == (
        "double: InfeasibleError: hard level 0 is infeasible: cannot satisfy "
        "contact_support together with self_collision (active)"
    )
    solve = jump.controller.track

    def failing(q, targets, dt, changed):  # every double support's solve fails
        if targets.phase == "double":
            raise error
        return solve(q, targets, dt, changed)

    jump.controller.track = failing
    for _ in range(100):
        jump.tick()
    assert jump.failed_solves >= 20
    assert set(jump.failure_causes) == {failure_cause(error, "double")}
    assert failure_lines(jump)[0].startswith(f"WARNING: {jump.failed_solves} of 400 walk ticks")
    for option in ("contact_reach", "contact_rate"):
        with pytest.raises(ConfigurationError, match=option):
            Walker(robot, walker.controller, None, **{option: -0.001})


def test_stance_contact_slides_toward_the_measured_landing(robot) -> None:
    """In single support the controller's stance contact moves from the planned sole toward
    the measured landing (leg odometry, 24 mm off here), at most ``contact_reach`` from the
    plan and ``contact_rate`` × dt per tick; in double support (two hard contacts and the
    feet's self-collision rows) no contact target moves; no solve fails."""
    from wbc.drive.walker import DRIVE_CONTACT_RATE, DRIVE_CONTACT_REACH
    from wbc.tasks.contact import ContactTask

    rows = []  # (tick, phase, frame, plan object, target, plan position)

    def record(walker) -> None:
        tasks = [t for t in walker.controller.control.stack.tasks() if isinstance(t, ContactTask)]
        for task in tasks:
            if task.active:
                side = "left" if task.frame == "l_sole" else "right"
                plan = walker.engine.feet[side]
                rows.append((len(walker.tick_time), walker.last.support, task.frame, plan,
                             task.target_position.copy(), plan.position.copy()))  # fmt: skip

    walker = _sagging_walk(robot, record)
    assert walker.failed_solves == 0, dict(walker.failure_causes)
    step = DRIVE_CONTACT_RATE * walker.engine.dt
    off = [float(np.linalg.norm(r[4] - r[5])) for r in rows]
    assert max(off) > 0.8 * DRIVE_CONTACT_REACH  # it moved toward the measured sole ...
    assert max(off) <= DRIVE_CONTACT_REACH + 1e-9  # ... within the reach
    last = {}
    moved_in_double = 0
    for k, support, frame, plan, target, _ in rows:
        before = last.get(frame)
        if before is not None and before[0] == k - 1 and before[1] is plan:
            d = float(np.linalg.norm(target - before[2]))
            assert d <= step + 1e-12  # at the rate
            moved_in_double += support == SUPPORT_DOUBLE and d > 0
        last[frame] = (k, plan, target)
    assert moved_in_double == 0


def _double_support_gaps(walker, gaps: list) -> None:
    """The gap (m) between the two hard contacts' targets (foot rectangles) at each double
    support tick, appended to ``gaps``."""
    from wbc.geometry import yaw_of
    from wbc.tasks.contact import ContactTask
    from wbc.walking.footgaps import rectangle_gaps

    tasks = {
        t.frame: t
        for t in walker.controller.control.stack.tasks()
        if isinstance(t, ContactTask) and t.active
    }
    if len(tasks) == 2:
        left, right = tasks["l_sole"], tasks["r_sole"]
        xy, yaw = left.target_position[None, :2], np.array([yaw_of(left.target_rotation)])
        foot = walker.engine.foot
        gaps.append(float(rectangle_gaps(xy, yaw, right.target_position[:2],
                                         yaw_of(right.target_rotation), foot)[0]))  # fmt: skip


@pytest.mark.parametrize("keep_clear", [True, False])
def test_turning_on_the_spot_keeps_the_contacts_clear(robot, keep_clear) -> None:
    """Turning on the spot at the turning limit the trailing sole lands 7–8 mm beside the
    stance sole; with the encoders reading each landing ~8 mm inward of its plan (a left hip
    roll sagging 0.05 rad), the stance contact's move toward the measured sole in single
    support (``contact_reach``, 5 mm) took the next double support's two hard contacts to
    0.3 mm apart, inside the feet's 5 mm self-collision margin: 50 failed solves in 400
    ticks (main before 2026-12-06; the regression of the random sequences, turning on the
    spot). Kept clear of the swing's planned landing (the default) the contacts stay at the
    feet's clearance (``EngineParams.min_clearance``) and no solve fails."""
    from wbc.bench.solvers import registry

    walker = Walker(robot, registry("physics")["hqp-daqp"].make(robot), None,
                    keep_clear=keep_clear)  # fmt: skip
    sag = np.zeros(robot.n_joints)
    sag[robot.joint_names.index("l_hip_roll")] = -0.05
    walker.present = lambda: walker.q[7:] + sag
    walker.command(0.0, 0.0, walker.limits.wz)
    walker.start()
    gaps: list[float] = []
    for _ in range(400):
        walker.tick()
        _double_support_gaps(walker, gaps)
    assert walker.engine.steps_taken >= 6
    assert min(walker.engine.landing_errors) > 0.006  # the landings measured off their plans
    clearance = walker.engine.params.min_clearance
    if keep_clear:
        assert walker.failed_solves == 0, dict(walker.failure_causes)
        assert min(gaps) >= clearance - 1e-9
    else:  # (what it guards against)
        assert walker.failed_solves > 0
        assert min(gaps) < clearance


@pytest.mark.parametrize("finish", [False, True])
def test_a_finishing_stop_ends_where_the_commands_put_the_walk(robot, finish) -> None:
    """A command takes effect at the next lift-off and the walk starts with a 0.8 s start
    phase, so a short script ends before the steps have made up the lag: 1.5 s at 6 cm/s
    forward and 0.3 rad/s, then a plain stop closes about a step short of the commanded
    pose. ``stop(finish=True)`` (a script's end) walks on with the command zero while the
    steps make up the lag (at most DRIVE_FINISH_STEPS), then closes: within 1 cm and 2°.
    (Ideal servos, no IMU: the engine's own odometry.)"""
    from wbc.bench.solvers import registry
    from wbc.drive.walker import DRIVE_FINISH_STEPS
    from wbc.geometry import wrap_angle
    from wbc.walking.geometry import rot2

    walker = Walker(robot, registry("physics")["hqp-daqp"].make(robot), None)
    walker.present = lambda: walker.q[7:]
    engine = walker.engine
    walker.command(0.06, 0.0, 0.3)
    walker.start()
    for _ in range(150):
        walker.tick()
    walker.stop(finish=finish)
    steps = engine.steps_taken
    while walker.walking:
        walker.tick()
    start = engine.pose_cmd  # (the commanded pose, unchanged since the stop)
    c = engine.centre + engine.odometry_offset
    xy = c[:2] + rot2(c[2]) @ engine.origin
    off, turn = float(np.hypot(*(start[:2] - xy))), abs(wrap_angle(start[2] - c[2]))
    if finish:
        assert off < 0.01 and turn < math.radians(2.0)
        assert engine.steps_taken <= steps + DRIVE_FINISH_STEPS + 2  # (+ the closing steps)
    else:
        assert off > 0.02 or turn > math.radians(5.0)


@pytest.mark.parametrize("hold", [0.0, 0.02])
def test_a_stop_holds_the_base_on_the_commanded_place(robot, hold) -> None:
    """The last steps land on the commanded pose, but the standing robot's base is not
    where the standing pose has it over them (the engine's rest puts the CoM at the soles'
    midpoint; the Bioloid's standing CoM is ~5 mm ahead of it): without the base's hold the
    base (by the joints, here the commanded ones) ends > 3 mm off the commanded pose; with
    it, after the walk, the CoM target moves until it is within 1 mm, and the walker
    reports walking until then (at most the hold's seconds more)."""
    from wbc.bench.solvers import registry
    from wbc.drive.walker import DRIVE_HOLD

    walker = Walker(robot, registry("physics")["hqp-daqp"].make(robot), None, hold=hold)
    walker.present = lambda: walker.q[7:]
    engine = walker.engine
    walker.command(0.05, 0.0, 0.0)
    walker.start()
    for _ in range(100):
        walker.tick()
    walker.stop()
    ended = None
    for n in range(1000):
        if not walker.walking:
            break
        walker.tick()
        if ended is None and not engine.walking:
            ended = n
    assert not walker.walking and ended is not None
    error = float(np.hypot(*(engine.pose_cmd[:2] - engine.frame_offset[:2]
                             - walker._measured_base())))  # fmt: skip
    if hold:
        assert error < 0.001
        assert n - ended <= round(DRIVE_HOLD["seconds"] / engine.dt) + 1
        assert walker.failed_solves == 0
    else:
        assert error > 0.003 and n - ended <= 1


def test_the_walker_reads_its_links_through_the_play(robot) -> None:
    """``Walker(play=p)``: the present positions its own measurements use (the leg odometry,
    the heading's tilt, the swing's lift) have the play taken out — a joint whose reading
    rose is read ``p / 2`` higher —; without it, they are the readings; a bad play is
    refused in one line."""
    q0 = robot.configuration("stand")
    readings = [q0[7:].copy(), q0[7:] + 0.01]
    made = {}
    for play in (0.0, 0.02):
        walker = Walker(robot, StackController(load_stack("walk", robot, solver="weighted")),
                        None, params=LEGS_ONLY, limits=LIMITS, window=None,
                        play=play)  # fmt: skip
        for present in readings:
            walker.present = lambda present=present: present
            walker.tick()
        made[play] = walker._present_configuration()[7:]
    assert made[0.0] == pytest.approx(readings[1])
    assert made[0.02] == pytest.approx(readings[1] + 0.01)
    with pytest.raises(ConfigurationError, match="play"):
        Walker(robot, StackController(load_stack("walk", robot, solver="weighted")), None,
               params=LEGS_ONLY, limits=LIMITS, window=None, play=-0.01)  # fmt: skip


class _TurnedOdometry:
    """An outer loop's odometry that measures the walking frame and the torso turned
    ``error`` (rad) off the planned soles' midpoint (a closing step landed turned, as the
    gyro would see it)."""

    def __init__(self, walker: Walker, error: float) -> None:
        self.walker, self.error, self.started = walker, error, True
        self.start_heading = 0.0  # (the walk starts facing x)

    @property
    def heading(self) -> float:
        from wbc.geometry import mean_angle

        feet = self.walker.engine.feet
        return mean_angle(feet["left"].yaw, feet["right"].yaw) + self.error

    def landed(self, side, q, placed=None) -> np.ndarray:
        feet = self.walker.engine.feet
        return np.r_[0.5 * (feet["left"].xy + feet["right"].xy), self.heading]

    def stop(self) -> None:
        self.started = False

    def turn(self, *args) -> None:
        pass


@pytest.mark.parametrize(("steps", "error", "taken"), [(0, 2.0, 0), (1, 2.0, 1), (1, -3.0, 0)])
def test_a_finish_step_turns_a_closing_step_measured_off(robot, steps, error, taken) -> None:
    """When the walk has ended, the walker measures the closing step's landing by its
    odometry (here one that sees the soles 2° counter-clockwise of their plan, where the
    turning walk's plan ended ~5° short of the commanded heading) and, off the commanded
    pose by more than DRIVE_FINISH_TOLERANCE (within DRIVE_FINISH_BELIEVED), takes one finish
    step aimed from the measured frame (``finish_steps``): the measured heading then ends
    within 0.6° of the commanded one (without: 2° and more off), one step more, the walker
    walking until it ends; the measured errors are kept per walk's end. Measured ~8° off
    (beyond DRIVE_FINISH_BELIEVED), none is taken."""
    from wbc.bench.solvers import registry
    from wbc.geometry import wrap_angle

    walker = Walker(robot, registry("physics")["hqp-daqp"].make(robot), None)
    walker.present = lambda: walker.q[7:]
    walker.odometry = _TurnedOdometry(walker, math.radians(error))  # type: ignore[assignment]
    walker.finish.steps = steps
    engine = walker.engine
    walker.command(0.04, 0.0, 0.3)
    walker.start()
    for _ in range(150):
        walker.tick()
    walker.stop()
    ended = None
    for _ in range(1000):
        if not walker.walking:
            break
        walker.tick()
        if ended is None and walker.finish.errors:
            ended = engine.steps_taken
    assert not walker.walking and ended is not None
    assert len(walker.finish.errors) == 1 + taken
    turn = abs(wrap_angle(walker.finish.errors[-1][2]))
    assert abs(wrap_angle(walker.finish.errors[0][2])) > math.radians(2.0)
    assert engine.steps_taken == ended + taken
    assert (turn < math.radians(0.6)) if taken else (turn > math.radians(2.0))
    assert walker.failed_solves == 0


@pytest.mark.parametrize("rest_rotation", [False, True])
def test_the_walker_passes_rest_rotation_to_its_odometry(robot, rest_rotation: bool) -> None:
    """``Walker(rest_rotation=...)`` reaches the outer loop's odometry (off by default)."""
    from wbc.imu import Imu, ImuReading

    class Still(Imu):
        def read(self) -> ImuReading:
            return ImuReading(0.0, np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.zeros(3))

    controller = StackController(load_stack("walk", robot, solver="weighted"))
    options = {"rest_rotation": True} if rest_rotation else {}
    walker = Walker(robot, controller, Still(), **options)
    assert walker.odometry is not None
    assert walker.odometry.rest_rotation is rest_rotation
