"""Viewer without a browser: geometry, the meshcat server's life cycle and the scene it holds.

The scene is checked by decoding the commands the meshcat server embeds in its static page
(what any browser would receive), not by trusting the viewer's own bookkeeping.
"""

from __future__ import annotations

import os
import socket
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from wbc.exceptions import ConfigurationError, ModelError, TrajectoryError
from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT, Recording
from wbc.viewer.geometry import (
    Camera,
    convex_hull,
    fit_camera,
    polygon_area,
    sole_rectangle,
    support_polygon,
    visual_shapes,
)
from wbc.viewer.scene import Viewer, scene_commands
from wbc.viewer.server import MeshcatServer

# ---------------------------------------------------------------------- geometry (pure)

coords = st.floats(-1.0, 1.0, allow_nan=False, width=32)


@given(arrays(np.float64, st.tuples(st.integers(3, 30), st.just(2)), elements=coords))
def test_convex_hull_contains_every_point_and_is_ccw(points):
    hull = convex_hull(points)
    # every hull vertex is an input point
    for v in hull:
        assert np.any(np.all(np.isclose(points, v), axis=1))
    if len(hull) < 3:
        return
    assert polygon_area(hull) > 0  # counter-clockwise
    edges = np.roll(hull, -1, axis=0) - hull
    for p in points:  # every point on the inner side of every edge
        rel = p - hull
        cross = edges[:, 0] * rel[:, 1] - edges[:, 1] * rel[:, 0]
        assert np.all(cross >= -1e-9)


def test_convex_hull_of_a_square_with_inner_points():
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [0.5, 0], [0.2, 0.7]])
    hull = convex_hull(pts)
    assert len(hull) == 4 and polygon_area(hull) == pytest.approx(1.0)


def test_convex_hull_rejects_bad_input():
    with pytest.raises(ConfigurationError, match="points"):
        convex_hull(np.zeros((3, 3)))
    with pytest.raises(ConfigurationError, match="finite"):
        convex_hull(np.array([[0.0, np.nan], [1, 1]]))


def test_visual_shapes_match_the_urdf(robot):
    """Independent oracle: parse the URDF's <visual> boxes and materials with ElementTree."""
    root = ET.parse(robot.urdf_path).getroot()
    colors = {
        m.get("name"): tuple(float(c) for c in m.find("color").get("rgba").split())
        for m in root.findall("material")
    }
    expected = []
    for link in root.findall("link"):
        for vis in link.findall("visual"):
            size = tuple(float(v) for v in vis.find("geometry/box").get("size").split())
            expected.append((size, colors[vis.find("material").get("name")]))
    shapes = visual_shapes(robot)
    assert len(shapes) == len(expected) == 33
    got = sorted((tuple(np.round(s.size, 6)), tuple(np.round(s.rgba, 4))) for s in shapes)
    want = sorted((tuple(np.round(s, 6)), tuple(np.round(c, 4))) for s, c in expected)
    assert got == want
    assert all(s.kind == "box" for s in shapes)
    head = [s for s in shapes if s.color_hex == 0xD9731A]  # 0.85 0.45 0.1 -> orange
    assert len(head) == 3  # head + two feet


def test_sole_rectangle_is_the_foot_plate(robot):
    # robots/bioloid: foot box 101 x 61 mm centred under the ankle, bottom face = sole plane
    for sole in ("l_sole", "r_sole"):
        rect = sole_rectangle(robot, sole)
        assert rect == pytest.approx((-0.0505, 0.0505, -0.0305, 0.0305), abs=1e-9)
    with pytest.raises(ModelError, match="unknown frame"):
        sole_rectangle(robot, "l_toe")


def test_sole_rectangle_without_a_visual_box_is_the_robots_foot():
    """No visual box at the sole: the robot's own foot (robot.toml [feet] or the collision
    box), centred, never the Bioloid's 101 x 61 mm."""
    from wbc import load_robot

    kokone = load_robot("kokone")
    length, width = kokone.foot_size
    rect = sole_rectangle(kokone, "l_sole", shapes=())
    assert rect == pytest.approx((-length / 2, length / 2, -width / 2, width / 2))
    assert (length, width) != (0.101, 0.061)


