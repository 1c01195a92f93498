"""The robot and the controller's quantities in meshcat: live, replayed, or exported as HTML.

Scene layout (meshcat paths under ``/meshcat/wbc``)::

    robot/<joint>/<shape>   the URDF's visual primitives, one group per Pinocchio joint
    com, com_ground, com_drop   CoM sphere, its ground projection, the vertical between them
    com_ref, swing_ref      reference markers (drawn when given)
    support                 support polygon (filled + outline) on the ground
    paths/<name>            com, com_ref, swing, swing_ref paths (line segments)
    frames/<frame>          axis triads of the requested frames (soles, torso, ...)
    ground                  a floor with a 5 cm grid

Camera: meshcat 0.3.2 always orbits about the world origin (its OrbitControls target cannot
be set from Python), so the ``wbc`` group is shifted by ``-target`` and the camera is placed
at ``eye - target``; world coordinates inside the scene are unchanged.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import TracebackType

import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
from meshcat.animation import Animation

from ..exceptions import ConfigurationError, TrajectoryError
from ..model import Robot
from ..recording import SUPPORT_LEFT, SUPPORT_RIGHT, Recording
from .geometry import (
    Camera,
    VisualShape,
    fit_camera,
    sole_rectangle,
    support_polygon,
    visual_shapes,
)
from .server import MeshcatServer

ROOT = "wbc"
COLORS = {
    "com": 0xE0115F,
    "com_ref": 0x1E88E5,
    "swing": 0xFDD835,
    "swing_ref": 0x8E24AA,
    "support": 0x2E7D32,
    "ground": 0xF0F0F0,
    "grid": 0xA8A8A8,
}
PATHS = ("com", "com_ref", "swing", "swing_ref")
GRID_STEP = 0.05
_LIFT = 0.0008  # overlays drawn this high above the floor to avoid z-fighting
_Y_TO_Z = np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], dtype=float)


@dataclass
class FrameState:
    """Everything drawn at one instant (world coordinates)."""

    joints: list[np.ndarray]  # 4x4 placement of each drawn joint, in Viewer.joint_ids order
    com: np.ndarray
    com_ref: np.ndarray | None
    swing_ref: np.ndarray | None
    support: np.ndarray  # (k, 2) polygon
    frames: list[np.ndarray]  # 4x4 placement of each shown frame


def _translation(p: Sequence[float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _vector(value: object, what: str, size: int = 3) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    if v.shape != (size,) or not np.all(np.isfinite(v)):
        raise ConfigurationError(f"viewer: {what} must be a finite {size}-vector, got {v!r}")
    return v


class Viewer:
    """A meshcat view of one robot.

    Live mode: call :meth:`update` every control tick with the configuration and optional
    references; drawing is throttled to ``max_rate`` Hz (``None``: draw every call) while
    the paths still record every tick. Replay: :meth:`play` a :class:`~wbc.recording.Recording`
    at real time or slower, or :meth:`show_frame` one of its frames. Export:
    :meth:`load_animation` then :meth:`static_html` (or :func:`export_html`).

    The viewer starts its own meshcat server unless ``server`` is given, and stops it in
    :meth:`close` (also on ``with`` exit).
    """

    def __init__(
        self,
        robot: Robot,
        *,
        server: MeshcatServer | None = None,
        frames: Sequence[str] = (),
        q: np.ndarray | None = None,
        camera: Camera | None = None,
        max_rate: float | None = 30.0,
        trail_length: int = 5000,
    ) -> None:
        if max_rate is not None and not max_rate > 0:
            raise ConfigurationError(f"viewer: max_rate must be positive or None, got {max_rate}")
        if trail_length < 2:
            raise ConfigurationError(f"viewer: trail_length must be >= 2, got {trail_length}")
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.shapes: list[VisualShape] = visual_shapes(robot)
        self.joint_ids: list[int] = sorted({s.joint for s in self.shapes})
        self._sole_ids = (robot.frame_id("l_sole"), robot.frame_id("r_sole"))
        self._sole_rects = tuple(
            sole_rectangle(robot, s, self.shapes) for s in ("l_sole", "r_sole")
        )
        self.max_rate = max_rate
        self._owns_server = server is None
        self.server = MeshcatServer() if server is None else server
        self.vis = self.server.vis
        self.root = self.vis[ROOT]
        self.frame_names: tuple[str, ...] = ()
        self._frame_ids: list[int] = []
        self._trails = {name: deque(maxlen=trail_length) for name in PATHS}
        self._drawn_support: np.ndarray | None = None
        self._visible_markers: dict[str, bool] = {}
        self._pending: FrameState | None = None
        self._last_draw = -np.inf
        self.camera: Camera | None = None
        try:
            q0 = self._default_pose() if q is None else robot.check_configuration(q)
            self._draw_static()
            self.show_frames(frames)
            self._draw(self._state(q0))
            self.set_camera(camera or fit_camera(self.robot_points(q0)))
        except BaseException:
            self.close()
            raise

    def _default_pose(self) -> np.ndarray:
        return self.robot.configuration("stand")

    # ------------------------------------------------------------------ server
    @property
    def url(self) -> str:
        """The page to open in a browser."""
        return self.server.url

    def wait_for_browser(self) -> None:
        """Block until a browser page is connected."""
        self.server.wait_for_browser()

    def close(self) -> None:
        """Stop the meshcat server if this viewer started it."""
        if self._owns_server:
            self.server.close()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def static_html(self) -> str:
        """The current scene (and animation) as one self-contained HTML page."""
        return self.vis.static_html()

    # ------------------------------------------------------------------ static scene
    def _draw_static(self) -> None:
        self.vis["/Grid"].set_property("visible", False)  # metre-scale grid: ours is 5 cm
        self.vis["/Axes"].set_property("visible", False)
        self.root.delete()
        for shape in self.shapes:
            node = self.root["robot"][self._joint_name(shape.joint)][shape.name]
            material = mg.MeshPhongMaterial(color=shape.color_hex, opacity=shape.rgba[3])
            if shape.kind == "box":
                node.set_object(mg.Box(shape.size), material)
                node.set_transform(shape.placement)
            elif shape.kind == "sphere":
                node.set_object(mg.Sphere(shape.size[0]), material)
                node.set_transform(shape.placement)
            else:  # cylinder: meshcat's axis is y, the URDF's is z
                node.set_object(mg.Cylinder(shape.size[1], shape.size[0]), material)
                node.set_transform(shape.placement @ _Y_TO_Z)
        # The CoM is usually inside the body: draw it on top of everything (no depth test).
        com = self.root["com"]
        com.set_object(mg.Sphere(0.007), _on_top(mg.MeshBasicMaterial, color=COLORS["com"]))
        disc = mg.Cylinder(0.001, 0.007)
        flat = _Y_TO_Z @ _translation([0, 0.0005, 0])
        self.root["com_ground"]["disc"].set_object(disc, mg.MeshBasicMaterial(color=COLORS["com"]))
        self.root["com_ground"]["disc"].set_transform(flat)
        drop = self.root["com_drop"]["line"]
        drop.set_object(
            mg.Cylinder(1.0, 0.0008), mg.MeshBasicMaterial(color=COLORS["com"], opacity=0.7)
        )
        drop.set_transform(_Y_TO_Z @ _translation([0, 0.5, 0]))
        for name in ("com_ref", "swing_ref"):
            self.root[name].set_object(
                mg.Sphere(0.0055), _on_top(mg.MeshBasicMaterial, color=COLORS[name], opacity=0.8)
            )
            self._set_visible(name, False)

    def _joint_name(self, joint: int) -> str:
        return "base" if joint == 1 else self.model.names[joint]

    def _set_visible(self, name: str, visible: bool) -> None:
        if self._visible_markers.get(name) != visible:
            self.root[name].set_property("visible", visible)
            self._visible_markers[name] = visible

    def draw_ground(self, center: Sequence[float], size: float) -> None:
        """A ``size`` x ``size`` m floor centred near ``center`` (x, y), with a 5 cm grid."""
        n = max(2, int(np.ceil(size / GRID_STEP)))
        half = 0.5 * n * GRID_STEP
        cx, cy = (round(float(c) / GRID_STEP) * GRID_STEP for c in center[:2])
        ground = self.root["ground"]
        ground["floor"].set_object(
            mg.Box([2 * half, 2 * half, 0.002]), mg.MeshPhongMaterial(color=COLORS["ground"])
        )
        ground["floor"].set_transform(_translation([cx, cy, -0.0011]))
        ticks = np.linspace(-half, half, n + 1)
        segments = []
        for s in ticks:
            segments += [[cx + s, cy - half, 0], [cx + s, cy + half, 0]]
            segments += [[cx - half, cy + s, 0], [cx + half, cy + s, 0]]
        pts = np.asarray(segments, dtype=np.float32).T
        ground["grid"].set_object(
            mg.LineSegments(mg.PointsGeometry(pts), mg.LineBasicMaterial(color=COLORS["grid"]))
        )
        ground["grid"].set_transform(_translation([0, 0, 0.0002]))

    def set_camera(self, camera: Camera, ground: float | None = None) -> None:
        """Aim the browser's camera (and lay the floor around its target, ``ground`` m wide).

        Sets ``/Cameras/default/rotated/<object>`` position (y-up frame: world (x, y, z) is
        (x, z, -y)) and field of view; the scene is shifted so the target is the orbit centre.
        """
        target = np.asarray(camera.target, dtype=float)
        rel = np.asarray(camera.eye, dtype=float) - target
        self.root.set_transform(_translation(-target))
        self.vis["/Cameras/default"].set_transform(np.eye(4))
        cam = self.vis["/Cameras/default/rotated/<object>"]
        cam.set_property("position", [float(rel[0]), float(rel[2]), float(-rel[1])])
        cam.set_property("fov", float(camera.fov))
        size = ground if ground is not None else max(1.0, 2.2 * float(np.linalg.norm(rel[:2])))
        self.draw_ground(target, size)
        self.camera = camera

    def show_frames(self, names: Sequence[str]) -> None:
        """Draw axis triads (x red, y green, z blue, 4 cm) at these frames; () hides all."""
        ids = [self.robot.frame_id(n) for n in names]  # validates the names
        self.root["frames"].delete()
        self.frame_names = tuple(names)
        self._frame_ids = ids
        for name in names:
            triad = mg.triad(0.05)
            triad.material = _on_top(mg.LineBasicMaterial, vertexColors=True)
            self.root["frames"][name].set_object(triad)

    # ------------------------------------------------------------------ kinematics
    def _forward(self, q: np.ndarray) -> np.ndarray:
        """Forward kinematics + frames into self.data; returns the CoM."""
        com = pin.centerOfMass(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        return com.copy()

    def shape_placements(self, q: np.ndarray) -> list[np.ndarray]:
        """World 4x4 placement of every visual shape (``self.shapes`` order) at q."""
        q = self.robot.check_configuration(q)
        self._forward(q)
        return [self.data.oMi[s.joint].homogeneous @ s.placement for s in self.shapes]

    def robot_points(self, q: np.ndarray) -> np.ndarray:
        """World corners of every visual shape at q (for camera fitting)."""
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        pts = []
        for s, M in zip(self.shapes, self.shape_placements(q), strict=True):
            half = 0.5 * np.asarray(s.size if s.kind == "box" else [2 * max(s.size)] * 3)
            pts.append((corners * half) @ M[:3, :3].T + M[:3, 3])
        return np.vstack(pts)

    def _state(
        self,
        q: np.ndarray,
        com: np.ndarray | None = None,
        com_ref: np.ndarray | None = None,
        swing_ref: np.ndarray | None = None,
        support: int | None = None,
        soles: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> FrameState:
        com_fk = self._forward(q)
        joints = [self.data.oMi[j].homogeneous for j in self.joint_ids]
        if soles is None:
            soles = tuple(self.data.oMf[f].homogeneous for f in self._sole_ids)
        poly = support_polygon(soles[0], soles[1], support, *self._sole_rects)
        frames = [self.data.oMf[f].homogeneous for f in self._frame_ids]
        return FrameState(joints, com_fk if com is None else com, com_ref, swing_ref, poly, frames)

    # ------------------------------------------------------------------ drawing
    def _draw(self, state: FrameState) -> None:
        robot = self.root["robot"]
        for j, M in zip(self.joint_ids, state.joints, strict=True):
            robot[self._joint_name(j)].set_transform(M)
        c = state.com
        self.root["com"].set_transform(_translation(c))
        self.root["com_ground"].set_transform(_translation([c[0], c[1], _LIFT]))
        self.root["com_drop"].set_transform(
            _translation([c[0], c[1], 0]) @ np.diag([1.0, 1.0, max(float(c[2]), 1e-4), 1.0])
        )
        for name in ("com_ref", "swing_ref"):
            value = getattr(state, name)
            self._set_visible(name, value is not None)
            if value is not None:
                self.root[name].set_transform(_translation(value))
        self._draw_support(state.support)
        for name, M in zip(self.frame_names, state.frames, strict=True):
            self.root["frames"][name].set_transform(M)

    def _draw_support(self, poly: np.ndarray) -> None:
        drawn = self._drawn_support
        if drawn is not None and drawn.shape == poly.shape and np.allclose(drawn, poly, atol=5e-4):
            return
        self._drawn_support = poly
        node = self.root["support"]
        for child, obj in zip(("fill", "outline"), _polygon_objects(poly), strict=True):
            if obj is None:
                node[child].delete()
            else:
                node[child].set_object(obj)

    def _draw_paths(self, paths: dict[str, np.ndarray]) -> None:
        for name, pts in paths.items():
            obj = _path_object(pts, COLORS[name])
            if obj is None:
                self.root["paths"][name].delete()
            else:
                self.root["paths"][name].set_object(obj)

    # ------------------------------------------------------------------ live mode
    def update(
        self,
        q: np.ndarray,
        *,
        com_ref: np.ndarray | None = None,
        swing: np.ndarray | None = None,
        swing_ref: np.ndarray | None = None,
        support: int | None = None,
        force: bool = False,
    ) -> bool:
        """Show configuration q (one control tick); returns True if the frame was drawn.

        ``com_ref``, ``swing``, ``swing_ref``: world 3-vectors (m); ``support``: a recording
        support code (``None``: soles on the ground). The CoM, its reference and the swing
        foot leave paths. Drawing is skipped when the last one is less than ``1/max_rate``
        s old, unless ``force``; call :meth:`flush` after the last tick.
        """
        q = self.robot.check_configuration(q)
        com_ref = None if com_ref is None else _vector(com_ref, "com_ref")
        swing = None if swing is None else _vector(swing, "swing")
        swing_ref = None if swing_ref is None else _vector(swing_ref, "swing_ref")
        state = self._state(q, com_ref=com_ref, swing_ref=swing_ref, support=support)
        if swing is None and support in (SUPPORT_LEFT, SUPPORT_RIGHT):
            swing = self.data.oMf[self._sole_ids[1 if support == SUPPORT_LEFT else 0]].translation
        for name, value in (("com", state.com), ("com_ref", com_ref), ("swing", swing)):
            if value is not None:
                self._trails[name].append(np.array(value, dtype=float))
        if swing_ref is not None:
            self._trails["swing_ref"].append(swing_ref)
        self._pending = state
        now = time.monotonic()
        if not force and self.max_rate is not None and now - self._last_draw < 1 / self.max_rate:
            return False
        self.flush()
        return True

    def flush(self) -> None:
        """Draw the latest state given to :meth:`update` (and the paths) now."""
        state = self._pending
        if state is None:
            return
        self._draw(state)
        self._draw_paths({k: np.array(v) for k, v in self._trails.items() if len(v) >= 2})
        self._last_draw = time.monotonic()
        self._pending = None

    def clear_paths(self) -> None:
        """Forget and erase the live paths."""
        for trail in self._trails.values():
            trail.clear()
        self.root["paths"].delete()

    # ------------------------------------------------------------------ recordings
    def _check_recording(self, rec: Recording) -> None:
        if tuple(rec.joint_names) != self.robot.joint_names:
            raise TrajectoryError(
                f"recording joints {list(rec.joint_names)} do not match {self.robot.name}'s "
                f"{list(self.robot.joint_names)}"
            )
        for name, width in (("com", 3), ("com_ref", 3), ("swing", 3), ("swing_ref", 3)):
            if name in rec.channels and rec.channels[name].shape[1:] != (width,):
                raise TrajectoryError(
                    f"recording channel {name!r} must be (N, {width}), got {rec[name].shape}"
                )
        for name in ("l_sole", "r_sole"):
            if name in rec.channels and rec.channels[name].shape[1:] != (7,):
                raise TrajectoryError(
                    f"recording channel {name!r} must be (N, 7) xyz + quaternion, "
                    f"got {rec[name].shape}"
                )

    def recording_state(self, rec: Recording, i: int) -> FrameState:
        """What frame ``i`` of a recording shows (channels used where present)."""
        ch = rec.channels
        soles = None
        if "l_sole" in ch and "r_sole" in ch:
            soles = tuple(pin.XYZQUATToSE3(ch[s][i]).homogeneous for s in ("l_sole", "r_sole"))
        support = int(ch["support"][i]) if "support" in ch else None
        return self._state(
            rec.q[i],
            com=np.asarray(ch["com"][i], float) if "com" in ch else None,
            com_ref=np.asarray(ch["com_ref"][i], float) if "com_ref" in ch else None,
            swing_ref=np.asarray(ch["swing_ref"][i], float) if "swing_ref" in ch else None,
            support=support,
            soles=soles,
        )

    def recording_paths(self, rec: Recording) -> dict[str, np.ndarray]:
        """The paths a recording draws: CoM (channel or forward kinematics) and whichever
        of ``com_ref``, ``swing``, ``swing_ref`` it has."""
        paths = {}
        if "com" in rec.channels:
            paths["com"] = np.asarray(rec["com"], float)
        else:
            paths["com"] = np.array([self._forward(q) for q in rec.q])
        for name in ("com_ref", "swing", "swing_ref"):
            if name in rec.channels:
                paths[name] = np.asarray(rec[name], float)
        return paths

    def frame_camera(self, rec: Recording) -> Camera:
        """A camera that sees the robot at the first and last frames and every path."""
        pts = [self.robot_points(rec.q[0]), self.robot_points(rec.q[-1])]
        for p in self.recording_paths(rec).values():
            pts.append(p[np.all(np.isfinite(p), axis=1)])
        return fit_camera(np.vstack(pts))

    def show_recording(self, rec: Recording, camera: Camera | bool = True) -> None:
        """Draw a recording's full paths and its first frame; ``camera=True`` re-aims."""
        self._check_recording(rec)
        self.clear_paths()
        self._draw_paths(self.recording_paths(rec))
        if camera is True:
            self.set_camera(self.frame_camera(rec))
        elif isinstance(camera, Camera):
            self.set_camera(camera)
        self._draw(self.recording_state(rec, 0))

    def show_frame(self, rec: Recording, i: int) -> None:
        """Draw frame ``i`` of a recording (paths are drawn by :meth:`show_recording`)."""
        self._check_recording(rec)
        if not -len(rec) <= i < len(rec):
            raise TrajectoryError(f"frame {i} outside the recording's {len(rec)} frames")
        self._draw(self.recording_state(rec, i % len(rec)))

    def play(
        self,
        rec: Recording,
        speed: float = 1.0,
        *,
        camera: Camera | bool = True,
        on_frame: Callable[[int], None] | None = None,
    ) -> int:
        """Replay a recording at ``speed`` x real time (1 = real time, 0.5 = half speed).

        Frames whose time has already passed are skipped so the replay keeps the clock;
        the last frame is always drawn. Returns the number of frames drawn.
        """
        if not (np.isfinite(speed) and speed > 0):
            raise ConfigurationError(f"replay speed must be a positive number, got {speed}")
        self.show_recording(rec, camera)
        rel = rec.t - rec.t[0]
        start = time.monotonic()
        i, drawn = 0, 0
        while i < len(rec):
            elapsed = (time.monotonic() - start) * speed
            if elapsed < rel[i]:
                time.sleep((rel[i] - elapsed) / speed)
            else:
                i = max(i, int(np.searchsorted(rel, elapsed, side="right")) - 1)
            self._draw(self.recording_state(rec, i))
            drawn += 1
            if on_frame is not None:
                on_frame(i)
            i += 1
        return drawn

    # ------------------------------------------------------------------ export
    def load_animation(
        self, rec: Recording, speed: float = 1.0, fps: float = 30.0, repetitions: int = 1000
    ) -> Animation:
        """Turn a recording into a meshcat animation played in the page (and static HTML).

        Keys are recording frames at least ``1/fps`` s (replay time) apart, plus the last
        frame and the two frames around every support change; key times are
        ``(t - t0) / speed`` (the page interpolates linearly between keys). The support
        polygon changes by switching the visibility of one polygon per support phase.
        """
        if not (np.isfinite(speed) and speed > 0):
            raise ConfigurationError(f"replay speed must be a positive number, got {speed}")
        if not fps > 0:
            raise ConfigurationError(f"fps must be positive, got {fps}")
        self.show_recording(rec)
        rel = (rec.t - rec.t[0]) / speed
        # support phases over every frame: (first frame, polygon)
        phases: list[tuple[int, np.ndarray]] = []
        for i in range(len(rec)):
            poly = self.recording_state(rec, i).support
            last = phases[-1][1] if phases else None
            if last is None or not (
                last.shape == poly.shape and np.allclose(last, poly, atol=5e-4)
            ):
                phases.append((i, poly))
        keys = {0, len(rec) - 1}
        for start, _ in phases[1:]:
            keys.update((start - 1, start))
        previous = 0
        for i in range(1, len(rec)):
            if rel[i] - rel[previous] >= 1 / fps - 1e-9:
                keys.add(i)
                previous = i
        anim = Animation(default_framerate=fps)
        robot_path = f"{ROOT}/robot"
        for i in sorted(keys):
            state = self.recording_state(rec, i)
            with anim.at_frame(self.vis, rel[i] * fps) as frame:
                for j, M in zip(self.joint_ids, state.joints, strict=True):
                    frame[f"{robot_path}/{self._joint_name(j)}"].set_transform(M)
                c = state.com
                frame[f"{ROOT}/com"].set_transform(_translation(c))
                frame[f"{ROOT}/com_ground"].set_transform(_translation([c[0], c[1], _LIFT]))
                drop = frame[f"{ROOT}/com_drop"]
                drop.set_transform(_translation([c[0], c[1], 0]))
                drop.set_property("scale", "vector3", [1.0, 1.0, max(float(c[2]), 1e-4)])
                for name in ("com_ref", "swing_ref"):
                    value = getattr(state, name)
                    if value is not None:
                        frame[f"{ROOT}/{name}"].set_transform(_translation(value))
                for name, M in zip(self.frame_names, state.frames, strict=True):
                    frame[f"{ROOT}/frames/{name}"].set_transform(M)
        # one polygon per support phase, shown only during its phase
        self.root["support"].delete()
        self._drawn_support = None
        for k, (start, poly) in enumerate(phases):
            node = self.root["support_phases"][str(k)]
            for child, obj in zip(("fill", "outline"), _polygon_objects(poly), strict=True):
                if obj is not None:
                    node[child].set_object(obj)
            track = f"{ROOT}/support_phases/{k}"
            switches = [(0.0, k == 0), (rel[start] * fps, True)]
            if k + 1 < len(phases):
                switches.append((rel[phases[k + 1][0]] * fps, False))
            for frame_no, visible in switches[0 if k else 1 :]:
                with anim.at_frame(self.vis, frame_no) as frame:
                    frame[track].set_property("visible", "boolean", visible)
        self.vis.set_animation(anim, play=True, repetitions=repetitions)
        return anim


