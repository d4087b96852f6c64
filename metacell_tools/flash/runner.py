"""Execute a flash plan: build and upload each board (PlatformIO's uploader, or touch + bossac), wait for it to come
back, verify its identity; stop at the first failure unless asked to go on."""

from __future__ import annotations

import os
import shlex
import subprocess
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .boards import Port
from .bossac import make_bin, touch_1200, uploader_error, wait_for_port
from .identity import Identity, IdentityError, QueryResult, query_identity
from .plan import Plan, Step
from .toolchain import APP_OFFSET

OK = "ok"
BUILD_FAILED = "build failed"
NO_BOOTLOADER = "no bootloader port"
UPLOAD_FAILED = "upload failed"
GONE = "did not come back"
NO_IDENTITY = "no identity"
MISMATCH = "identity mismatch"
NOT_RUN = "not run"
UNPLUGGED_S = 5.0  # a board absent from the listing this long while bossac talks to it was unplugged
WATCH_EVERY_S = 0.25


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


def overwrote(offset: int) -> str:
    """What an upload below the application's offset did to the board ("" at or above it)."""
    if offset >= APP_OFFSET:
        return ""
    return (
        f"; the upload at 0x{offset:x} overwrote the bootloader, so the board can neither start nor take an upload "
        "over USB any more: restore the bootloader with an SWD probe (docs/hardware.md#when-a-board-fails-to-flash)"
    )


def wait_for_app_port(
    serial: str,
    list_ports: Callable[[], list[Port]],
    timeout: float,
    poll: float = 0.5,
    sleep: Callable[[float], None] = time.sleep,
    clock: Callable[[], float] = time.monotonic,
) -> Port | None:
    """The application-mode port of the board with this USB serial number, once it is back."""
    return wait_for_port(serial, list_ports, timeout, bootloader=False, poll=poll, sleep=sleep, clock=clock)


class Gate:
    """Where parallel uploads wait for each other: arrive() once per board, by its key (the n-th lets them all go;
    wait=False only counts). For emulated boards: bossac waits 1 s of wall time for its erase's answer, and the
    emulation keeps that pace only while every board is erasing (a board stalled in an erase costs nothing);
    started together, the 17 erases run side by side."""

    def __init__(self, n: int, timeout: float) -> None:
        self.left, self.timeout = n, timeout
        self.cond = threading.Condition()
        self.arrived: set[int] = set()

    def arrive(self, key: int, wait: bool = True) -> None:
        with self.cond:
            if key not in self.arrived:
                self.arrived.add(key)
                self.left -= 1
                self.cond.notify_all()
            if wait:
                self.cond.wait_for(lambda: self.left <= 0, timeout=self.timeout)


