"""Balance on a body (issue 15): between the plan and the servos, and the closed loop.

* :mod:`wbc.balance.compliance` — servo compliance feed-forward (static contact torques from
  pinocchio through the inverse of the AX-12A law of the shared servo settings);
* :mod:`wbc.balance.feedback` — torso gyro feedback on the leg goals (OP3-style);
* :mod:`wbc.balance.estimator` — state estimate from the encoders and a torso IMU
  (complementary filter; CoM, its velocity and the DCM from the stance leg's kinematics);
* :mod:`wbc.balance.stabilizer` — feedback on the walking targets inside the control tick
  (:class:`~wbc.walking.loop.Session`'s ``stabilizer``);
* :mod:`wbc.balance.stepping` — step placement from the measured DCM: the footsteps and the
  walk re-planned inside the closed loop (:class:`~wbc.walking.loop.Session`'s ``stepping``);
* :mod:`wbc.balance.retime` — the walk re-timed after a push (a lift-off waits for the
  measured DCM: :class:`~wbc.walking.loop.Session`'s ``hold``); the closed loop's sway is
  narrowed by the walk's generator (``Gains.transfer``, :func:`wbc.walking.gait.narrow_sway`);
* :mod:`wbc.balance.live` — :func:`~wbc.balance.live.closed_loop`: a controller solved live in
  the deployment's tick on any ServoBus + Imu (``wbc deploy --live STACK --closed-loop``).

``wbc deploy --compensate``, ``wbc bench --physics --compensate / --gyro / --closed-loop``
(the options: :mod:`wbc.cli.options`).
Figures: benchmarks/balance.md; guide: docs/closed_loop.md.
"""

from __future__ import annotations

#: the compliance feed-forward gain that measured best per servo law: x0.5 on the AX-12A
#: (benchmarks/physics.md: closed loop on the plant-randomised sweep, issue 30); x1 on hobby PWM
#: servos (benchmarks/kokone_sim.md section 0: all nine Kokone walks stand with it, none
#: without, x1.3 worse); x0.5 on the XM430 (the OP3's eight walks with its stack, closed loop:
#: at most 3.1 deg against 4.2 at x0, 6.0 at x1; benchmarks/op3.md section 7). What the
#: commands use by default.
BEST_COMPENSATE_BY_LAW = {"ax12a": 0.5, "hobby_pwm": 1.0, "xm430": 0.5}
BEST_COMPENSATE = BEST_COMPENSATE_BY_LAW["ax12a"]


def best_compensate(robot) -> float:
    """The default feed-forward gain for ``robot``: :data:`BEST_COMPENSATE_BY_LAW` for its
    servo law (0 for a law without a measured best, or no servo model at all)."""
    from ..exceptions import WbcError
    from ..sim.actuator import servo_kind

    try:
        return BEST_COMPENSATE_BY_LAW.get(servo_kind(robot), 0.0)
    except WbcError:  # no servo model at all: nothing to feed forward
        return 0.0
