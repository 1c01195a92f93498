"""The simulated robot: MuJoCo physics, the servo law every step, faults and state.

The servo law is the robot's (:func:`wbc.sim.actuator.nominal_servo`): the AX-12A
(:class:`~wbc.sim.actuator.ServoArray`, goals in Dynamixel ticks) or hobby PWM servos on an
SSC-32 (:class:`~wbc.sim.actuator.HobbyServoArray`, goals in µs of pulse width).

Configurations use wbc's convention (Pinocchio free flyer: ``[x, y, z, qx, qy, qz, qw,
joints...]`` in the robot's joint order); MuJoCo's own ``qpos`` (quaternion ``w`` first, its
joint order) stays inside this module.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError
from ..model import Robot
from ..servo_map import ServoSettings
from . import mujoco_module
from .actuator import HobbyServoArray, HobbyServoParams, ServoArray, ServoParams, nominal_servo
from .model import ModelParams, build_model, site_names

#: a servo fault the simulation can inject: stops answering (``silent``) or the overload bit
FAULT_KINDS = ("silent", "overload")


class Simulation:
    """One simulated robot on a floor.

    ``step()`` computes the servo torques from the state (vectorised over joints), sets them
    as the actuators' controls and advances MuJoCo by one timestep; ``advance(duration)``
    repeats it. Goals are written in ticks (:meth:`write_goals`) as on the bus.
    """

    def __init__(
        self,
        robot: Robot,
        model_params: ModelParams | None = None,
        servo_params: ServoParams | HobbyServoParams | None = None,
        settings: ServoSettings | None = None,
    ) -> None:
        self.mj = mujoco_module()
        self.robot = robot
        mp = model_params or ModelParams()
        if servo_params is None:

            def mean(v):
                return None if v is None else float(np.mean(v))

            servo_params = nominal_servo(
                robot, settings, damping=mean(mp.damping), armature=mean(mp.armature),
                friction_loss=mean(mp.friction_loss),
            )  # fmt: skip
        self.servo_params = servo_params
        self.hobby = isinstance(servo_params, HobbyServoParams)
        self.settings = None if self.hobby else (settings or robot.servo_map.settings)
        self.model_params = mp.resolved(servo_params)
        self.model = build_model(robot, self.model_params)
        self.data = self.mj.MjData(self.model)
        self._dt = float(self.model.opt.timestep)
        m, mj = self.model, self.mj
        jid = [mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, n) for n in robot.joint_names]
        self.qadr = np.array([m.jnt_qposadr[j] for j in jid])
        self.vadr = np.array([m.jnt_dofadr[j] for j in jid])
        self.act = np.array(
            [mj.mj_name2id(m, mj.mjtObj.mjOBJ_ACTUATOR, n) for n in robot.joint_names]
        )
        self.damping = m.dof_damping[self.vadr].copy()
        self._q_index = _as_slice(self.qadr)  # a slice when contiguous: faster per step
        self._ctrl_index = _as_slice(self.act)
        self.site = {
            n: mj.mj_name2id(m, mj.mjtObj.mjOBJ_SITE, n) for n in (*site_names(robot), "imu")
        }
        self.root = int(m.jnt_bodyid[mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, "base")])
        self.floor = mj.mj_name2id(m, mj.mjtObj.mjOBJ_GEOM, "floor")
        if self.hobby:
            from .actuator import pwm_map

            self.pwm_map = pwm_map(robot)
            self.servos = HobbyServoArray(self.pwm_map.codec(), self.servo_params, self._dt)
        elif isinstance(self.servo_params, ServoParams):
            self.servos = ServoArray(robot.servo_map, self.servo_params)
        else:  # the XM430 (wbc.sim.xm430)
            from .xm430 import XServoArray

            self.servos = XServoArray(robot.servo_map, self.servo_params)
        self.silent = np.zeros(robot.n_joints, dtype=bool)
        self.steps = 0
        self.peak_torque = np.zeros(robot.n_joints)  # max |τ| since the last reset_peak()
        self._push: tuple[float, float, np.ndarray] | None = None
        #: s between a goal write and the servos acting on it (a plant's bus / firmware
        #: latency; any value, not only whole control ticks: :meth:`write_goals`)
        self.goal_delay = 0.0
        self._queued: deque[tuple[float, np.ndarray, float | None]] = deque()
        self.reset(robot.configuration("stand"))

    # ------------------------------------------------------------------ state
    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def dt(self) -> float:
        return self._dt

    def reset(self, q: np.ndarray, torque: bool = False) -> None:
        """Put the robot at configuration ``q`` (wbc convention), at rest; goals there."""
        q = self.robot.check_configuration(q)
        mj = self.mj
        mj.mj_resetData(self.model, self.data)
        self.data.qpos[:3] = q[:3]
        self.data.qpos[3:7] = [q[6], q[3], q[4], q[5]]
        self.data.qpos[self.qadr] = q[7:]
        mj.mj_forward(self.model, self.data)
        self.servos.reset(q[7:])
        self.silent[:] = False
        self.set_torque(torque)
        self.steps = 0
        self.peak_torque[:] = 0.0
        self._push = None
        self._queued.clear()
        self.data.xfrc_applied[:] = 0.0

    def q(self) -> np.ndarray:
        """The configuration (wbc convention)."""
        qp = self.data.qpos
        return np.concatenate([qp[:3], [qp[4], qp[5], qp[6], qp[3]], qp[self.qadr]])

    def robot_feet(self) -> tuple[str, str]:
        """Names of the bodies carrying the left and right soles."""
        m, mj = self.model, self.mj
        return tuple(
            mj.mj_id2name(m, mj.mjtObj.mjOBJ_BODY, int(m.site_bodyid[self.site[s]]))
            for s in ("l_sole", "r_sole")
        )

    def joint_velocities(self) -> np.ndarray:
        return self.data.qvel[self.vadr].copy()

    def base_rotation(self) -> np.ndarray:
        return self.data.xmat[self.root].reshape(3, 3).copy()

    def site_pose(self, name: str) -> pin.SE3:
        """World placement of a site (``torso``, ``l_sole``, ``r_sole``, hands, ``imu``)."""
        k = self.site[name]
        return pin.SE3(self.data.site_xmat[k].reshape(3, 3).copy(), self.data.site_xpos[k].copy())

    def com(self) -> np.ndarray:
        """Whole-body centre of mass (world)."""
        return self.data.subtree_com[self.root].copy()

    def joint_torques(self) -> np.ndarray:
        """Servo torques of the last step (N·m, joint direction)."""
        return self.servos.torque.copy()

    def _floor_contacts(self):
        """Each floor contact: (the MuJoCo contact, its force in the contact frame (6: normal,
        two tangents, then torsion and rolling), the other geom's body)."""
        mj, m, d = self.mj, self.model, self.data
        for i in range(d.ncon):
            c = d.contact[i]
            if self.floor not in (c.geom1, c.geom2):
                continue
            f6 = np.zeros(6)
            mj.mj_contactForce(m, d, i, f6)
            other = c.geom2 if c.geom1 == self.floor else c.geom1
            yield c, f6, int(m.geom_bodyid[other])

    def contacts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Floor contacts: points (k, 3), normal forces (k,) and the body of each point."""
        pts, fz, body = [], [], []
        for c, f6, b in self._floor_contacts():
            pts.append(c.pos.copy())
            fz.append(f6[0])
            body.append(b)
        if not pts:
            return np.zeros((0, 3)), np.zeros(0), np.zeros(0, int)
        return np.array(pts), np.array(fz), np.array(body)

    def floor_wrench(self, body: int, point: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """The floor's wrench on ``body`` (world axes): force F (3), moment M (3) about
        ``point`` (``Σ (p_i − point) × f_i`` plus the contacts' torsion, condim ≥ 4), and the
        largest yaw moment its friction could resist about the contacts' centre of pressure,
        ``Σ μ_i f_n,i |p_i − cop|`` (each point sliding on a circle about it)."""
        pts, fs, fn, mu, torsion = [], [], [], [], np.zeros(3)
        for c, f6, b in self._floor_contacts():
            if b != body:
                continue
            frame = c.frame.reshape(3, 3)  # rows: the normal (floor → body's geom), tangents
            sign = 1.0 if c.geom1 == self.floor else -1.0
            pts.append(c.pos.copy())
            fs.append(sign * (frame.T @ f6[:3]))
            fn.append(f6[0])
            mu.append(c.friction[0])
            if c.dim >= 4:
                torsion += sign * f6[3] * frame[0]
        if not pts:
            return np.zeros(3), np.zeros(3), 0.0
        P, F, N = np.array(pts), np.array(fs), np.array(fn)
        M = np.cross(P - point, F).sum(axis=0) + torsion
        cop = (P * N[:, None]).sum(axis=0) / max(N.sum(), 1e-12)
        reach = np.linalg.norm((P - cop)[:, :2], axis=1)
        return F.sum(axis=0), M, float((np.array(mu) * N * reach).sum())

    def cop(self) -> np.ndarray | None:
        """Centre of pressure on the floor (x, y) from the contact forces; None in the air."""
        pts, fz, _ = self.contacts()
        total = fz.sum()
        if total <= 1e-9:
            return None
        return (pts[:, :2] * fz[:, None]).sum(axis=0) / total

    # ------------------------------------------------------------------ servos
    def set_torque(self, enabled: bool | np.ndarray) -> None:
        """Torque on/off (all servos or a mask); the back-EMF brake only acts when on.
        Hobby servos: off stops their pulses (``#L``); on changes nothing (they are driven
        from the first pulse on)."""
        if self.hobby:
            off = ~np.broadcast_to(np.asarray(enabled, dtype=bool), (self.robot.n_joints,))
            if np.any(off):
                self.servos.off(off)
            self._update_damping()
            return
        self.servos.enabled[:] = enabled
        self._update_damping()

    def _update_damping(self) -> None:
        self.model.dof_damping[self.vadr] = np.where(self.servos.enabled, self.damping, 0.0)

    def set_speed_ticks(self, ticks_per_s: float | np.ndarray) -> None:
        """The moving-speed cap of every servo (ticks/s; AX-12A only)."""
        self._require_ax("a moving-speed register")
        self.servos.speed[:] = ticks_per_s

    def _require_ax(self, what: str) -> None:
        if self.hobby:
            raise ConfigurationError(
                f"{self.robot.name}'s hobby servos have no {what} (AX-12A only)"
            )

    def write_goals(self, ticks: np.ndarray, move_ms: float | None = None) -> None:
        """Goal positions (model order; AX-12A ticks, or hobby servos' pulse widths in µs
        reaching the board as one group move of ``move_ms``); a silent servo ignores its
        goal. With :attr:`goal_delay` > 0 the servos act on it that many seconds later (at the
        first physics step that starts at or after then)."""
        ticks = np.asarray(ticks, dtype=float)
        if self.goal_delay > 0:
            self._queued.append((self.time + self.goal_delay, ticks.copy(), move_ms))
            return
        self._apply_goals(ticks, move_ms)

    def _apply_goals(self, ticks: np.ndarray, move_ms: float | None) -> None:
        if self.hobby:
            self.servos.write(ticks, move_ms)
            return
        self.servos.goal[:] = np.where(self.silent, self.servos.goal, ticks)

    def present_ticks(self) -> np.ndarray:
        """Present Position of every servo (quantised ticks; AX-12A only)."""
        self._require_ax("position feedback")
        return self.servos.present(self.data.qpos[self.qadr])

    def inject(self, kind: str, index: int) -> None:
        """A servo fault: ``silent`` (stops answering and ignores goals) or ``overload``."""
        if kind not in FAULT_KINDS:
            raise ConfigurationError(f"unknown fault {kind!r}; choose from {FAULT_KINDS}")
        if not 0 <= index < self.robot.n_joints:
            raise ConfigurationError(
                f"fault: servo index {index} outside 0..{self.robot.n_joints - 1}"
            )
        if kind == "silent":
            self.silent[index] = True
            if self.hobby:  # its signal wire is cut: no more pulses, the servo goes limp
                self.servos.silent[index] = True
        else:
            self._require_ax("error bits (an overload fault)")
            self.servos.error[index] |= 0x20

    # ------------------------------------------------------------------ stepping
    def push(self, force: Sequence[float], duration: float, start: float | None = None) -> None:
        """A force (N, world) on the root body's CoM for ``duration`` s from ``start``
        (default: now); the impulse is ``force · duration`` (N·s)."""
        t0 = self.time if start is None else float(start)
        self._push = (t0, t0 + float(duration), np.asarray(force, dtype=float).copy())

    def reset_peak(self) -> np.ndarray:
        """The peak |torque| per joint since the last call, and start a new window."""
        out = self.peak_torque.copy()
        self.peak_torque[:] = 0.0
        return out

    def step(self) -> None:
        """One physics step: servo law, then MuJoCo."""
        d = self.data
        servos = self.servos
        queued = self._queued
        while queued and queued[0][0] <= d.time + 1e-9:
            _, ticks, move_ms = queued.popleft()
            self._apply_goals(ticks, move_ms)
        tau = servos.law(d.qpos[self._q_index], self._dt)
        if self.hobby and servos.powered_changed:  # pulses started/stopped: the motor brake
            servos.powered_changed = False
            self._update_damping()
        d.ctrl[self._ctrl_index] = tau
        np.maximum(self.peak_torque, np.abs(tau), out=self.peak_torque)
        push = self._push
        if push is not None:
            on = push[0] - 1e-9 <= d.time < push[1] - 1e-9
            d.xfrc_applied[self.root, :3] = push[2] if on else 0.0
        self.mj.mj_step(self.model, d)
        if push is not None and d.time >= push[1] - 1e-9:
            d.xfrc_applied[self.root, :3] = 0.0
            self._push = None
        self.steps += 1

    def advance(self, duration: float) -> None:
        """Step until ``duration`` seconds later (whole timesteps)."""
        self.advance_to(self.time + duration)

    def advance_to(self, t: float) -> None:
        """Step while the next step ends at or before ``t``."""
        n = math.floor((t - self.data.time) / self._dt + 1e-6)
        step = self.step
        for _ in range(n):
            step()


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as a slice if it is a contiguous increasing range."""
    if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0] + index.size))
    return index
