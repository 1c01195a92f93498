"""The viewer as a user sees it: headless Chromium renders the page and we read its pixels.

Needs Debian's ``chromium`` (``apt-get install chromium``; playwright drives it through
``executable_path``, its own browser downloads are never used). WebGL renders in software
(SwiftShader). Each check finds the robot's orange parts (head and feet, URDF colour
0.85 0.45 0.1) in a screenshot and compares where they are with where the viewer's camera
model projects those boxes.
"""

from __future__ import annotations

import io
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_viewer import walk_recording

from wbc.viewer.geometry import Camera

# WBC_CHROMIUM names another Chromium binary (or a missing one, to see the skip)
CHROMIUM = os.environ.get("WBC_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--headless",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
W, H = 640, 480
ORANGE = (0.85, 0.45, 0.1)
TIMEOUT_MS = 20_000
# one worker runs them all (under pytest-xdist): one Chromium and one viewer server
pytestmark = pytest.mark.xdist_group("browser")

if not Path(CHROMIUM).is_file():
    pytest.skip(
        f"chromium not installed ({CHROMIUM}): `apt-get install chromium` to run the browser "
        "tests of the viewer",
        allow_module_level=True,
    )
sync_playwright = pytest.importorskip("playwright.sync_api").sync_playwright
Image = pytest.importorskip("PIL.Image")

# all the robot's meshes are in the scene (the page loads them asynchronously)
SCENE_READY = """(n) => { let k = 0;
    const robot = viewer.scene.getObjectByName('robot');
    if (robot) robot.traverse(o => { if (o.isMesh) k++; });
    return k >= n; }"""
TWO_FRAMES = "() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))"


@pytest.fixture(scope="module")
def browser():
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, timeout=TIMEOUT_MS)
        yield b
        b.close()


@pytest.fixture()
def page(browser):
    pg = browser.new_page(viewport={"width": W, "height": H})
    pg.set_default_timeout(TIMEOUT_MS)
    yield pg
    pg.close()


@pytest.fixture(scope="module")
def viewer(robot):
    from wbc.viewer.scene import Viewer

    with Viewer(robot, max_rate=None) as v:
        yield v


def screenshot(page) -> np.ndarray:
    page.evaluate(TWO_FRAMES)
    return np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)


def orange_mask(img: np.ndarray) -> np.ndarray:
    """Pixels of the head/feet colour, lit or in shade (r > g > b, both ratios large)."""
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > 90) & (r > 1.5 * g) & (g > 1.5 * b) & (g > 25)


