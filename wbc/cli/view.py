"""``wbc view``: show the robot at a pose, or replay a recording, in meshcat.

Examples::

    wbc view                              # Walk Ready pose; serve until Ctrl-C
    wbc view run.npz --speed 0.5          # wait for a browser, replay at half speed
    wbc view run.npz --export run.html    # write a self-contained replay page and exit
    wbc view run.npz --no-browser --no-wait --speed 1   # replay once, then quit

The viewer runs a private meshcat server on the first free ports from 7000 (HTTP) and
6000 (ZeroMQ); it is stopped on exit, Ctrl-C and SIGTERM.
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
import time
import webbrowser
from collections.abc import Iterator

from ..exceptions import WbcError
from ..model import load_robot, print_notes
from ..recording import Recording
from .options import add_robot_argument, number

DEFAULT_FRAMES = ("l_sole", "r_sole", "torso")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", nargs="?", help="recording (.npz) to replay")
    add_robot_argument(parser)
    parser.add_argument(
        "--pose", default="stand", help="named configuration shown without a recording"
    )
    parser.add_argument(
        "--speed",
        type=number(0, 100, lo_open=True),
        default=1.0,
        help="replay speed (1 = real time, 0.5 = half)",
    )
    parser.add_argument("--loop", action="store_true", help="replay until Ctrl-C")
    parser.add_argument(
        "--frames",
        nargs="*",
        metavar="FRAME",
        help=f"draw axis triads at these frames (no names: {' '.join(DEFAULT_FRAMES)})",
    )
    parser.add_argument("--export", metavar="HTML", help="write a self-contained HTML page")
    parser.add_argument(
        "--fps", type=number(0, 240, lo_open=True), default=30.0, help="--export frame rate"
    )
    parser.add_argument(
        "--serve", action="store_true", help="keep serving the live viewer after --export"
    )
    parser.add_argument("--no-browser", action="store_true", help="do not open a web browser")
    parser.add_argument(
        "--no-wait",
        action="store_true",
        help="do not wait for a browser before replaying; exit when done instead of serving",
    )


@contextlib.contextmanager
def _terminate_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM/SIGHUP into KeyboardInterrupt so ``finally`` blocks stop the server."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: object) -> None:
        raise KeyboardInterrupt(signal.Signals(signum).name)

    previous = {s: signal.signal(s, handler) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def run(args: argparse.Namespace) -> int:
    # Imported here so `wbc --help` works without meshcat installed.
    from ..viewer.scene import Viewer, export_html

    if not (args.speed > 0 and args.speed < float("inf")):
        print(f"wbc view: --speed must be a positive number, got {args.speed}", file=sys.stderr)
        return 2
    frames = None if args.frames is None else (tuple(args.frames) or DEFAULT_FRAMES)
    try:
        robot = load_robot(args.robot)
        print_notes(robot, "view")
        rec = Recording.load(args.recording) if args.recording else None
        q = rec.q[0] if rec is not None else robot.configuration(args.pose)
        for name in frames or ():
            robot.frame_id(name)
    except WbcError as exc:
        print(f"wbc view: {exc}", file=sys.stderr)
        return 2

    viewer = None
    with _terminate_as_interrupt():
        try:
            if args.export:
                if rec is not None:
                    path = export_html(
                        robot, rec, args.export, speed=args.speed, fps=args.fps, frames=frames or ()
                    )
                else:
                    with Viewer(robot, q=q, frames=frames or (), max_rate=None) as still:
                        html = still.static_html()
                    with open(args.export, "w", encoding="utf-8") as f:
                        f.write(html)
                    path = args.export
                print(f"wbc view: wrote {path}", flush=True)
                if not args.serve:
                    return 0
            viewer = Viewer(robot, q=q, frames=frames or ())
            print(f"wbc view: meshcat viewer at {viewer.url}", flush=True)
            if not args.no_browser:
                webbrowser.open(viewer.url, new=2)
            if rec is not None:
                if not args.no_wait:
                    print("wbc view: waiting for a browser to connect (Ctrl-C to quit)", flush=True)
                    viewer.wait_for_browser()
                while True:
                    viewer.play(rec, args.speed)
                    if not args.loop:
                        break
                print(f"wbc view: replayed {rec.t[-1] - rec.t[0]:.2f} s", flush=True)
            if not args.no_wait:
                print("wbc view: serving until Ctrl-C", flush=True)
                while True:
                    time.sleep(3600)
            return 0
        except KeyboardInterrupt:
            print("wbc view: stopped", file=sys.stderr)
            return 0
        except WbcError as exc:
            print(f"wbc view: {exc}", file=sys.stderr)
            return 1
        finally:
            if viewer is not None:
                viewer.close()
