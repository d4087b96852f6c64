"""An emulated board's USB CDC port as a laptop's program sees it: a pty under a stable name containing ttyACM.

The pty comes from serve's open_pty (raw, master non-blocking, slave closed); a client's open and close of the slave
are seen on the master as `serve` sees them (a read fails with EIO while nobody holds the slave), and the line speed
the client set through `tcgetattr` on the master (a new port starts at 9600 baud, as a new ttyACM does). A pty has
no modem lines, so the 1200-baud touch (open at 1200 baud, drop DTR, close) is taken as "the speed is 1200 and
nobody holds the port". The stable name is a symlink to the slave (`<dir>/ttyACM-mc01 -> /dev/pts/K`), re-pointed
atomically when the port is made again: bossac takes its USB path only for a port whose name contains ttyACM or
ttyUSB.
"""

from __future__ import annotations

import errno
import os
import termios

from ..bus.serve import open_pty

TOUCH_SPEED = termios.B1200
NEW_PORT_SPEED = termios.B9600  # a new ttyACM's speed (cdc_acm's probe sends 9600 8N1)
# termios speed constants -> baud
BAUDS = {
    getattr(termios, f"B{b}"): b
    for b in (300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 921600)
    + (1000000, 2000000, 3000000, 4000000)
    if hasattr(termios, f"B{b}")
}
BACKLOG_MAX = 1 << 16  # bytes kept for a client that does not read before new output is dropped


def point_link(link: str, target: str) -> None:
    """Make `link` a symlink to target, atomically (a reader never sees it missing while it is re-pointed)."""
    tmp = f"{link}.{os.getpid()}.tmp"
    if os.path.lexists(tmp):
        os.unlink(tmp)
    os.symlink(target, tmp)
    os.replace(tmp, link)


class PtyPort:
    """One board's port: made when the board enumerates, closed when it goes (a client holding it sees a hang-up)."""

    def __init__(self, link: str) -> None:
        self.link = link
        self.master, slave, self.path = open_pty()
        attrs = termios.tcgetattr(slave)
        attrs[4] = attrs[5] = NEW_PORT_SPEED
        termios.tcsetattr(slave, termios.TCSANOW, attrs)
        os.close(slave)
        self.client = False  # a client holds the slave
        self.backlog = bytearray()
        self.dropped = 0
        point_link(link, self.path)

    def fileno(self) -> int:
        return self.master

    def poll(self, readable: bool) -> tuple[bytes, bool]:
        """(bytes from the client, whether a client holds the port now). `readable`: select said the master is
        readable (data, or nobody holds the slave); otherwise a client holds it and sent nothing."""
        if not readable:
            return b"", True
        try:
            return os.read(self.master, 4096), True
        except OSError as e:
            if e.errno == errno.EAGAIN:
                return b"", True
            if e.errno == errno.EIO:
                return b"", False
            raise

    def baud(self) -> int:
        """The line speed the client set (baud; 0 when the master cannot tell)."""
        try:
            return BAUDS.get(termios.tcgetattr(self.master)[5], 0)
        except termios.error:
            return 0

    def touched(self) -> bool:
        """Nobody holds the port and the last client left it at 1200 baud: the touch."""
        try:
            attrs = termios.tcgetattr(self.master)
        except termios.error:
            return False
        return attrs[5] == TOUCH_SPEED

    def send(self, data: bytes) -> None:
        """Bytes for the client (kept while it does not read, up to BACKLOG_MAX; dropped when nobody holds it)."""
        if not self.client:
            self.backlog.clear()
            return
        if len(self.backlog) + len(data) > BACKLOG_MAX:
            self.dropped += len(data)
        else:
            self.backlog += data
        if self.backlog:
            try:
                del self.backlog[: os.write(self.master, self.backlog)]
            except OSError as e:
                if e.errno not in (errno.EAGAIN, errno.EIO):
                    raise

    def close(self, unlink: bool = True) -> None:
        """The device is gone: the pty closes (a client sees a hang-up), and the stable name with it unless it is
        re-pointed at once."""
        if self.master >= 0:
            os.close(self.master)
            self.master = -1
        if unlink and os.path.islink(self.link) and os.readlink(self.link) == self.path:
            os.unlink(self.link)
