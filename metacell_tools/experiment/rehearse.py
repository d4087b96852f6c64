"""Rehearsal without hardware: `python -m host_emulator serve SCENE --slcan` as a subprocess, its pty as the rig's port.

The served scene is the experiment's scene with model = "hil" and every perturbation's
torque set to 0: the pushes come from the runner's PERTURB commands, as on the rig. The
server runs in its own session (a Ctrl-C reaches the runner only, which then still
has a link to switch the drive off) and is always stopped (SIGTERM, then SIGKILL).
"""

from __future__ import annotations

import os
import re
import selectors
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

from host_emulator.params import Params
from metacell_tools.rigtools import proto

from .plan import CONTROL_PARAMS, FIRMWARE_PARAMS

if TYPE_CHECKING:
    from host_emulator.scene import Scene


class ServeError(RuntimeError):
    """The emulator server did not start (or said why it could not)."""


def serve_overrides(scene: Scene, sets: Sequence[str]) -> list[str]:
    """--set items for serve: the experiment's own, then model = hil, perturbation torques 0, and the
    firmware parameters at their defaults (the cells boot with them; the runner must set the scene's)."""
    base = Params()
    fw = [f"params.{name}={getattr(base, name)!r}" for name, _ in FIRMWARE_PARAMS] + [
        f"params.{name}={str(getattr(base, name)).lower()}" for name in CONTROL_PARAMS
    ]
    return (
        list(sets) + ["model=hil"] + [f"perturbation.{i + 1}.torque_Nm=0" for i in range(len(scene.perturbations))] + fw
    )


class Serve:
    """Context manager around one `python -m host_emulator serve` process; `.channel` is '<pty>@115200'."""

    def __init__(
        self,
        scene_arg: str,
        overrides: Sequence[str],
        extra: Sequence[str] = (),
        duration_s: float = 600.0,
        startup_timeout_s: float = 60.0,
    ) -> None:
        self.cmd = (
            [sys.executable, "-m", "host_emulator", "serve", scene_arg, "--slcan", "--duration", f"{duration_s:g}"]
            + [x for s in overrides for x in ("--set", s)]
            + list(extra)
        )
        self.startup_timeout_s = startup_timeout_s
        self.proc: subprocess.Popen[bytes] | None = None
        self.channel: str | None = None
        self.pty: str | None = None

    def __enter__(self):
        self.err = tempfile.TemporaryFile(mode="w+")
        self.proc = subprocess.Popen(
            self.cmd, cwd=proto.ROOT, stdout=subprocess.PIPE, stderr=self.err, start_new_session=True
        )
        out = self.proc.stdout
        assert out is not None  # stdout=PIPE
        sel = selectors.DefaultSelector()
        sel.register(out, selectors.EVENT_READ)
        deadline = time.monotonic() + self.startup_timeout_s
        line = b""
        while not line.endswith(b"\n"):
            left = deadline - time.monotonic()
            if left <= 0 or not sel.select(timeout=left):
                self.stop()
                raise ServeError(f"emulator server printed no pty path within {self.startup_timeout_s:g} s")
            chunk = os.read(out.fileno(), 1)
            if not chunk:
                break
            line += chunk
        sel.close()
        m = re.match(rb"slcan pty: (\S+)", line)
        if not m:
            self.proc.wait(5)
            self.err.seek(0)
            msg = self.err.read().strip() or line.decode(errors="replace").strip()
            self.stop()
            raise ServeError(f"emulator server failed: {msg}")
        self.pty = m.group(1).decode()
        self.channel = f"{self.pty}@115200"
        return self

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self) -> None:
        p = self.proc
        if p is None:
            return
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(5)
        if p.stdout:
            p.stdout.close()
        self.err.close()
        self.proc = None

    def __exit__(self, *exc):
        self.stop()
        return False
