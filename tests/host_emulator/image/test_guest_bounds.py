"""A guest's addresses at the top of the 4 GiB space reach the board's memory helpers without wrapping their bounds
(issue 32's audit of the C bounds checks): an exception vector read through a VTOR near the top, and an exception
return that unstacks from there, lock the core up (ARMv6-M: a vector or stack access that faults there is
unrecoverable) instead of reading 4 GiB past the board's flash."""

from __future__ import annotations

import struct

from host_emulator.image.harness import Asm, Harness, stub

IRQ = 15  # exception 31: its vector at VTOR + 0x7C, the last word below 2^32 when VTOR = 0xFFFFFF80


def test_a_vector_read_at_the_top_of_the_address_space_locks_the_core_up():
    h = Harness(program=stub(irqs_enabled=True))
    h.write("SCB.VTOR", 0xFFFFFF80)
    assert h.read("SCB.VTOR") == 0xFFFFFF80
    h.write("NVIC.ISER[0]", 1 << IRQ)
    # taken at once: the vector is read at 0xFFFFFFFC (the old check's 0xFFFFFFFC + 4 wrapped to 0, inside the flash)
    h.write("NVIC.ISPR[0]", 1 << IRQ)
    h.advance(1e-4)
    assert h.info().lockup
    assert any("exception vector unreadable" in n for n in h.notes()), h.notes()[-5:]


def handlers(a: Asm) -> dict[int, str]:
    """IRQ 15's handler moves SP to 0xFFFFFFFC and returns: the frame's first word is read at 0xFFFFFFFC."""
    a.label("irq")
    a.ldr_const(0, 0xFFFFFFFC)
    a.code += struct.pack("<H", 0x4685)  # mov sp, r0
    a.bx_lr()
    a.pool()
    return {16 + IRQ: "irq"}


def test_an_exception_return_that_unstacks_from_the_top_locks_the_core_up():
    h = Harness(program=stub(handlers, irqs_enabled=True))
    h.write("NVIC.ISER[0]", 1 << IRQ)
    h.write("NVIC.ISPR[0]", 1 << IRQ)
    h.advance(1e-4)
    assert h.info().lockup, h.notes()[-5:]