class Flasher:
    """Runs the plan step by step. Dependencies are injectable for tests (no hardware)."""

    def __init__(
        self,
        list_ports: Callable[[], list[Port]],
        *,
        expected_fw: str,
        run: Callable[..., Any] = subprocess.run,
        query: Callable[[str], QueryResult] = query_identity,
        touch: Callable[[str], None] = touch_1200,
        log_dir: Path | str = Path(".pio") / "flash-logs",
        upload_timeout: float = 600.0,
        reappear_timeout: float = 20.0,
        bootloader_timeout: float = 10.0,
        sleep: Callable[[float], None] = time.sleep,
        clock: Callable[[], float] = time.monotonic,
        out: Callable[[str], None] = print,
        together_s: float = 0.0,
        retries: int = 1,
        bossac_env: dict[str, str] | None = None,
    ) -> None:
        self.list_ports, self.expected_fw, self.run, self.query = list_ports, expected_fw, run, query
        self.touch, self.log_dir, self.upload_timeout = touch, Path(log_dir), upload_timeout
        self.reappear_timeout, self.bootloader_timeout = reappear_timeout, bootloader_timeout
        self.sleep, self.clock, self.out = sleep, clock, out
        # > 0: parallel bossacs start together (each waits at most this long for the others to be ready)
        self.together_s = together_s
        self._gate: Gate | None = None
        # a failed bossac is run again this many times while its board is still listed in bootloader mode (what one
        # does by hand after a USB hiccup before anything was written; after a failure mid-write the bootloader may
        # still wait for the rest of its transfer, and only a reset of the board helps)
        self.retries = retries
        # what bossac's environment gains (flash --emulated: libfaketime, so that bossac's clock keeps the boards' pace)
        self.bossac_env = dict(bossac_env or {})

    def _log_path(self, step: Step) -> Path:
        name = "primary" if step.board.role == "primary" else f"cell{step.board.cell:02d}"
        return self.log_dir / f"{name}.log"

    def _call(
        self,
        argv: tuple[str, ...],
        env: dict[str, str],
        log: Path,
        what: str,
        shown: str = "",
        serial: str = "",
    ) -> tuple[int, str] | str:
        """(exit status, output) of one command (`what` in messages), appended to the log; or why it could not run.
        The output is stdout, then stderr: both uploaders write their error to stderr, which a merged pipe can put
        before the progress lines still buffered on stdout (bossac's "No device found on PORT" is stderr only)."""
        with log.open("a") as f:
            f.write(f"$ {shown or shlex.join(argv)}\n")
        if serial and self.run is subprocess.run:
            return self._watched(argv, env, log, what, serial)
        try:
            res = self.run(
                list(argv),
                env=env,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
                timeout=self.upload_timeout,
            )
        except FileNotFoundError as exc:
            return f"cannot run {argv[0]}: {exc}"
        except subprocess.TimeoutExpired:
            return f"{what} did not finish in {self.upload_timeout:.0f} s"
        output = (res.stdout or "") + (getattr(res, "stderr", None) or "")
        with log.open("a") as f:
            f.write(output if output.endswith("\n") or not output else output + "\n")
        return res.returncode, output

    def _watched(self, argv: tuple[str, ...], env: dict[str, str], log: Path, what: str, serial: str):
        """_call of an uploader that talks to the board with this serial number, stopped when the board leaves the
        USB bus for UNPLUGGED_S while it runs (unplugged: bossac would wait on the dead port for ever)."""
        try:
            p = subprocess.Popen(list(argv), env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        except FileNotFoundError as exc:
            return f"cannot run {argv[0]}: {exc}"
        end = time.monotonic() + self.upload_timeout
        absent_since = None
        with p:
            while True:
                try:
                    stdout, stderr = p.communicate(timeout=WATCH_EVERY_S)
                    break
                except subprocess.TimeoutExpired:
                    pass
                try:
                    here = any(q.serial_number == serial for q in self.list_ports())
                except (OSError, ValueError):
                    here = False
                now = time.monotonic()
                absent_since = None if here else (absent_since or now)
                stop = ""
                if absent_since is not None and now - absent_since >= UNPLUGGED_S:
                    stop = (
                        f"the board (serial {serial}) left the USB bus during {what} and did not come back within "
                        f"{UNPLUGGED_S:g} s: unplugged? {what} stopped"
                    )
                elif now > end:
                    stop = f"{what} did not finish in {self.upload_timeout:.0f} s"
                if stop:
                    p.kill()
                    p.communicate()
                    with log.open("a") as f:
                        f.write(stop + "\n")
                    return stop
        output = (stdout or "") + (stderr or "")
        with log.open("a") as f:
            f.write(output if output.endswith("\n") or not output else output + "\n")
        return p.returncode, output

    def _bossac(self, step: Step, env: dict[str, str], log: Path) -> Outcome | int:
        """Touch, bootloader port, bossac: the bossac retries it took when the upload went through, else the failed
        Outcome."""
        up, b = step.upload, step.board
        assert up is not None
        if not up.firmware.is_file():
            why = make_bin(up.firmware, run=self.run)
            if why:
                return Outcome(step, BUILD_FAILED, why, log=log)
        now = [p for p in self.list_ports() if p.serial_number == b.serial and p.is_xiao]
        if not now:
            return Outcome(step, UPLOAD_FAILED, f"serial {b.serial} is no longer connected", log=log)
        boot = next((p for p in now if p.in_bootloader), None)
        if boot is None:
            app = now[0].device
            note = ""
            try:
                self.touch(app)
            except OSError as exc:  # serial.SerialException is an OSError
                note = f" (the touch failed: {exc})"
            with log.open("a") as f:
                f.write(f"1200-baud touch of {app}{note}\n")
            boot = wait_for_port(
                b.serial, self.list_ports, self.bootloader_timeout, bootloader=True, sleep=self.sleep, clock=self.clock
            )
            if boot is None:
                return Outcome(
                    step,
                    NO_BOOTLOADER,
                    f"{b.name} serial {b.serial}: its bootloader's port did not appear within "
                    f"{self.bootloader_timeout:g} s of the 1200-baud touch of {app}{note}; put it in its bootloader "
                    "by hand (short its two RST pads twice, quickly) and flash it again, or allow longer with "
                    "--bootloader-timeout",
                    log=log,
                )
        if self._gate is not None:
            self._gate.arrive(id(step))
        attempt = 0
        while True:
            res = self._call(up.argv(boot.device), {**env, **self.bossac_env}, log, "bossac", serial=b.serial)
            if isinstance(res, str):  # unplugged, or too slow: not retried
                return Outcome(step, UPLOAD_FAILED, res, log=log)
            rc, output = res
            if rc == 0:
                return attempt
            failed = f"{uploader_error(output)} (bossac exited with {rc} on {boot.device}, the board's bootloader port)"
            # the board in either mode, waiting for it if it is away (a board that re-enumerates is absent a moment)
            back = wait_for_port(
                b.serial, self.list_ports, UNPLUGGED_S, bootloader=None, sleep=self.sleep, clock=self.clock
            )
            if back is None:  # bossac failed because its port went away, and the board did not come back
                gone = (
                    f"the board (serial {b.serial}) left the USB bus during bossac and did not come back within "
                    f"{UNPLUGGED_S:g} s: unplugged? (bossac: {uploader_error(output)})"
                )
                return Outcome(step, UPLOAD_FAILED, gone, log=log)
            if attempt >= self.retries or not back.in_bootloader:
                tried = f" ({attempt + 1} attempts)" if attempt else ""
                return Outcome(step, UPLOAD_FAILED, failed + tried + overwrote(up.offset), log=log)
            attempt += 1
            boot = back
            note = f"bossac failed: {failed}; retry {attempt} of {self.retries} on {boot.device}"
            self.out(f"      {b.name}: {note}")
            with log.open("a") as f:
                f.write(note + "\n")

    def _flash_gated(self, step: Step) -> Outcome:
        try:
            return self.flash_one(step)
        finally:
            if self._gate is not None:
                self._gate.arrive(id(step), wait=False)  # (once: a board that failed before bossac lets the others go)

    def flash_one(self, step: Step) -> Outcome:
        log = self._log_path(step)
        log.parent.mkdir(parents=True, exist_ok=True)
        log.write_text("")
        env = dict(os.environ)
        env.update(dict(step.env_vars))
        if step.argv:  # (none: a prebuilt image)
            res = self._call(step.argv, env, log, "pio", step.shell())
            failed = BUILD_FAILED if step.upload is not None else UPLOAD_FAILED
            if isinstance(res, str):
                return Outcome(step, failed, res)
            rc, output = res
            if rc != 0:
                return Outcome(step, failed, f"{uploader_error(output)} (pio exited with {rc})", log=log)
        retried = 0
        if step.upload is not None:
            uploaded = self._bossac(step, env, log)
            if isinstance(uploaded, Outcome):
                return uploaded
            retried = uploaded
        port = wait_for_app_port(
            step.board.serial, self.list_ports, self.reappear_timeout, sleep=self.sleep, clock=self.clock
        )
        if port is None:
            why = overwrote(step.upload.offset) if step.upload is not None else ""
            return Outcome(
                step,
                GONE,
                f"no application port with serial {step.board.serial} "
                f"within {self.reappear_timeout:.0f} s after upload{why}",
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
        again = f" (after {retried} bossac retr{'y' if retried == 1 else 'ies'})" if retried else ""
        return Outcome(step, OK, f"{q.identity.describe()} on {port.device}{again}", q.identity, log)

    def flash(self, plan: Plan, stop_on_error: bool = False, jobs: int = 1) -> list[Outcome]:
        """Every step in the plan's order; jobs > 1 flashes that many boards at once (each its own port and
        bossac; stop_on_error then starts no new board after a failure, the ones under way finish)."""
        if jobs > 1:
            return self._flash_parallel(plan, stop_on_error, jobs)
        outcomes: list[Outcome] = []
        n = len(plan.steps)
        for i, step in enumerate(plan.steps, 1):
            self.out(f"[{i}/{n}] {step.board.name}: serial {step.board.serial} on {step.port.device}")
            o = self.flash_one(step)
            outcomes.append(o)
            self._said(o)
            if not o.ok and stop_on_error:
                for rest in plan.steps[i:]:
                    outcomes.append(Outcome(rest, NOT_RUN, "stopped after an earlier failure"))
                break
        return outcomes

    def _said(self, o: Outcome, who: str = "") -> None:
        self.out(
            f"      {who}{'OK' if o.ok else 'FAILED'}: {o.status}: {o.detail}"
            + (f" (log {o.log})" if o.log and not o.ok else "")
        )

    def _flash_parallel(self, plan: Plan, stop_on_error: bool, jobs: int) -> list[Outcome]:
        from concurrent.futures import FIRST_COMPLETED, Future, wait

        n = len(plan.steps)
        done: dict[int, Outcome] = {}
        failed = False
        self._gate = Gate(n, self.together_s) if self.together_s and jobs >= n else None
        with ThreadPoolExecutor(max_workers=jobs) as pool:
            running: dict[Future, int] = {}
            queue = list(enumerate(plan.steps))
            while queue or running:
                while queue and len(running) < jobs and not (failed and stop_on_error):
                    i, step = queue.pop(0)
                    self.out(f"[{i + 1}/{n}] {step.board.name}: serial {step.board.serial} on {step.port.device}")
                    running[pool.submit(self._flash_gated, step)] = i
                if not running:
                    break
                finished, _ = wait(running, return_when=FIRST_COMPLETED)
                for f in finished:
                    i = running.pop(f)
                    o = f.result()
                    done[i] = o
                    failed = failed or not o.ok
                    self._said(o, f"{plan.steps[i].board.name}: ")
        stopped = "stopped after an earlier failure"
        return [done.get(i) or Outcome(step, NOT_RUN, stopped) for i, step in enumerate(plan.steps)]


def summary(outcomes: list[Outcome]) -> str:
    """Every board's outcome, then one line: how many were flashed and verified, which failed, which were not tried."""
    lines = ["summary:"]
    for o in outcomes:
        verdict = "OK" if o.ok else "NOT TRIED" if o.status == NOT_RUN else "FAILED"
        lines.append(f"  {o.step.board.name:18s} {o.step.board.serial:24s} {verdict:9s} {o.status}: {o.detail}")
    bad = [o for o in outcomes if not o.ok and o.status != NOT_RUN]
    untried = [o for o in outcomes if o.status == NOT_RUN]
    lines.append(
        f"{sum(o.ok for o in outcomes)} of {len(outcomes)} board(s) flashed and verified"
        + (f"; FAILED: {', '.join(o.step.board.name for o in bad)}" if bad else "")
        + (
            f"; NOT TRIED (stopped at the first failure; --keep-going goes on): "
            f"{', '.join(o.step.board.name for o in untried)}"
            if untried
            else ""
        )
    )
    return "\n".join(lines)
