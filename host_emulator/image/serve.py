"""The image tier behind `serve --slcan`: the real primary image's USB CDC port is the pty's other end.

The boards boot and the cells are configured as a run does it (model.bring_up: the scene's parameters over the bus,
the drive on); then the scripted laptop lets go of the port (DTR low) and the pty's client has it: python-can's
slcan interface talks to the primary's own SLCAN over the emulated USB, and everything it reads (frames, results,
PRIMARY_HEALTH) is what the flashed image sent. A client opening or closing the pty raises or drops DTR, as a
laptop opening the rig's port does.

Back-pressure: the laptop's USB host holds at most SAM_USB_BUF bytes for the primary's OUT endpoint. What it cannot
take yet is held here (`held`) and offered again after each advance; while anything is held, `ready()` is False and
serve stops reading the pty, so a client writing faster than the primary reads blocks in its own write (as on the
rig, where the CDC driver's buffer fills), and nothing it sent is lost or refused.
"""

from __future__ import annotations

from ..models.options import ConfigError
from ..models.plant import NumericalInstability
from .model import ImageSolver
from .world import WorldError


class ImageRig:
    """What `serve` drives: advance_to(scene microseconds), feed(bytes from the client), drain() (bytes for the
    client), session() at each open or close of the pty."""

    def __init__(self, solver: ImageSolver) -> None:
        self.solver = solver
        self.world = solver.world
        self.n = solver.model.n
        primary = self.world.primary
        if primary is None:  # pragma: no cover (the model always loads the primary)
            raise ConfigError("image: no primary board to serve")
        self.port = primary.index
        solver.laptop.close()  # the scripted laptop lets go: DTR low, the client's open raises it again
        self.world.usb_read(self.port)  # what the primary said to the scripted laptop is not the client's
        self.open = False
        self.bytes_in = self.bytes_out = 0
        self.t0 = solver.t_start
        self.band_stops = 0
        self.transactions = 0
        self.held = bytearray()  # the client's bytes the USB host could not take yet (oldest first)
        self.held_most = 0  # the most ever held at once
        self.line_at = 0  # the control transfers done once the device has the client's line state

    def advance_to(self, sim_us: int) -> None:
        try:
            self.world.run_to(self.t0 + sim_us * 1e-6)
        except WorldError as e:
            raise NumericalInstability(f"image: {e}") from None
        self.transactions = int(self.world.bus_info().transactions)
        self._offer()

    def session(self) -> None:
        """The pty was opened or closed: DTR follows; what the last client sent and the USB host had not taken yet
        goes with its session (the primary drops a half line at a new session too)."""
        self.open = not self.open
        self.held.clear()
        # as a laptop's open() returns only once the device took the new line state (cdc_acm's control transfer):
        # the client's first bytes wait for it (else the primary could read them in the session before)
        self.line_at = int(self.world.usb_info(self.port).control_transfers) + 1
        self.world.usb_dtr(self.port, self.open)

    def feed(self, data: bytes) -> bytes:
        """Bytes from the client to the primary's USB OUT endpoint (its answers come through drain): what the USB
        host cannot take now is held and offered again after each advance (ready() is False meanwhile)."""
        self.bytes_in += len(data)
        self.held += data
        self._offer()
        self.held_most = max(self.held_most, len(self.held))
        return b""

    def ready(self) -> bool:
        """True when nothing is held: serve reads the pty only then (back-pressure on the client)."""
        return not self.held

    def _offer(self) -> None:
        if self.held and int(self.world.usb_info(self.port).control_transfers) >= self.line_at:
            taken = self.world.usb_write(self.port, bytes(self.held))  # -1: the port is not attached (yet)
            del self.held[: max(0, taken)]

    def drain(self) -> bytes:
        out = self.world.usb_read(self.port)
        self.bytes_out += len(out)
        return out

    def summary(self, sim_s: float, wall_s: float) -> str:
        w = self.world
        boards = [w.info(b.index) for b in w.boards]
        resets = sum(int(i.resets) - 1 for i in boards)
        usb = w.usb_info(self.port)
        return (
            f"the flashed images: {self.transactions} I2C transactions, {usb.in_bytes} bytes from the primary's "
            f"USB ({usb.out_bytes} to it, at most {self.held_most} bytes held back while the USB host was full), "
            f"{resets} board resets after power-up; {sim_s / wall_s:.2f}x real time "
            f"(the image tier cannot always keep up)"
        )


def make_image_rig(solver) -> ImageRig:
    if not isinstance(solver, ImageSolver):
        raise TypeError(f"model image built a {type(solver).__name__}")
    return ImageRig(solver)
