"""One reader per serial port: the project's tools refuse a port another program holds, and lock the ports they hold.

Two programs reading one serial port each get part of its bytes (a logger beside `python -m can.logger` lost
86-92 % of the samples, or python-can's parser died on half lines), and both used to exit 0. So before a tool
opens a port (`slcanbus.open_bus`: the logger, the command tool, the experiment runner):

* it looks for any other process holding the device open (`/proc/*/fd`, what `fuser` does): this finds
  programs that take no lock, such as `python -m can.logger` or a terminal program;
* it takes the advisory exclusive lock of the device (`flock(LOCK_EX | LOCK_NB)` on its own descriptor: the
  convention pyserial's ``exclusive=True`` uses), held until the bus shuts down, so two of our tools never share
  a port even when /proc hides other users' processes.

A busy port raises PortBusy (an OSError) with one line naming the holder. The kernel's TIOCEXCL is not used: it
does not stop root, and on a pseudo-terminal it outlives a client killed without closing, locking the next one
out. `holders()` is also what `python -m host_emulator serve` uses to see a second client on its pty.
"""

from __future__ import annotations

import fcntl
import os
import stat


class PortBusy(OSError):
    """Another program holds the port; the message names it (one line)."""


def device_of(channel: str) -> str | None:
    """The device path of a python-can serial channel ('/dev/ttyACM0@115200' -> '/dev/ttyACM0'), or None when the
    channel is not a character device here (a URL such as socket://, a name python-can resolves itself)."""
    dev = channel.split("@", 1)[0]
    try:
        return dev if stat.S_ISCHR(os.stat(dev).st_mode) else None
    except (OSError, ValueError):
        return None


def _cmdline(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            text = " ".join(f.read().decode(errors="replace").replace("\0", " ").split())
    except OSError:
        return "?"
    return text if len(text) <= 80 else text[:77] + "..."


def holders(device: str, exclude: set[int] | None = None) -> dict[int, str]:
    """{pid: command line} of the processes other than `exclude` (default: this one) holding `device` open."""
    exclude = {os.getpid()} if exclude is None else exclude
    try:
        want = os.stat(device).st_rdev
        real = os.path.realpath(device)
    except OSError:
        return {}
    out: dict[int, str] = {}
    try:
        pids = [int(p) for p in os.listdir("/proc") if p.isdigit()]
    except OSError:  # no /proc (not Linux): the lock alone guards
        return {}
    for pid in pids:
        if pid in exclude:
            continue
        fd_dir = f"/proc/{pid}/fd"
        try:
            fds = os.listdir(fd_dir)
        except OSError:  # gone, or another user's process we may not inspect
            continue
        for fd in fds:
            try:
                link = os.readlink(f"{fd_dir}/{fd}")
                if link != real and not link.startswith("/dev/"):
                    continue
                if link == real or os.stat(f"{fd_dir}/{fd}").st_rdev == want:
                    out[pid] = _cmdline(pid)
                    break
            except OSError:
                continue
    return out


def busy_text(device: str, held: dict[int, str]) -> str:
    who = "; ".join(f"pid {pid}: {cmd}" for pid, cmd in sorted(held.items())[:3])
    return (
        f"{device} is in use by another program ({who}): a serial port has one reader "
        "(send commands through the logger's --do, or stop the other program)"
    )


def claim(channel: str) -> int | None:
    """Refuse a port held by another program, then lock it: the lock's descriptor (close it with release()), or None
    when the channel is not a local character device. Raises PortBusy."""
    dev = device_of(channel)
    if dev is None:
        return None
    held = holders(dev)
    if held:
        raise PortBusy(busy_text(dev, held))
    fd = os.open(dev, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise PortBusy(
            f"{dev} is locked by another program (flock): a serial port has one reader "
            "(send commands through the logger's --do, or stop the other program)"
        ) from None
    return fd


def release(fd: int | None) -> None:
    if fd is not None:
        try:
            os.close(fd)
        except OSError:
            pass
