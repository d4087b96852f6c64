"""The interrupt map of a linked XIAO image: vector table, fault entry and record, the cell's NVIC priorities.

Read from the ELF the boards run (``nm``, ``objdump -s`` and ``objdump -d``), never from the source:

* **vectors**: every slot of the SAMD21 vector table names either a handler the program means to have
  (per role: the core's Reset, SysTick, USB; Wire's SERCOM2; the variant's SERCOM4; on the cell the
  core's EIC and NMI and our TC3) or ``sys_fault_entry``; none is the core's ``Dummy_Handler`` or 0;
* **fault entry**: ``sys_fault_entry`` calls ``sys_fault``, whose first call is ``sys_safe_outputs``
  (on the cell that calls ``hw_drivers_off``: both drivers asleep before anything else);
* **fault record**: ``mc_fault_record`` (an absolute symbol, ``--defsym``) lies above the image's RAM and
  the UF2 bootloader's, and far enough under the top of RAM for the stack the next boot uses first;
* **priorities** (cell): the table ``hw_irq_priority`` puts the EIC alone at the top, the tick above the
  I2C secondary and both above USB, and ``setup`` applies it after every call that sets a priority of
  its own (``hw_encoders_init``, ``hw_tick_start``, ``bus_setup``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from metacell_common.target.vectors import IRQN, SLOTS

from .armbuild import _run

#: Slots each program handles on purpose; every other slot must be the fault entry.
LIVE = {
    "primary": {"Reset", "SysTick", "USB", "SERCOM2", "SERCOM4"},
    "cell": {"Reset", "SysTick", "USB", "SERCOM2", "SERCOM4", "NMI", "EIC", "TC3"},
}
FAULT_ENTRY = "sys_fault_entry"

#: The UF2 bootloader runs on every reset and uses RAM from 0x20000000 up (its data, bss and 8 KiB stack stay
#: under 0x20005000, where its SAM-BA monitor loads applets) plus the double-tap word at the top of RAM.
BOOTLOADER_RAM_END = 0x2000_5000
#: Stack the next boot may use before setup() reads the record (Reset_Handler, main, init, the USB interrupt).
BOOT_STACK_BYTES = 1536
RECORD_BYTES = 16

#: The core's priorities where the cell's table is missing (USBCore.cpp, WInterrupts.c, SERCOM.cpp, our tick).
CORE_PRIORITIES = {"EIC": 0, "USB": 0, "TC3": 1, "SERCOM2": 3}
#: Calls in the cell's setup() that set a priority of their own: the table must be applied after them.
PRIORITY_SETTERS = ("hw_encoders_init", "hw_tick_start", "bus_setup")
APPLY = "hw_irq_priorities"
TABLE = "hw_irq_priority"


class ImageError(ValueError):
    """The image lacks a symbol or section the check needs."""


@dataclass
class Symbols:
    by_name: dict[str, tuple[int, int, str]]  # name -> (address, size, nm type)
    names_at: dict[int, set[str]]  # address (Thumb bit cleared) -> names

    def addr(self, name: str) -> int:
        if name not in self.by_name:
            raise ImageError(f"symbol {name} not in the image")
        return self.by_name[name][0]


def _demangle_key(name: str) -> str:
    """``_Z17hw_irq_prioritiesv`` -> ``hw_irq_priorities`` (plain C++ functions of the glue); others unchanged."""
    m = re.match(r"^_Z(\d+)(\w+)$", name)
    if m and len(m.group(2)) >= int(m.group(1)):
        return m.group(2)[: int(m.group(1))]
    return name


def symbols(elf: Path) -> Symbols:
    by_name: dict[str, tuple[int, int, str]] = {}
    names_at: dict[int, set[str]] = {}
    for ln in _run(["arm-none-eabi-nm", "-S", str(elf)]).splitlines():
        parts = ln.split()
        if len(parts) == 4:
            a, s, t, n = parts
        elif len(parts) == 3:
            a, t, n = parts
            s = "0"
        else:
            continue
        addr, size = int(a, 16), int(s, 16)
        by_name[n] = (addr, size, t)
        by_name.setdefault(_demangle_key(n), (addr, size, t))
        if t in "TtWw":
            names_at.setdefault(addr & ~1, set()).add(n)
    return Symbols(by_name, names_at)


def read_bytes(elf: Path, addr: int, n: int) -> bytes:
    """n bytes of the image at addr (``objdump -s`` of that range)."""
    out = _run(["arm-none-eabi-objdump", "-s", f"--start-address={addr:#x}", f"--stop-address={addr + n:#x}", str(elf)])
    data = bytearray()
    for ln in out.splitlines():
        m = re.match(r"^ ([0-9a-f]{4,8}) ((?:[0-9a-f]{2,8} ?){1,4})", ln)
        if m:
            data += bytes.fromhex(m.group(2).replace(" ", ""))
    if len(data) < n:
        raise ImageError(f"only {len(data)} of {n} bytes at {addr:#x}")
    return bytes(data[:n])


_BL = re.compile(r"^\s+([0-9a-f]+):\s+(bl|b|b\.n|b\.w)\s+[0-9a-f]+ <([^>+]+)>")


def calls(elf: Path, func: str, sym: Symbols) -> list[str]:
    """Direct callees of ``func`` (bl, and tail calls by b to another function), in address order."""
    start, size, _ = sym.by_name[func] if func in sym.by_name else (None, 0, "")
    if start is None:
        raise ImageError(f"function {func} not in the image")
    out = _run(
        [
            "arm-none-eabi-objdump",
            "-d",
            "--no-show-raw-insn",
            f"--start-address={start & ~1:#x}",
            f"--stop-address={(start & ~1) + max(size, 2):#x}",
            str(elf),
        ]
    )
    names = []
    for ln in out.splitlines():
        m = _BL.match(ln)
        if m and (m.group(2) == "bl" or m.group(3) != func):
            names.append(_demangle_key(m.group(3)))
    return names


def literal_words(elf: Path, func: str, sym: Symbols) -> set[int]:
    """The literal-pool words of ``func`` (what its PC-relative loads can load)."""
    start, size, _ = sym.by_name[func]
    data = read_bytes(elf, start & ~1, size)
    return {int.from_bytes(data[i : i + 4], "little") for i in range(0, len(data) - 3, 2)}


@dataclass
class IrqReport:
    role: str
    vectors: dict[str, str] = field(default_factory=dict)  # slot -> handler (one name per address)
    priorities: dict[str, int] | None = None  # cell: slot -> priority as the image sets it
    record: int | None = None
    errors: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.errors


def _handler_name(names: set[str]) -> str:
    if FAULT_ENTRY in names:
        return FAULT_ENTRY
    if "Dummy_Handler" in names:
        return "Dummy_Handler"
    return sorted(names, key=lambda n: (not n.endswith("_Handler"), n))[0]


def priority_table(elf: Path, sym: Symbols | None = None) -> dict[str, int] | None:
    """The cell's priority map as the linked image sets it, or None when the image has no table."""
    sym = sym or symbols(elf)
    if TABLE not in sym.by_name:
        return None
    addr, size, _ = sym.by_name[TABLE]
    raw = read_bytes(elf, addr, size)
    names = {v: k for k, v in IRQN.items()}
    out: dict[str, int] = {}
    for i in range(0, size - 1, 2):
        irq, prio = raw[i], raw[i + 1]
        out[names.get(irq, f"IRQ{irq}")] = prio
    return out