def _on_top(material: type[mg.GenericMaterial], **kwargs: object) -> mg.GenericMaterial:
    """A material drawn over the robot: transparent (rendered last) without depth test."""
    kwargs.setdefault("opacity", 1.0)
    return material(transparent=True, depthTest=False, **kwargs)


def _polygon_objects(poly: np.ndarray) -> tuple[mg.Object | None, mg.Object | None]:
    """Filled (translucent) and outlined support polygon, lifted above the floor."""
    if poly.shape[0] < 2:
        return None, None
    pts = np.column_stack([poly, np.full(len(poly), _LIFT)]).astype(np.float32)
    outline = mg.LineLoop(mg.PointsGeometry(pts.T), mg.LineBasicMaterial(color=COLORS["support"]))
    if poly.shape[0] < 3:
        return None, outline
    faces = np.array([[0, k, k + 1] for k in range(1, len(poly) - 1)], dtype=np.uint32)
    fill = mg.Mesh(
        mg.TriangularMeshGeometry(pts, faces),
        mg.MeshBasicMaterial(color=COLORS["support"], opacity=0.3),
    )
    return fill, outline


def _path_object(points: np.ndarray, color: int) -> mg.Object | None:
    """Line segments joining consecutive finite points (NaN rows leave gaps)."""
    pts = np.asarray(points, dtype=float)
    ok = np.all(np.isfinite(pts), axis=1)
    pair = ok[:-1] & ok[1:]
    if not np.any(pair):
        return None
    seg = np.empty((2 * int(pair.sum()), 3), dtype=np.float32)
    seg[0::2] = pts[:-1][pair]
    seg[1::2] = pts[1:][pair]
    return mg.LineSegments(mg.PointsGeometry(seg.T), mg.LineBasicMaterial(color=color))


def scene_commands(html: str) -> list[dict]:
    """The meshcat commands embedded in a static page (:meth:`Viewer.static_html`), decoded.

    Each is a dict with ``type`` (``set_object``, ``set_transform``, ``set_property``,
    ``set_animation``) and ``path``; handy to inspect an exported file.
    """
    import base64
    import re

    import umsgpack

    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def export_html(
    robot: Robot,
    rec: Recording,
    path: str,
    *,
    speed: float = 1.0,
    fps: float = 30.0,
    frames: Sequence[str] = (),
    camera: Camera | None = None,
) -> str:
    """Write a recording's replay as one self-contained HTML file; returns the path.

    Uses a short-lived private meshcat server (meshcat builds the page: its JavaScript is
    inlined, so the file works offline); the animation auto-plays and has play/pause/time
    controls under "Animations" in the page's menu.
    """
    from pathlib import Path

    with Viewer(robot, frames=frames, max_rate=None, q=rec.q[0]) as viewer:
        viewer.load_animation(rec, speed=speed, fps=fps)
        if camera is not None:
            viewer.set_camera(camera)
        html = viewer.static_html()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(html, encoding="utf-8")
    return str(out)
