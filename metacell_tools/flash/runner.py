"""Execute a flash plan: upload each board with PlatformIO, wait for it to come back, verify its identity."""

from __future__ import annotations

import os
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .boards import Port
from .identity import Identity, IdentityError, QueryResult, query_identity
from .plan import Plan, Step

OK = "ok"
UPLOAD_FAILED = "upload failed"
GONE = "did not come back"
NO_IDENTITY = "no identity"
MISMATCH = "identity mismatch"
NOT_RUN = "not run"


@dataclass
class Outcome:
    step: Step
    status: str
    detail: str = ""
    identity: Identity | None = None
    log: Path | None = None

    @property
    def ok(self) -> bool:
        return self.status == OK


def check_identity(step: Step, ident: Identity, fw: str) -> str:
    """Empty string when the board is what the plan wanted, else what differs."""
    want = Identity(step.board.role, fw, step.board.cell, step.board.addr)
    got = Identity(ident.role, ident.fw, ident.cell, ident.addr)
    return "" if want == got else f"expected {want.describe()}, board says {got.describe()}"


def wait_for_app_port(
    serial: str,
    list_ports: Callable[[], list[Port]],
    timeout: float,
    poll: float = 0.5,
    sleep: Callable[[float], None] = time.sleep,
    clock: Callable[[], float] = time.monotonic,
) -> Port | None:
    """The application-mode port of the board with this USB serial number, once it is back."""
    end = clock() + timeout
    while True:
        for p in list_ports():
            if p.serial_number == serial and p.is_xiao and not p.in_bootloader:
                return p
        if clock() >= end:
            return None
        sleep(poll)


class Flasher:
    """Runs the plan step by step. Dependencies are injectable for tests (no hardware)."""

    def __init__(
        self,
        list_ports: Callable[[], list[Port]],
        *,
        expected_fw: str,
        run: Callable[..., Any] = subprocess.run,
        query: Callable[[str], QueryResult] = query_identity,
        log_dir: Path | str = Path(".pio") / "flash-logs",
        upload_timeout: float = 600.0,
        reappear_timeout: float = 20.0,
        sleep: Callable[[float], None] = time.sleep,
        clock: Callable[[], float] = time.monotonic,
        out: Callable[[str], None] = print,
    ) -> None:
        self.list_ports, self.expected_fw, self.run, self.query = list_ports, expected_fw, run, query
        self.log_dir, self.upload_timeout = Path(log_dir), upload_timeout
        self.reappear_timeout, self.sleep, self.clock, self.out = reappear_timeout, sleep, clock, out

    def _log_path(self, step: Step) -> Path:
        name = "primary" if step.board.role == "primary" else f"cell{step.board.cell:02d}"
        return self.log_dir / f"{name}.log"

    def flash_one(self, step: Step) -> Outcome:
        log = self._log_path(step)
        log.parent.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ)
        env.update(dict(step.env_vars))
        try:
            res = self.run(
                list(step.argv),
                env=env,
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                text=True,
                timeout=self.upload_timeout,
            )
        except FileNotFoundError as exc:
            return Outcome(step, UPLOAD_FAILED, f"cannot run {step.argv[0]}: {exc}")
        except subprocess.TimeoutExpired:
            return Outcome(step, UPLOAD_FAILED, f"pio did not finish in {self.upload_timeout:.0f} s")
        log.write_text(f"$ {step.shell()}\n{res.stdout or ''}")
        if res.returncode != 0:
            return Outcome(step, UPLOAD_FAILED, f"pio exited with {res.returncode}", log=log)
        port = wait_for_app_port(
            step.board.serial, self.list_ports, self.reappear_timeout, sleep=self.sleep, clock=self.clock
        )
        if port is None:
            return Outcome(
                step,
                GONE,
                f"no application port with serial {step.board.serial} "
                f"within {self.reappear_timeout:.0f} s after upload",
                log=log,
            )
        try:
            q = self.query(port.device)
        except IdentityError as exc:
            return Outcome(step, NO_IDENTITY, f"malformed reply: {exc}", log=log)
        except OSError as exc:  # serial.SerialException is an OSError
            return Outcome(step, NO_IDENTITY, f"cannot talk to {port.device}: {exc}", log=log)
        if q.identity is None:
            return Outcome(step, NO_IDENTITY, f"no answer to ID? on {port.device}", log=log)
        diff = check_identity(step, q.identity, self.expected_fw)
        if q.errors:
            diff = "; ".join(filter(None, [diff, "board reports start-up error: " + ", ".join(q.errors)]))
        if diff:
            return Outcome(step, MISMATCH, diff, q.identity, log)
        return Outcome(step, OK, f"{q.identity.describe()} on {port.device}", q.identity, log)

    def flash(self, plan: Plan, stop_on_error: bool = False) -> list[Outcome]:
        outcomes: list[Outcome] = []
        n = len(plan.steps)
        for i, step in enumerate(plan.steps, 1):
            self.out(f"[{i}/{n}] {step.board.name}: serial {step.board.serial} on {step.port.device}")
            o = self.flash_one(step)
            outcomes.append(o)
            self.out(
                f"      {'OK' if o.ok else 'FAILED'}: {o.status}: {o.detail}"
                + (f" (log {o.log})" if o.log and not o.ok else "")
            )
            if not o.ok and stop_on_error:
                for rest in plan.steps[i:]:
                    outcomes.append(Outcome(rest, NOT_RUN, "stopped after an earlier failure"))
                break
        return outcomes


def summary(outcomes: list[Outcome]) -> str:
    lines = ["summary:"]
    for o in outcomes:
        lines.append(
            f"  {o.step.board.name:18s} {o.step.board.serial:24s} "
            f"{'OK' if o.ok else 'FAILED':6s} {o.status}: {o.detail}"
        )
    bad = [o for o in outcomes if not o.ok]
    lines.append(
        f"{len(outcomes) - len(bad)} of {len(outcomes)} board(s) flashed and verified"
        + (f"; FAILED: {', '.join(o.step.board.name for o in bad)}" if bad else "")
    )
    return "\n".join(lines)
