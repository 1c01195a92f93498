"""Balance on a body (issue 15): goal shaping between the plan and the servos.

* :mod:`wbc.balance.compliance` — servo compliance feed-forward (static contact torques from
  pinocchio through the inverse of the AX-12A law of the shared servo settings);
* :mod:`wbc.balance.feedback` — torso gyro feedback on the leg goals (OP3-style, closed loop).

Both wrap a target source (:class:`wbc.servos.sources.TargetSource`): ``wbc deploy
--compensate``, ``wbc bench --physics --compensate / --gyro``. Figures: benchmarks/balance.md.
"""