def test_support_polygon_modes(robot):
    q = robot.configuration("walk_ready")
    L = robot.frame_placement(q, "l_sole").homogeneous
    R = robot.frame_placement(q, "r_sole").homogeneous
    rect = sole_rectangle(robot, "l_sole")
    foot_area = (rect[1] - rect[0]) * (rect[3] - rect[2])
    left = support_polygon(L, R, SUPPORT_LEFT, rect, rect)
    right = support_polygon(L, R, SUPPORT_RIGHT, rect, rect)
    double = support_polygon(L, R, SUPPORT_DOUBLE, rect, rect)
    # the soles are flat to within a few milliradians at walk_ready (servo tick rounding)
    assert polygon_area(left) == pytest.approx(foot_area, rel=1e-4)
    assert polygon_area(right) == pytest.approx(foot_area, rel=1e-4)
    assert np.all(left[:, 1] > 0) and np.all(right[:, 1] < 0)
    gap = L[1, 3] - R[1, 3] - (rect[3] - rect[2])  # space between the feet
    assert polygon_area(double) == pytest.approx(2 * foot_area + gap * 0.101, rel=0.02)
    # None = soles on the ground: both at walk_ready ...
    assert polygon_area(support_polygon(L, R, None, rect, rect)) == pytest.approx(
        polygon_area(double)
    )
    # ... and only the left one when the right sole is lifted 2 cm
    lifted = R.copy()
    lifted[2, 3] += 0.02
    assert np.allclose(support_polygon(L, lifted, None, rect, rect), left)
    with pytest.raises(ConfigurationError, match="support code"):
        support_polygon(L, R, 7, rect, rect)


def test_camera_projects_target_to_centre_and_up_to_up():
    cam = Camera((0.1, 0.0, 0.15), (0.9, 0.5, 0.4), fov=40)
    uv = cam.project([[0.1, 0.0, 0.15], [0.1, 0.0, 0.30], [0.9 + 0.8, 0.5 + 0.5, 0.4]], 640, 480)
    assert uv[0] == pytest.approx([320, 240])
    assert uv[1, 1] < 240 and uv[1, 0] == pytest.approx(320, abs=1e-6)  # z up is screen up
    assert np.all(np.isnan(uv[2]))  # behind the camera
    # a point at the edge of the vertical field of view lands on the image border
    d = np.linalg.norm(np.subtract(cam.eye, cam.target))
    up = cam.rotation[:, 1]
    edge = np.asarray(cam.target) + up * d * np.tan(np.radians(20))
    assert cam.project(edge, 640, 480)[0, 1] == pytest.approx(0.0, abs=1e-6)
    with pytest.raises(ConfigurationError, match="above"):
        Camera((0, 0, 0), (0, 0, 1))
    with pytest.raises(ConfigurationError, match="fov"):
        Camera((0, 0, 0), (1, 0, 0), fov=0)


def test_fit_camera_keeps_the_robot_in_view(robot):
    shapes = visual_shapes(robot)
    q = robot.configuration("walk_ready")
    pin.framesForwardKinematics(robot.model, robot.data, q)
    centres = np.array([(robot.data.oMi[s.joint].homogeneous @ s.placement)[:3, 3] for s in shapes])
    cam = fit_camera(centres)
    uv = cam.project(centres, 640, 480)
    assert np.all((uv > 0) & (uv < [640, 480]))
    height = uv[:, 1].max() - uv[:, 1].min()
    assert 0.3 * 480 < height < 0.95 * 480  # a 30 cm robot fills a good part of the view


# ---------------------------------------------------------------------- server


