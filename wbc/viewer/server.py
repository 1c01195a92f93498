"""A private meshcat server: started fresh on free ports, always stopped by us.

meshcat 0.3.2's ``Visualizer(zmq_url=None)`` starts ``meshcat.servers.zmqserver`` in a
subprocess (its own session, so Ctrl-C in the terminal does not reach it), but
``Visualizer.close()`` raises and the server only dies at interpreter exit. Here the
subprocess is started the same way — the server itself probes ports upwards from 6000
(ZeroMQ) and 7000 (HTTP) and skips any port already bound, so it never talks to a user's
running server — and :meth:`MeshcatServer.close` terminates it.
"""

from __future__ import annotations

import atexit
import contextlib
import io
import os
import re
import selectors
import subprocess
import sys
import threading
import time
from types import TracebackType

import meshcat
import meshcat.visualizer
import zmq

from ..exceptions import WbcError

_URL = re.compile(r"^(zmq_url|web_url)=(\S+)$")


class ViewerError(WbcError):
    """The meshcat server could not be started or reached."""


class MeshcatServer:
    """A meshcat server subprocess plus a :class:`meshcat.Visualizer` connected to it.

    Use as a context manager, or call :meth:`close`; an ``atexit`` hook closes it too.
    """

    def __init__(self, start_timeout: float = 20.0) -> None:
        args = [sys.executable, "-u", "-m", "meshcat.servers.zmqserver"]
        self.proc = subprocess.Popen(
            args,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        self._closed = False
        atexit.register(self.close)
        try:
            urls = self._read_urls(start_timeout)
        except BaseException:
            self.close()
            raise
        self.zmq_url: str = urls["zmq_url"]
        self.web_url: str = urls["web_url"]
        # The server may still print (errors) on stdout: drain it so it never blocks.
        threading.Thread(target=self._drain, daemon=True).start()
        try:
            with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL itself
                window = meshcat.visualizer.ViewerWindow(
                    zmq_url=self.zmq_url, start_server=False, server_args=[]
                )
        except BaseException:
            self.close()
            raise
        window.server_proc = self.proc
        self.window = window
        self.vis = meshcat.Visualizer(window=window)

    def _read_urls(self, timeout: float) -> dict[str, str]:
        """Parse ``zmq_url=...`` and ``web_url=...`` from the server's first output lines."""
        urls: dict[str, str] = {}
        buffer = b""
        fd = self.proc.stdout.fileno()
        deadline = time.monotonic() + timeout
        sel = selectors.DefaultSelector()
        sel.register(fd, selectors.EVENT_READ)
        try:
            while len(urls) < 2:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise ViewerError(f"meshcat server did not report its URLs within {timeout} s")
                if not sel.select(remaining):
                    continue
                chunk = os.read(fd, 4096)
                if not chunk:
                    self.proc.wait(timeout=5)
                    raise ViewerError(
                        f"meshcat server exited at start-up with code {self.proc.returncode}"
                    )
                buffer += chunk
                *lines, buffer = buffer.split(b"\n")
                for line in lines:
                    m = _URL.match(line.decode("utf-8", "replace").strip())
                    if m:
                        urls[m.group(1)] = m.group(2)
        finally:
            sel.close()
        return urls

    def _drain(self) -> None:
        stdout = self.proc.stdout
        with contextlib.suppress(Exception):
            while stdout.read1(4096):
                pass
            stdout.close()

    @property
    def url(self) -> str:
        """The page to open in a browser (``http://127.0.0.1:PORT/static/``)."""
        return self.web_url

    @property
    def alive(self) -> bool:
        """True while the server process runs."""
        return self.proc.poll() is None

    def wait_for_browser(self) -> None:
        """Block until a browser page is connected (meshcat has no timeout for this)."""
        self._check_open()
        self.window.wait()

    def _check_open(self) -> None:
        if self._closed:
            raise ViewerError("the meshcat server is closed")
        if not self.alive:
            raise ViewerError(f"the meshcat server died (exit code {self.proc.returncode})")

    def close(self) -> None:
        """Stop the server process and the ZeroMQ socket (idempotent)."""
        if self._closed:
            return
        self._closed = True
        atexit.unregister(self.close)
        window = getattr(self, "window", None)
        if window is not None:
            with contextlib.suppress(zmq.ZMQError):
                window.zmq_socket.close(linger=0)
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def __enter__(self) -> MeshcatServer:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
