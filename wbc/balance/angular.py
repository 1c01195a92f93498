"""How much a push the whole body can take by spinning parts of itself (hip strategy bound).

The LIPM with angular momentum: with ``L`` the centroidal angular momentum about the horizontal
axis ``z × u`` (``u`` the direction of the fall), the ground force's line through the CoM
meets the floor at the centroidal moment pivot ``r = p + L̇ / (m g)`` (along ``u``; ``p`` the
CoP), and the DCM ``ξ = c + ċ/ω₀`` obeys ``ξ̇ = ω₀ (ξ − r)``. With the CoP held at the
sole's edge ``e``, the DCM is caught iff

    ξ(0) − e ≤ ∫₀^∞ ω₀ e^{−ω₀ t} (r − e) dt = (1/(m g)) ∫ ω₀ e^{−ω₀ t} L̇ dt
             = (1/(m h)) ∫₀^∞ e^{−ω₀ t} L(t) dt          (by parts, L(0) = 0, ω₀² = g/h)

so a body of inertia ``I`` spun at ``θ̇(t)`` about that axis buys
``Δξ = (I / (m h)) ∫ e^{−ω₀ t} θ̇ dt``: early speed counts, and a spin held at speed keeps
paying until the joint range ends it (the stop's reverse pivot is already in the integral:
θ̇ returns to 0). Each spinning part is driven by one position servo, saturated (the largest
torque it has): ``I_eff θ̈ = τ_s − τ_g − b θ̇`` (``τ_g`` the gravity torque the joint already
holds, ``b = τ_s/ω_nl`` the back-EMF, ``I_eff = I + armature``), i.e.
``θ̇ = v_∞ (1 − e^{−(t − t_d)/T})`` after the detection delay ``t_d``, ``v_∞ = (τ_s − τ_g)/b``,
``T = I_eff / b``, until ``θ`` reaches the joint's range in that direction.

:func:`flywheel_shift` is that law; :func:`hip_strategy_bound` applies it to a robot at a
configuration: the stance hip roll spinning everything above the stance leg (torso, arms,
swing leg), plus the swing hip roll spinning the swing leg and the shoulder rolls the arms
(added as independent flywheels: optimistic). :func:`point_push_bound`: the same bound for a
push applied above the CoM, where the simulator applies it (the root body's CoM,
:func:`push_point`): its moment about the sole's edge moves the DCM with the angular momentum
returned by ``z_p / h`` times a push at the CoM, and its own spin is either given back or
kept by the upper body (``L(0) ≠ 0`` above). Figures: benchmarks/pushes.md.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, ModelError
from ..model import Robot
from ..sim.actuator import ARMATURE, NO_LOAD_SPEED, STALL_TORQUE

GRAVITY = 9.81


def flywheel_shift(
    inertia: float,
    mass: float,
    com_height: float,
    torque: float,
    damping: float,
    joint_range: float,
    armature: float = ARMATURE,
    delay: float = 0.0,
    speed0: float = 0.0,
) -> float:
    """Δξ (m) bought by one body of ``inertia`` (kg·m², about the spin axis) spun by a
    saturated servo (net ``torque`` N·m beyond what it holds, back-EMF ``damping``
    N·m·s/rad) through ``joint_range`` rad, starting ``delay`` s after the push (module
    docstring): ``(I / (m h)) ∫ e^{−ω₀ t} θ̇ dt``, the spin ending when ``θ`` reaches the range.
    ``speed0`` (rad/s, ≥ 0): the spin the push itself gave the body at ``t = 0`` (0: from
    rest); it coasts on the back-EMF alone until ``delay`` (``θ̇ = s₀ e^{−t/T}``), then
    the servo drives it (``θ̇ = v∞ + (s₁ − v∞) e^{−t/T}``), the same range for both."""
    for name, v in (("inertia", inertia), ("mass", mass), ("com_height", com_height),
                    ("damping", damping)):  # fmt: skip
        if not (np.isfinite(v) and v > 0):
            raise ConfigurationError(f"flywheel_shift: {name} must be a finite number > 0, got {v}")
    if not (np.isfinite(speed0) and speed0 >= 0):
        raise ConfigurationError(
            f"flywheel_shift: speed0 must be a finite number >= 0, got {speed0}"
        )
    if joint_range <= 0 or (torque <= 0 and speed0 == 0):
        return 0.0
    omega = math.sqrt(GRAVITY / com_height)
    v_inf = max(torque, 0.0) / damping
    tau = (inertia + armature) / damping
    k = omega + 1.0 / tau
    # the push's own spin coasting until the servo drives (0 with speed0 = 0)
    first, spent, s1 = 0.0, 0.0, speed0
    if speed0 > 0 and delay > 0:
        t1 = delay
        if speed0 * tau * (1.0 - math.exp(-delay / tau)) >= joint_range:  # the range first
            t1 = -tau * math.log(1.0 - joint_range / (speed0 * tau))
        first = speed0 * (1.0 - math.exp(-k * t1)) / k
        spent = speed0 * tau * (1.0 - math.exp(-t1 / tau))
        s1 = speed0 * math.exp(-t1 / tau)
        if t1 < delay:
            return inertia / (mass * com_height) * first
    left = joint_range - spent

    def theta(t: float) -> float:
        return v_inf * t + (s1 - v_inf) * tau * (1.0 - math.exp(-t / tau))

    # θ(hi) ≥ v∞ (hi − T) = range; coasting alone (v∞ = 0) ends at s₁ T
    hi = left / v_inf + tau if v_inf > 0 else 50.0 * tau
    lo = 0.0
    if theta(hi) < left:  # (coasting: the range never reached)
        lo = hi
    for _ in range(100):  # the spin's end: θ(t) = range (θ increases)
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if theta(mid) < left else (lo, mid)
    ts = hi
    integral = (
        v_inf * (1.0 - math.exp(-omega * ts)) / omega + (s1 - v_inf) * (1.0 - math.exp(-k * ts)) / k
    )
    return inertia / (mass * com_height) * (first + math.exp(-omega * delay) * integral)


def _about_axis(model: pin.Model, data: pin.Data, bodies: set[int], j: int):
    """(inertia about joint j's axis, gravity torque about it, the axis) of ``bodies``."""
    o = data.oMi[j]
    kind = model.joints[j].shortname()
    if kind not in ("JointModelRX", "JointModelRY", "JointModelRZ"):
        raise ModelError(f"hip_strategy_bound: joint {model.names[j]} is not a revolute RX/RY/RZ")
    a = o.rotation[:, "XYZ".index(kind[-1])]
    inertia, torque = 0.0, 0.0
    for b in bodies:
        Y, B = model.inertias[b], data.oMi[b]
        c = B.act(Y.lever)
        r = c - o.translation
        r_perp = r - (r @ a) * a
        inertia += float(a @ (B.rotation @ Y.inertia @ B.rotation.T) @ a + Y.mass * r_perp @ r_perp)
        torque += float(a @ np.cross(r, np.array([0.0, 0.0, -Y.mass * GRAVITY])))
    return inertia, torque, a


def hip_strategy_bound(
    robot: Robot,
    q: np.ndarray,
    stance: str,
    direction: np.ndarray,
    com_height: float,
    delay: float = 0.0,
    stall_torque: float = STALL_TORQUE,
    no_load_speed: float = NO_LOAD_SPEED,
    armature: float = ARMATURE,
    stance_speed: float = 0.0,
) -> dict[str, Any]:
    """The DCM shift (mm) and impulse (N·s) the whole body's spinning parts can add to the
    CoP's catch against a push along ``direction`` (horizontal, world), standing on
    ``stance`` ("left"/"right") at configuration ``q`` (module docstring). Parts: the stance
    hip roll turning everything above the stance leg about it (the torso's top thrown along
    ``direction``), the swing hip roll turning the swing leg and the shoulder rolls turning
    the arms the same way; each from rest at its servo's stall torque less the gravity torque
    it holds, within its joint range in that direction, ``delay`` s after the push;
    ``stance_speed`` (rad/s): the spin the push itself gave the stance hip's part
    (:func:`point_push_bound`; 0: every part from rest)."""
    if stance not in ("left", "right"):
        raise ConfigurationError(
            f"hip_strategy_bound: stance must be 'left' or 'right', got {stance!r}"
        )
    u = np.array([direction[0], direction[1], 0.0], dtype=float)
    if not np.linalg.norm(u) > 0:
        raise ConfigurationError("hip_strategy_bound: direction must have a horizontal part")
    u /= np.linalg.norm(u)
    w = np.cross([0.0, 0.0, 1.0], u)  # the spin axis: the top moves along u
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    mass = robot.total_mass
    damping = stall_torque / no_load_speed
    roles = robot.roles
    swing = "right" if stance == "left" else "left"
    every = set(range(1, model.njoints))
    parts = []
    arms = [roles.get(side, "shoulder_roll") for side in ("left", "right")]
    for joint, moving in (
        (roles.joint(stance, "hip_roll"), "above"),
        (roles.joint(swing, "hip_roll"), "below"),
        *((a, "below") for a in arms if a is not None),
    ):
        j = model.getJointId(joint)
        sub = set(model.subtrees[j])  # joint j and every joint below it
        bodies = every - sub if moving == "above" else sub
        inertia, grav, a = _about_axis(model, data, bodies, j)
        # the moving part turns by +Δq·a (subtree) or −Δq·a (the rest, the leg held)
        sign = 1.0 if moving == "below" else -1.0
        dq = sign * math.copysign(1.0, float(a @ w))  # joint motion per rad of spin along w
        k = robot.joint_index(joint)
        qi = float(q[7 + k])
        span = robot.q_max[k] - qi if dq > 0 else qi - robot.q_min[k]
        # gravity's torque on the moving part along its spin (+: helps)
        helps = sign * grav * dq
        cos = abs(float(a @ w))
        net = stall_torque + min(helps, 0.0)  # a servo gives at most its stall torque
        speed0 = stance_speed if moving == "above" else 0.0
        shift = cos * flywheel_shift(inertia, mass, com_height, net, damping, max(span, 0.0),
                                     armature, delay, speed0)  # fmt: skip
        parts.append(
            {"joint": joint, "inertia_kgm2": inertia, "gravity_torque_nm": helps,
             "range_deg": math.degrees(max(span, 0.0)), "shift_mm": 1e3 * shift}
        )  # fmt: skip
    omega = math.sqrt(GRAVITY / com_height)
    total = sum(p["shift_mm"] for p in parts) * 1e-3
    return {
        "parts": parts,
        "stance_hip_shift_mm": parts[0]["shift_mm"],
        "shift_mm": 1e3 * total,
        "stance_hip_ns": mass * omega * parts[0]["shift_mm"] * 1e-3,
        "ns": mass * omega * total,
        "delay_s": delay,
    }


def push_point(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Where the simulator's push acts (world, at ``q``): the root body's centre of mass
    (:meth:`wbc.sim.simulator.Simulator.push`)."""
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    return np.asarray(data.oMi[1].act(model.inertias[1].lever), dtype=float)


def point_push_bound(
    robot: Robot,
    q: np.ndarray,
    stance: str,
    direction: np.ndarray,
    com_height: float,
    cop_shift: float,
    delay: float = 0.0,
    floor: float = 0.0,
) -> dict[str, Any]:
    """The whole-body bound (N·s) for a horizontal push applied where the simulator applies
    it (:func:`push_point`, ``z_p`` above ``floor``), not at the CoM as the LIPM bounds
    count it. ``cop_shift`` (m): the DCM margin the CoP alone catches (``e − ξ``).

    The push's moment about the stance sole's edge is ``J z_p`` whatever the body does with
    it (the ground's impulse acts at the sole), so it moves ``η = ξ + L / (m h ω₀)`` (the DCM
    with the centroidal angular momentum returned) by ``J z_p / (m h ω₀)``: ``z_p / h`` times
    a push at the CoM; the catch needs ``η(0⁺) − e ≤ (1/(m h)) ∫ e^{−ω₀t} L dt`` (module
    docstring without ``L(0) = 0``). Two figures: ``returned_ns``, the push's own angular
    momentum ``J (z_p − c_z)`` about the CoM given back at once (the parts from rest,
    :func:`hip_strategy_bound`); ``kept_ns``, that momentum kept as the spin of everything
    above the stance hip (its initial speed ``J (z_p − c_z) / I``, the same servo law and
    range after it: its best use, optimistic)."""
    model = robot.model
    data = model.createData()
    c = pin.centerOfMass(model, data, q)
    z_p = float(push_point(robot, q)[2]) - floor
    lever = z_p - (float(c[2]) - floor)
    mass = robot.total_mass
    omega = math.sqrt(GRAVITY / com_height)
    per_ns = z_p / (mass * com_height * omega)  # η's jump per N·s (m)
    rest = hip_strategy_bound(robot, q, stance, direction, com_height, delay=delay)
    inertia = rest["parts"][0]["inertia_kgm2"]

    def margin(impulse: float) -> float:
        b = hip_strategy_bound(robot, q, stance, direction, com_height, delay=delay,
                               stance_speed=impulse * lever / inertia)  # fmt: skip
        return cop_shift + 1e-3 * b["shift_mm"] - impulse * per_ns

    lo, hi = 0.0, 1.0
    while margin(hi) > 0 and hi < 100.0:
        lo, hi = hi, 2.0 * hi
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if margin(mid) > 0 else (lo, mid)
    return {
        "push_height_mm": 1e3 * z_p,
        "above_com_mm": 1e3 * lever,
        "eta_per_ns_mm": 1e3 * per_ns,
        "lipm_per_ns_mm": 1e3 / (mass * omega),
        "angular_momentum_per_ns": lever,
        "returned_ns": (cop_shift + 1e-3 * rest["shift_mm"]) / per_ns,
        "kept_ns": lo,
        "delay_s": delay,
    }