def live_children(pid: int | None = None) -> set[int]:
    """Live child processes of a process (default: this one; the meshcat servers we start)."""
    out = set()
    for task in Path(f"/proc/{pid or os.getpid()}/task").iterdir():
        try:
            text = (task / "children").read_text().split()
        except OSError:  # the thread ended between listing and reading
            continue
        out.update(int(p) for p in text)
    return {p for p in out if Path(f"/proc/{p}").exists() and process_state(p) != "Z"}


def process_state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "Z"


def _port_open(url: str) -> bool:
    port = int(url.rsplit(":", 1)[1].split("/")[0])
    with socket.socket() as s:
        s.settimeout(1.0)
        return s.connect_ex(("127.0.0.1", port)) == 0


def _first_free_port(start: int) -> socket.socket:
    """Listen on the first free port >= start (where a fresh meshcat server would go)."""
    for port in range(start, start + 200):
        s = socket.socket()
        try:
            s.bind(("0.0.0.0", port))
            s.listen()
            return s
        except OSError:
            s.close()
    raise RuntimeError(f"no free port from {start}")


def test_server_skips_busy_ports_and_stops():
    """Ports already in use (say a user's meshcat on 7000/6000) are never taken over: we hold
    the ports a fresh server would pick next and check it goes past them."""
    http, zmq_port = _first_free_port(7000), _first_free_port(6000)
    try:
        held = (http.getsockname()[1], zmq_port.getsockname()[1])
        with MeshcatServer() as a, MeshcatServer() as b:
            assert a.url != b.url and a.zmq_url != b.zmq_url
            for srv in (a, b):
                assert srv.url.startswith("http://127.0.0.1:") and srv.url.endswith("/static/")
                port = int(srv.url.rsplit(":", 1)[1].split("/")[0])
                zport = int(srv.zmq_url.rsplit(":", 1)[1])
                assert port != held[0] and zport != held[1]
                assert _port_open(srv.url) and srv.alive
        assert not a.alive and not b.alive
        assert a.proc.returncode is not None
        assert not _port_open(a.url)
        a.close()  # idempotent
    finally:
        http.close()
        zmq_port.close()


# ---------------------------------------------------------------------- scene


@pytest.fixture(scope="module")
def viewer(robot):
    with Viewer(robot, max_rate=None) as v:
        yield v


def _last(cmds, kind, path):
    hits = [c for c in cmds if c["type"] == kind and c["path"] == path]
    assert hits, f"no {kind} at {path}"
    return hits[-1]


def _vertices(cmd):
    """(n, 3) vertex positions of a set_object command's geometry."""
    attr = cmd["object"]["geometries"][0]["data"]["attributes"]["position"]
    return np.frombuffer(attr["array"].data, dtype=np.float32).reshape(-1, 3)


def _matrix(cmd):
    return np.array(cmd["matrix"]).reshape(4, 4).T


