"""The compliance feed-forward's inertial field, gated (``Gains.ff_inertial`` with
``ff_inertial_back`` and ``ff_inertial_band``; issue 30, seventeenth session).

The static feed-forward loads the stance ankle with the CoM's moment ``m g (c − a)``; the ankle
must carry the planned CoP's, ``m g (p − a)``: they differ by ``m h c̈``. ``ff_inertial`` feeds
the torques under ``g − k c̈_ref`` (:meth:`~wbc.balance.compliance.ComplianceCompensator.
torques`), which helps the backward push and costs the forward catch and the walk's length
(benchmarks/pushes.md, sixteenth session). The gates were built to keep the field where the
sixteenth session placed the walk's lag (the CoM decelerating over the stance foot) and to
drop it where a catch forward needs the body over the stance foot (measured, seventeenth
session: neither gate keeps main's backward pushes; all off):

* ``back``: the field's part along the walk's heading ``u`` (the torso target's yaw), only
  while it points backward (``c̈ · u < 0``: the CoM behind the ZMP, decelerating over the
  stance foot); the sideways part dropped;
* ``band`` > 0: × ``clip(−e / band, 0, 1)``, ``e = (ξ − ξ_ref) · u`` the estimated DCM's
  error along the heading: full while the DCM lags by ``band`` or more, none once it is
  ahead (a push forward releases it); from ``start`` (``ff_inertial_from``) on:
  ``clip((−e − start) / band, 0, 1)``, the unpushed walk's own lag left out.
"""

from __future__ import annotations

import math

import numpy as np


def gated_field(
    acc: np.ndarray,
    heading: float,
    dcm_error: np.ndarray | None,
    back: bool,
    band: float,
    start: float = 0.0,
) -> np.ndarray:
    """(3,) the CoM acceleration (m/s², world; already × ``ff_inertial``) the feed-forward
    takes, gated by ``back`` and ``band`` (module docstring; ``dcm_error``: (2,) ``ξ − ξ_ref``,
    None: not yet estimated, the gate shut; ``start``: the lag, m, the gate opens from)."""
    out = np.array(acc, dtype=float)
    u = np.array([math.cos(heading), math.sin(heading)])
    if back:
        along = min(float(out[:2] @ u), 0.0)
        out[:2] = along * u
    if band > 0:
        if dcm_error is None:
            return np.zeros(3)
        e = float(np.asarray(dcm_error, dtype=float)[:2] @ u)
        out *= min(max((-e - start) / band, 0.0), 1.0)
    return out