def orange_boxes(viewer, q) -> list[np.ndarray]:
    """World corners (8, 3) of each orange box at q."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    out = []
    for s, M in zip(viewer.shapes, viewer.shape_placements(q), strict=True):
        if np.allclose(s.rgba[:3], ORANGE, atol=0.01):
            out.append((corners * 0.5 * np.asarray(s.size)) @ M[:3, :3].T + M[:3, 3])
    assert len(out) == 3, "expected the head and two feet to be orange"
    return out


def check_robot_drawn(img: np.ndarray, viewer, camera: Camera, q) -> np.ndarray:
    """The orange boxes are drawn where the camera projects them; returns their centroid."""
    mask = orange_mask(img)
    boxes = [camera.project(c, W, H) for c in orange_boxes(viewer, q)]
    for uv in boxes:  # each box: its projected outline holds a good share of orange pixels
        lo, hi = np.floor(uv.min(axis=0)).astype(int), np.ceil(uv.max(axis=0)).astype(int)
        region = mask[max(lo[1], 0) : hi[1] + 1, max(lo[0], 0) : hi[0] + 1]
        area = (hi[0] - lo[0]) * (hi[1] - lo[1])
        assert region.sum() > 0.3 * area, f"box at {lo}..{hi} not drawn ({region.sum()} px)"
    allpts = np.vstack(boxes)
    lo, hi = allpts.min(axis=0) - 6, allpts.max(axis=0) + 6
    vs, us = np.nonzero(mask)
    inside = (us >= lo[0]) & (us <= hi[0]) & (vs >= lo[1]) & (vs <= hi[1])
    assert mask.sum() > 400, f"only {mask.sum()} orange pixels"
    assert inside.mean() > 0.97, "orange pixels outside the robot's projected outline"
    return np.array([us.mean(), vs.mean()])


def test_still_pose_is_drawn(robot, viewer, page, tmp_path):
    q = robot.configuration("walk_ready")
    viewer.update(q, force=True)
    page.goto(viewer.url)
    page.wait_for_function(SCENE_READY, arg=len(viewer.shapes))
    img = screenshot(page)
    Image.fromarray(img.astype(np.uint8)).save(tmp_path / "still.png")
    centroid = check_robot_drawn(img, viewer, viewer.camera, q)
    # the 30 cm robot is centred and fills a good part of the view
    assert abs(centroid[0] - W / 2) < 0.15 * W
    uv = viewer.camera.project(viewer.robot_points(q), W, H)
    assert 0.35 * H < uv[:, 1].max() - uv[:, 1].min() < 0.95 * H
    # the floor is visible below the robot: light grey pixels in the bottom rows
    bottom = img[-40:]
    assert np.mean(np.all(bottom > 200, axis=-1)) > 0.3


def test_replay_frame_moves_the_robot(robot, viewer, page, tmp_path):
    rec = walk_recording(robot, n=21, duration=0.4, dx=0.15)
    viewer.show_recording(rec)  # aims the camera at the whole run, shows frame 0
    camera = viewer.camera
    page.goto(viewer.url)
    page.wait_for_function(SCENE_READY, arg=len(viewer.shapes))
    first = screenshot(page)
    c0 = check_robot_drawn(first, viewer, camera, rec.q[0])
    viewer.play(rec, speed=1.0, camera=False)  # live page follows the replay
    last = screenshot(page)
    Image.fromarray(last.astype(np.uint8)).save(tmp_path / "replay_last.png")
    c1 = check_robot_drawn(last, viewer, camera, rec.q[-1])
    # the robot moved on screen as the camera model predicts for a 15 cm step along x
    expected = camera.project(rec.q[-1, :3], W, H)[0] - camera.project(rec.q[0, :3], W, H)[0]
    assert np.linalg.norm(c1 - c0) > 30
    assert np.linalg.norm((c1 - c0) - expected) < 0.25 * np.linalg.norm(expected)


def test_static_export_plays_offline(robot, viewer, page, tmp_path):
    from wbc.viewer.scene import export_html

    rec = walk_recording(robot, n=31, duration=0.6, dx=0.15)
    path = Path(export_html(robot, rec, tmp_path / "run.html"))
    camera = viewer.frame_camera(rec)  # export_html aims its camera the same way
    remote = []

    def block(route):
        remote.append(route.request.url)
        route.abort()

    page.route("http*://**", block)  # offline: anything not file:// or data: fails
    page.goto(path.as_uri())
    page.wait_for_function(SCENE_READY, arg=len(viewer.shapes))
    page.wait_for_function("() => viewer.animator.actions.length > 0")
    duration = page.evaluate("() => viewer.animator.duration")
    assert duration == pytest.approx(0.6, abs=1e-3)
    page.evaluate("() => { viewer.animator.pause(); viewer.animator.seek(0); }")
    start = screenshot(page)
    c0 = check_robot_drawn(start, viewer, camera, rec.q[0])
    page.evaluate(f"() => viewer.animator.seek({duration})")
    end = screenshot(page)
    Image.fromarray(end.astype(np.uint8)).save(tmp_path / "export_end.png")
    c1 = check_robot_drawn(end, viewer, camera, rec.q[-1])
    expected = camera.project(rec.q[-1, :3], W, H)[0] - camera.project(rec.q[0, :3], W, H)[0]
    assert np.linalg.norm((c1 - c0) - expected) < 0.25 * np.linalg.norm(expected)
    assert remote == []