def walk_recording(robot, n=31, duration=0.6, dx=0.15):
    """Walk Ready moved along x in three jumps (double, left, right support phases: the feet
    stay put within a phase) with made-up CoM and swing references."""
    q0 = robot.configuration("walk_ready")
    t = np.linspace(0.0, duration, n)
    phase = np.minimum(3 * np.arange(n) // n, 2)
    q = np.tile(q0, (n, 1))
    q[:, 0] += dx * phase / 2
    com = np.array([robot.com(qi) for qi in q])
    support = np.array([SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT], dtype=np.int8)[phase]
    channels = {
        "com": com,
        "com_ref": com + np.array([0.01, 0.0, 0.0]),
        "swing_ref": np.column_stack([q[:, 0], np.full(n, -0.04), np.full(n, 0.02)]),
        "support": support,
    }
    return Recording(t, q, robot.joint_names, channels, {"made_up": True})


def test_live_update_sends_forward_kinematics(robot, viewer):
    q = robot.configuration("walk_ready")
    q[robot.q_index("l_shoulder_roll")] = 0.8
    q[robot.q_index("r_knee")] = 0.5
    com_ref = robot.com(q) + np.array([0.01, 0.0, 0.0])
    viewer.clear_paths()
    assert viewer.update(q, com_ref=com_ref, support=SUPPORT_LEFT, force=True)
    cmds = scene_commands(viewer.static_html())
    pin.framesForwardKinematics(robot.model, robot.data, q)
    for j in viewer.joint_ids:
        name = "base" if j == 1 else robot.model.names[j]
        sent = _matrix(_last(cmds, "set_transform", f"/meshcat/wbc/robot/{name}"))
        assert np.allclose(sent, robot.data.oMi[j].homogeneous, atol=1e-9), name
    com = _matrix(_last(cmds, "set_transform", "/meshcat/wbc/com"))
    assert np.allclose(com[:3, 3], robot.com(q))
    ref = _matrix(_last(cmds, "set_transform", "/meshcat/wbc/com_ref"))
    assert np.allclose(ref[:3, 3], com_ref)
    assert _last(cmds, "set_property", "/meshcat/wbc/com_ref")["value"] is True
    # left single support: the polygon is the left foot plate
    verts = _vertices(_last(cmds, "set_object", "/meshcat/wbc/support/fill"))
    left = robot.frame_placement(q, "l_sole").translation
    assert np.allclose(verts[:, :2].mean(axis=0), left[:2], atol=1e-4)
    # a second tick makes the paths; in left support the swing path follows the right sole
    viewer.update(q, com_ref=com_ref + 0.001, support=SUPPORT_LEFT, force=True)
    cmds = scene_commands(viewer.static_html())
    for name in ("com", "com_ref", "swing"):
        _last(cmds, "set_object", f"/meshcat/wbc/paths/{name}")
    swing = _vertices(_last(cmds, "set_object", "/meshcat/wbc/paths/swing"))
    assert np.allclose(swing, robot.frame_placement(q, "r_sole").translation, atol=1e-6)
    assert not [c for c in cmds if c["path"] == "/meshcat/wbc/paths/swing_ref"]


def test_live_update_is_throttled(robot):
    q = robot.configuration("walk_ready")
    with Viewer(robot, max_rate=0.5) as v:  # at most one draw every 2 s
        assert v.update(q)
        q2 = q.copy()
        q2[0] += 0.05
        assert not v.update(q2)  # too soon: recorded, not drawn
        base = _matrix(
            _last(scene_commands(v.static_html()), "set_transform", "/meshcat/wbc/robot/base")
        )
        assert base[0, 3] == pytest.approx(q[0])
        v.flush()
        base = _matrix(
            _last(scene_commands(v.static_html()), "set_transform", "/meshcat/wbc/robot/base")
        )
        assert base[0, 3] == pytest.approx(q2[0])


def test_failed_start_leaves_no_server(robot):
    before = live_children()
    with pytest.raises(ConfigurationError, match="nq=25"):
        Viewer(robot, q=np.zeros(3))
    assert live_children() == before


def test_bad_input_is_named(robot, viewer):
    with pytest.raises(ConfigurationError, match="nq=25"):
        viewer.update(np.zeros(7))
    with pytest.raises(ConfigurationError, match="com_ref"):
        viewer.update(robot.configuration("walk_ready"), com_ref=[0, 0])
    with pytest.raises(ModelError, match="unknown frame"):
        viewer.show_frames(["l_toe"])
    rec = walk_recording(robot, n=4)
    with pytest.raises(ConfigurationError, match="speed"):
        viewer.play(rec, speed=0)
    other = Recording(rec.t, rec.q, tuple(reversed(robot.joint_names)))
    with pytest.raises(TrajectoryError, match="do not match"):
        viewer.play(other)
    with pytest.raises(TrajectoryError, match="outside"):
        viewer.show_frame(rec, 4)


def test_camera_is_set_for_a_small_robot(robot, viewer):
    viewer.set_camera(fit_camera(viewer.robot_points(robot.configuration("walk_ready"))))
    cmds = scene_commands(viewer.static_html())
    cam = viewer.camera
    props = [c for c in cmds if c["path"] == "/Cameras/default/rotated/<object>"]
    pos = [c["value"] for c in props if c["property"] == "position"][-1]
    rel = np.subtract(cam.eye, cam.target)
    assert np.allclose(pos, [rel[0], rel[2], -rel[1]])  # y-up camera frame
    assert [c["value"] for c in props if c["property"] == "fov"][-1] == cam.fov
    assert 0.5 < np.linalg.norm(rel) < 1.5  # metre-scale default would be ~3 m away
    root = _matrix(_last(cmds, "set_transform", "/meshcat/wbc"))
    assert np.allclose(root[:3, 3], -np.asarray(cam.target))
    assert 0.1 < cam.target[2] < 0.2  # about the robot's mid-height


def test_replay_real_time(robot, viewer):
    rec = walk_recording(robot, n=21, duration=0.4)
    seen = []
    import time

    start = time.monotonic()
    drawn = viewer.play(rec, speed=0.5, on_frame=seen.append)
    elapsed = time.monotonic() - start
    assert elapsed >= 0.4 / 0.5 - 0.02  # never faster than asked
    assert seen[-1] == len(rec) - 1 and seen == sorted(seen) and drawn == len(seen)
    cmds = scene_commands(viewer.static_html())
    base = _matrix(_last(cmds, "set_transform", "/meshcat/wbc/robot/base"))
    assert np.allclose(base, pin.XYZQUATToSE3(rec.q[-1, :7]).homogeneous)
    for name in ("com", "com_ref", "swing_ref"):
        _last(cmds, "set_object", f"/meshcat/wbc/paths/{name}")
    assert not [c for c in cmds if c["path"] == "/meshcat/wbc/paths/swing"]  # not recorded


def test_animation_export_embeds_every_frame(robot, tmp_path):
    from wbc.viewer.scene import export_html

    rec = walk_recording(robot, n=31, duration=0.6)
    path = export_html(robot, rec, tmp_path / "run.html", fps=30)
    html = Path(path).read_text(encoding="utf-8")
    assert "<script src" not in html and "MeshCat.Viewer" in html  # JS inlined: works offline
    cmds = scene_commands(html)
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in anim["animations"]}
    base = clips["/meshcat/wbc/robot/base"]
    tracks = {t["name"]: t for t in base["tracks"]}
    keys = tracks[".position"]["keys"]
    # 31 frames 20 ms apart: keys >= 1/30 s apart (every other frame), plus both frames
    # around each support change (frames 10|11 and 20|21), so the jumps stay sharp
    expected = sorted(set(range(0, 31, 2)) | {10, 11, 20, 21})
    assert [k["time"] / base["fps"] for k in keys] == pytest.approx(rec.t[expected])
    for key, i in zip(keys, expected, strict=True):
        assert np.allclose(key["value"], rec.q[i, :3])
    # three support phases (double, left, right): one polygon each, shown in turn
    phases = sorted(p for p in clips if p.startswith("/meshcat/wbc/support_phases/"))
    assert len(phases) == 3
    fps = clips[phases[0]]["fps"]

    def shown(track, t):  # discrete track: the last key at or before t
        keys = sorted(track["keys"], key=lambda key: key["time"])
        return [key["value"] for key in keys if key["time"] / fps <= t + 1e-9][-1]

    for k, p in enumerate(phases):
        (vis,) = clips[p]["tracks"]
        assert vis["name"] == ".visible" and vis["type"] == "boolean"
        for i in range(len(rec)):  # phase k is shown exactly while the recording is in it
            t = rec.t[i] - 0.0001 if i == len(rec) - 1 else rec.t[i]
            assert shown(vis, t) is (min(3 * i // len(rec), 2) == k), (k, i)
    # each phase's polygon is that phase's support: double, then left foot, then right foot
    for k, side in ((1, 1.0), (2, -1.0)):
        fill = _last(cmds, "set_object", f"/meshcat/wbc/support_phases/{k}/fill")
        verts = _vertices(fill)
        assert np.all(side * verts[:, 1] > 0.005)
