"""``wbc view``: prints its URL, exports, and always stops its meshcat server."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest
from test_viewer import live_children, process_state, walk_recording

from wbc.cli import main
from wbc.viewer.scene import scene_commands

REPO = Path(__file__).resolve().parent.parent


def _port_open(url: str) -> bool:
    port = int(url.rsplit(":", 1)[1].split("/")[0])
    with socket.socket() as s:
        s.settimeout(1.0)
        return s.connect_ex(("127.0.0.1", port)) == 0


def test_export_writes_a_replay_and_leaves_no_server(robot, tmp_path, capsys):
    rec_path = walk_recording(robot, n=11, duration=0.2).save(tmp_path / "run.npz")
    out = tmp_path / "run.html"
    before = live_children()
    assert main(["view", str(rec_path), "--export", str(out), "--no-browser", "--fps", "50"]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    assert live_children() == before  # the export's private server is gone
    cmds = scene_commands(out.read_text(encoding="utf-8"))
    assert [c for c in cmds if c["type"] == "set_animation"]


def test_export_of_a_still_pose(tmp_path):
    out = tmp_path / "pose.html"
    assert main(["view", "--pose", "zero", "--export", str(out), "--frames"]) == 0
    cmds = scene_commands(out.read_text(encoding="utf-8"))
    assert not [c for c in cmds if c["type"] == "set_animation"]
    frames = {c["path"] for c in cmds if c["path"].startswith("/meshcat/wbc/frames/")}
    assert frames == {f"/meshcat/wbc/frames/{f}" for f in ("l_sole", "r_sole", "torso")}


def test_replay_once_without_waiting(robot, tmp_path, capsys):
    rec_path = walk_recording(robot, n=11, duration=0.2).save(tmp_path / "run.npz")
    before = live_children()
    start = time.monotonic()
    code = main(["view", str(rec_path), "--no-browser", "--no-wait", "--speed", "0.5"])
    assert code == 0 and time.monotonic() - start >= 0.4 - 0.02
    out = capsys.readouterr().out
    assert "meshcat viewer at http://127.0.0.1:" in out and "replayed 0.20 s" in out
    assert live_children() == before


def test_bad_arguments_are_named(tmp_path, capsys):
    assert main(["view", str(tmp_path / "missing.npz"), "--no-browser"]) == 2
    assert "recording not found" in capsys.readouterr().err
    assert main(["view", "--pose", "crouch", "--no-browser"]) == 2
    assert "unknown configuration 'crouch'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:  # argparse: wbc.cli.number, one line
        main(["view", "--speed", "0", "--no-browser"])
    assert exit_.value.code == 2
    assert "--speed: must be a finite number in (0, 100]" in capsys.readouterr().err
    assert main(["view", "--frames", "l_toe", "--no-browser"]) == 2
    assert "unknown frame 'l_toe'" in capsys.readouterr().err


def _sigint_default() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_stops_the_server(robot, tmp_path, sig):
    """Serving (waiting for a browser before a replay): a signal ends it and its server."""
    rec_path = walk_recording(robot, n=11, duration=0.2).save(tmp_path / "run.npz")
    proc = subprocess.Popen(
        [sys.executable, "-m", "wbc.cli", "view", str(rec_path), "--no-browser"],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # A background job of a non-interactive shell inherits SIGINT ignored, and Python then
        # installs no KeyboardInterrupt handler: give the child the disposition a terminal gives.
        preexec_fn=_sigint_default,
    )
    try:
        line = proc.stdout.readline()  # blocks until the URL is printed (or the process dies)
        assert "meshcat viewer at " in line, line + proc.stderr.read()
        url = line.split(" at ", 1)[1].strip()
        with urllib.request.urlopen(url, timeout=5) as page:
            assert b"MeshCat" in page.read()
        assert "waiting for a browser" in proc.stdout.readline()
        servers = live_children(proc.pid)
        assert len(servers) == 1
        proc.send_signal(sig)
        assert proc.wait(timeout=10) == 0
        assert "stopped" in proc.stderr.read()
        deadline = time.monotonic() + 5
        while _port_open(url) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _port_open(url), "the meshcat server outlived wbc view"
        assert all(process_state(p) == "Z" for p in servers)  # gone (no process, or not reaped)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()
