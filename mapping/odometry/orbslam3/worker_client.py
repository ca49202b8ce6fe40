"""The adapter's side of the ORB-SLAM3 worker process (``orbslam3-worker.py``, protocol there).

ORB-SLAM3 is GPL-3.0: exobench never imports it; the worker script does, in a process of its
own started with this interpreter. Every exchange has a deadline: a worker that does not answer
in time is killed (it and nothing else: the process this object started, by its id) and counts
as failed, as does one that exits or closes its pipe. ORB-SLAM3's own messages go to a log file
in the pipeline's temporary folder; the last lines of it are the failure's reason.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import struct
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

WORKER_SCRIPT = Path(__file__).with_name("orbslam3-worker.py")


class WorkerError(RuntimeError):
    """The worker failed: it crashed, closed its pipe, answered with an error or not in time."""


class OrbSlam3Worker:
    """One ORB-SLAM3 process; ``request`` sends a message and waits for the answer."""

    def __init__(self, folder: Path, *, script: Path = WORKER_SCRIPT) -> None:
        self.log_path = Path(folder) / "orbslam3.log"
        self._log = open(self.log_path, "wb")  # noqa: SIM115 - the worker writes it for its whole life
        self.proc = subprocess.Popen([sys.executable, str(script)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=self._log, cwd=str(folder), close_fds=True)  # fmt: skip
        self._buf = b""
        os.set_blocking(self.proc.stdin.fileno(), False)  # a stopped worker must not block a write forever

    @property
    def pid(self) -> int:
        return self.proc.pid

    def request(self, header: dict[str, Any], arrays: dict[str, np.ndarray] | None = None,
                timeout_s: float = 10.0) -> tuple[dict[str, Any], dict[str, np.ndarray]]:  # fmt: skip
        """Send one request and return the answer; raise :class:`WorkerError` on any failure."""
        arrays = arrays or {}
        head = dict(header, arrays=[(k, a.dtype.str, list(a.shape)) for k, a in arrays.items()])
        body = json.dumps(head).encode()
        deadline = time.monotonic() + timeout_s
        self._write(struct.pack("<I", len(body)) + body, deadline)
        for a in arrays.values():
            self._write(memoryview(np.ascontiguousarray(a)).cast("B"), deadline)
        n = struct.unpack("<I", self._read(4, deadline))[0]
        reply = json.loads(self._read(n, deadline))
        out = {}
        for name, dtype, shape in reply.get("arrays", ()):
            dt = np.dtype(dtype)
            out[name] = np.frombuffer(self._read(int(np.prod(shape)) * dt.itemsize, deadline), dtype=dt).reshape(shape)
        if reply.get("op") == "error":
            raise WorkerError(str(reply.get("message", "error")))
        return reply, out

    def _write(self, data: bytes | memoryview, deadline: float) -> None:
        fd = self.proc.stdin.fileno()
        view = memoryview(data)
        while view:
            left = deadline - time.monotonic()
            if left <= 0:
                self.kill()
                raise WorkerError(self._died("did not answer in time"))
            select.select([], [fd], [], left)
            try:
                view = view[os.write(fd, view):]
            except BlockingIOError:
                continue
            except OSError:  # a closed pipe: the worker has gone
                raise WorkerError(self._died("exited")) from None

    def _read(self, n: int, deadline: float) -> bytes:
        fd = self.proc.stdout.fileno()
        while len(self._buf) < n:
            left = deadline - time.monotonic()
            if left <= 0:
                self.kill()
                raise WorkerError(self._died("did not answer in time"))
            ready, _, _ = select.select([fd], [], [], left)
            if not ready:
                continue
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                raise WorkerError(self._died("exited"))
            self._buf += chunk
        out, self._buf = self._buf[:n], self._buf[n:]
        return out

    def _died(self, what: str) -> str:
        code = self.proc.poll()
        if code is None and what != "did not answer in time":
            try:
                code = self.proc.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                code = None
        status = f" (exit status {code})" if code is not None else ""
        return f"ORB-SLAM3 worker {what}{status}{self.log_tail()}"

    def log_tail(self, n_lines: int = 3) -> str:
        try:
            self._log.flush()
            lines = [ln for ln in self.log_path.read_text(errors="replace").splitlines() if ln.strip()]
        except OSError:
            return ""
        return (": " + " | ".join(lines[-n_lines:])) if lines else ""

    def kill(self) -> None:
        """End the process (this one only) and wait for it."""
        if self.proc.poll() is None:
            self.proc.kill()
        with contextlib.suppress(subprocess.TimeoutExpired):  # a process the kernel has not reaped yet
            self.proc.wait(timeout=5.0)

    def finish(self, trajectory: Path, timeout_s: float) -> str:
        """Shut ORB-SLAM3 down and save its trajectory export (EuRoC format) to ``trajectory``;
        returns "" when saved, else ORB-SLAM3's reason (no keyframe left in its atlas)."""
        reply, _ = self.request({"op": "close", "trajectory": str(trajectory)}, timeout_s=timeout_s)
        return "" if reply.get("saved") else str(reply.get("save_error") or "nothing saved")

    def close(self, timeout_s: float = 10.0) -> None:
        """Ask the worker to shut ORB-SLAM3 down (when it still runs); kill it when it does not in time."""
        if self.proc.poll() is None:
            with contextlib.suppress(WorkerError):
                self.request({"op": "close"}, timeout_s=timeout_s)
        self.kill()
        for f in (self.proc.stdin, self.proc.stdout):
            with contextlib.suppress(OSError):
                f.close()
        self._log.close()