def effective_priorities(elf: Path) -> dict[str, int]:
    """Priorities in force after setup(): the cell's table over the core's defaults (the defaults alone if the
    image has no table)."""
    return {**CORE_PRIORITIES, **(priority_table(elf) or {})}


def check(elf: Path, role: str) -> IrqReport:
    sym = symbols(elf)
    rep = IrqReport(role)
    err = rep.errors.append

    # vectors
    table = sym.addr("exception_table")
    raw = read_bytes(elf, table, 4 * len(SLOTS))
    words = [int.from_bytes(raw[4 * i : 4 * i + 4], "little") for i in range(len(SLOTS))]
    if words[0] != sym.addr("__StackTop"):
        err(f"initial SP {words[0]:#x} is not __StackTop")
    for i, slot in enumerate(SLOTS):
        if i == 0 or slot is None:
            continue
        w = words[i]
        names = sym.names_at.get(w & ~1, set())
        if w == 0 or not names:
            err(f"{slot}: vector {w:#x} is no function (an exception there would jump into nothing)")
            continue
        if not w & 1:
            err(f"{slot}: vector {w:#x} lacks the Thumb bit")
        h = _handler_name(names)
        rep.vectors[slot] = h
        if slot in LIVE[role]:
            if h in (FAULT_ENTRY, "Dummy_Handler"):
                err(f"{slot}: the program handles it, but the vector is {h}")
        elif h != FAULT_ENTRY:
            err(f"{slot}: vector is {h}, not {FAULT_ENTRY}")

    # fault entry and what it does first
    try:
        if "sys_fault" not in calls(elf, FAULT_ENTRY, sym):
            err(f"{FAULT_ENTRY} does not call sys_fault")
        first = calls(elf, "sys_fault", sym)
        if not first or first[0] != "sys_safe_outputs":
            err(f"sys_fault's first call is {first[:1]}, not sys_safe_outputs")
        if role == "cell" and "hw_drivers_off" not in calls(elf, "sys_safe_outputs", sym):
            err("the cell's sys_safe_outputs does not call hw_drivers_off")
    except ImageError as e:
        err(str(e))

    # fault record placement
    try:
        rec = sym.addr("mc_fault_record")
        rep.record = rec
        ram_end = max(sym.addr("__bss_end__"), sym.addr("__HeapLimit"))
        top = sym.addr("__StackTop")
        if rec < max(ram_end, BOOTLOADER_RAM_END):
            err(f"mc_fault_record {rec:#x} is under the image's RAM ({ram_end:#x}) or the bootloader's")
        if top - (rec + RECORD_BYTES) < BOOT_STACK_BYTES:
            err(f"mc_fault_record {rec:#x} leaves under {BOOT_STACK_BYTES} B of stack for the next boot")
        if rec % 4:
            err(f"mc_fault_record {rec:#x} is not word-aligned")
    except ImageError as e:
        err(str(e))

    # the cell's priorities
    if role == "cell":
        prio = priority_table(elf, sym)
        if prio is None:
            err(f"no {TABLE} in the image: the core's priorities leave USB beside the encoder edges")
        else:
            rep.priorities = prio
            need = ("EIC", "TC3", "SERCOM2", "USB")
            if any(k not in prio for k in need):
                err(f"{TABLE} lacks {[k for k in need if k not in prio]}")
            else:
                others = [v for k, v in prio.items() if k != "EIC"]
                if not all(prio["EIC"] < v for v in others):
                    err(f"the EIC is not alone at the top: {prio}")
                if not prio["TC3"] < prio["USB"] or not prio["SERCOM2"] < prio["USB"]:
                    err(f"USB is not below the tick and the I2C secondary: {prio}")
            try:
                if sym.addr(TABLE) not in literal_words(elf, APPLY, sym):
                    err(f"{APPLY} does not load {TABLE}")
                seq = calls(elf, "setup", sym)
                if APPLY not in seq:
                    err(f"setup does not call {APPLY}")
                else:
                    last = max(i for i, n in enumerate(seq) if n == APPLY)
                    late = [n for n in seq[last + 1 :] if n in PRIORITY_SETTERS]
                    if late:
                        err(f"setup calls {late} after {APPLY}: their priorities would win")
            except ImageError as e:
                err(str(e))
    return rep


def format_report(rep: IrqReport, elf: str) -> str:
    lines = [f"fwcheck irq {elf} ({rep.role}):"]
    live = {s: h for s, h in rep.vectors.items() if h != FAULT_ENTRY}
    faults = [s for s, h in rep.vectors.items() if h == FAULT_ENTRY]
    lines.append("  handlers: " + ", ".join(f"{s}={h}" for s, h in live.items()))
    lines.append(f"  {FAULT_ENTRY}: {len(faults)} vectors ({', '.join(faults)})")
    if rep.record is not None:
        lines.append(f"  fault record at {rep.record:#010x}")
    if rep.priorities is not None:
        lines.append("  NVIC priorities (0 = most urgent): " + ", ".join(f"{k} {v}" for k, v in rep.priorities.items()))
    lines += [f"  ERROR {e}" for e in rep.errors]
    lines.append("  " + ("ok" if rep.ok else "FAILED"))
    return "\n".join(lines)
