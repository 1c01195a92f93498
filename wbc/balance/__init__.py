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

``wbc deploy --compensate``, ``wbc bench --physics --compensate / --gyro / --closed-loop``.
Figures: benchmarks/balance.md; guide: docs/closed_loop.md.
"""

from __future__ import annotations

import argparse

from ..cli import number


def add_compensate_argument(parser: argparse.ArgumentParser, purpose: str) -> None:
    """The ``--compensate [GAIN]`` option of every command that can add the servo compliance
    feed-forward (:mod:`wbc.balance.compliance`): off by default, gain 1 when given bare."""
    parser.add_argument(
        "--compensate",
        type=number(0, 10),
        nargs="?",
        const=1.0,
        default=0.0,
        metavar="GAIN",
        help=f"{purpose} (gain, default 1; wbc.balance.compliance)",
    )
    parser.add_argument(
        "--compensate-encoders",
        action="store_true",
        help="--compensate: rescale each servo's feed-forward online from the encoders' present "
        "positions (wbc.balance.compliance.EncoderCorrection; needs the positions read)",
    )


def check_compensate_encoders(args: argparse.Namespace) -> None:
    """``--compensate-encoders`` corrects the feed-forward: refused without ``--compensate``."""
    from ..exceptions import ConfigurationError

    if getattr(args, "compensate_encoders", False) and not args.compensate > 0:
        raise ConfigurationError(
            "--compensate-encoders corrects the feed-forward: give --compensate too"
        )
