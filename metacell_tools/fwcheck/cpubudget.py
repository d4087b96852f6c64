"""Worst-case CPU cycles of the cell's interrupt handlers, by static analysis of the linked image's disassembly.

Method (docs/hardware.md, "CPU budget"):

* ``arm-none-eabi-objdump -d`` of the image is split into functions, each into basic blocks;
  literal-pool words (``.word``) are kept so PC-relative loads know the constant they load.
* Every instruction gets a cycle cost from :class:`CycleModel` (Cortex-M0+ timings, one flash
  wait state at 48 MHz, a surcharge for loads/stores that may reach an APB peripheral).
* A function's worst case is the longest path through its control-flow graph. Calls (``bl``,
  tail ``b``, and ``blx rN`` through a stated resolution) add the callee's own worst case.
* Loops (back edges found by depth-first search) must have a stated bound, the largest number of
  times their back edges can be taken per call; an unbounded loop is an error, never a guess.
  Each of the ``bound`` extra passes is charged the worst path through the loop body, then the
  worst path out: an over-estimate whenever passes differ.
* Per-block constant tracking (``ldr rX, [pc, #..]`` of a literal, ``movs``/``lsls``/``adds``
  of immediates) classifies a load/store base as SRAM, flash, IOBUS or APB; bases it cannot
  prove to be SRAM, the stack or flash are charged as APB accesses.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

# the target's facts and the analysis, under the names this module always had (tests, image tier, fwcheck)
from metacell_common.target.board import (
    COUNTS_PER_REV,
    ENCODERS,
    F_CPU_HZ,
    NO_LOAD_RAD_PER_V_S,
    SUPPLY_V,
    TICK_HZ,
    max_edge_rate_hz,
)
from metacell_common.target.cycles import (
    CORE_ONLY,
    LOADS,
    STORES,
    CycleModel,
    Function,
    Image,
    Insn,
    UnsupportedInsn,
    base_cycles,
    disassemble,
    parse_disassembly,
)

from .wcet import Analyser, AnalysisError, Cost, access_cycles

__all__ = [
    "COUNTS_PER_REV",
    "ENCODERS",
    "F_CPU_HZ",
    "NO_LOAD_RAD_PER_V_S",
    "SUPPLY_V",
    "TICK_HZ",
    "max_edge_rate_hz",
    "CORE_ONLY",
    "LOADS",
    "STORES",
    "CycleModel",
    "Function",
    "Image",
    "Insn",
    "UnsupportedInsn",
    "base_cycles",
    "disassemble",
    "parse_disassembly",
    "AnalysisError",
    "Analyser",
    "Cost",
    "access_cycles",
    "BUDGET_LIMIT",
    "DEFAULT_ELF",
    "cell_budget",
    "format_budget",
]

#: The interrupts may take at most this fraction of the CPU (the rest: bus service, USB, the main loop).
BUDGET_LIMIT = 0.5
DEFAULT_ELF = Path(__file__).resolve().parents[2] / ".pio" / "build" / "cell" / "firmware.elf"

# --------------------------------------------------------------------------- the cell's budget

#: Loop bounds of the cell's interrupt paths (back-edge traversals per call), from the source.
CELL_LOOP_BOUNDS: dict[str, int] = {
    # lib/metacell/src/mc_cell.c: the stall check runs once per motor (alpha, beta): one back edge
    "mc_cell_tick": 1,
    # Seeed core WInterrupts.c: for (i = 0; i < nints; i++) over the attached callbacks; the cell
    # attaches four (both channels of both encoders): four back edges
    "EIC_Handler": 4,
    # src/cell/samd21_hw.cpp tcc0_sync(): waits for SYNCBUSY.CCB2|CCB3. The previous write was one
    # tick (500 us) ago and a synchronisation takes under 10 GCLK cycles (48 MHz) while one poll
    # takes at least 7: at most two polls wait even if a write had just started
    "_ZL9tcc0_syncm": 2,
    # --- the I2C secondary's interrupt (SERCOM2_Handler -> Wire.onService), for its response ---
    # Seeed core SERCOM.cpp prepareCommandBitsWire() / readDataWIRE(): the SYSOP / SB waits are in the
    # master branch (isMasterWIRE()); a cell's SERCOM2 is a secondary and never enters them
    "_ZN6SERCOM22prepareCommandBitsWireEh": 0,
    "_ZN6SERCOM12readDataWIREEv": 0,
    # src/cell/bus_glue.cpp on_receive(): reads at most its 32-byte buffer (the core clears the rest)
    "_ZL10on_receivei": 32,
    # bus/mc_crc8.c on the secondary's path: a POINTER write (3 bytes) and the 1-byte header; 32 = the
    # glue's receive buffer, a bound that survives longer checked writes
    "mc_crc8_update": 32,
    # bus/mc_regs.c: copies at most MC_WRITE_MAX_LEN = 8 bytes into the mailbox
    "mc_regs_on_receive": 8,
    # bus/mc_regs.c: copies one published block, at most MC_BLK_MAX_LEN = 25 bytes
    "mc_regs_on_request": 25,
    # Wire.cpp write(data, n): one write(byte) per byte of that block, at most 25
    "_ZN7TwoWire5writeEPKhj": 25,
    # Seeed core Reset.cpp tickReset() (SysTick, beside SERCOM2 at priority 2): its loops are those of banzai(),
    # inlined: the NVM-ready waits and the final while (true) on the way into the bootloader after a 1200-baud
    # touch; the chip resets there, no response follows
    "tickReset": 0,
}

#: EIC_Handler's ``ISRcallback[i]()`` is charged per edge (below), not inside the handler.
CELL_INDIRECT: dict[str, tuple[str, ...]] = {"EIC_Handler": ()}

ENCODER_CALLBACKS = ("hw_isr_encoder_alpha", "hw_isr_encoder_beta")


@dataclass
class IsrBudget:
    name: str
    cycles: int  # per event, exception entry and exit included
    insns: int
    rate_hz: float

    @property
    def load(self) -> float:
        return self.cycles * self.rate_hz / F_CPU_HZ


@dataclass
class Response:
    """Worst-case response of one interrupt under the image's NVIC priorities: from its event to the end of its
    handler, with the same-priority handler that may be running (an interrupt cannot pre-empt its equal) and every
    more urgent one that may arrive meanwhile. ``cycles`` None: no bound (a handler on its path has none)."""

    name: str
    priority: int
    cycles: int | None
    deadline: int  # cycles
    why: str

    @property
    def ok(self) -> bool:
        return self.cycles is not None and self.cycles <= self.deadline


@dataclass
class Budget:
    isrs: list[IsrBudget]
    model: CycleModel
    responses: list[Response] = field(default_factory=list)
    priorities: dict[str, int] | None = None

    @property
    def total(self) -> float:
        return sum(i.load for i in self.isrs)


#: Other handlers that may share a priority with the edges or the tick, as (vector, handler, indirect calls,
#: events per second or None when nothing bounds their rate). The core's USB handler calls UDD_Handler through
#: the pointer USB_SetHandler() stores, and busy-waits on the host during control transfers (USBCore.cpp
#: armRecvCtrlOUT, sendControl): no loop bound exists, so its analysis fails by design. SysTick stays at the
#: core's priority 2 (wiring.c).
OTHER_ISRS: tuple[tuple[str, str, dict[str, tuple[str, ...]], float | None], ...] = (
    ("USB", "USB_Handler", {"USB_Handler": ("UDD_Handler",)}, None),
    (
        "SERCOM2",
        "SERCOM2_Handler",
        # Wire.onService calls the glue's callbacks through the pointers Wire.onReceive/onRequest store, and the
        # virtual available(); Wire.write(data, n) the virtual write(byte)
        {
            "_ZN7TwoWire9onServiceEv": ("_ZL10on_receivei", "_ZL10on_requestv", "_ZN7TwoWire9availableEv"),
            "_ZN7TwoWire5writeEPKhj": ("_ZN7TwoWire5writeEh",),
        },
        None,
    ),
    ("SysTick", "SysTick_Handler", {}, 1000.0),
)
SYSTICK_PRIORITY = 2
#: Functions that mask every interrupt (``cpsid i``) while the drive runs: each one's whole worst case (an upper
#: bound of its masked section) may hold off an edge like a handler at the EIC's own level.
MASKED_RUNTIME = ("mc_quad_snapshot", "mc_quad_set_pos", "mc_regs_on_request")
#: Functions that mask interrupts only where no response matters, and why (matched by name prefix).
MASKED_ELSEWHERE = {
    "_Z16hw_encoders_init": "start-up: the pins are attached with interrupts off, before the tick and the drive",
    "_ZN7__Guard": "the core's guard of a function-local static, once, at its construction",
    "_sbrk": "heap growth: operator new in the core's USB set-up, before setup()",
    "tickReset": "the 1200-baud touch: interrupts off, then a reset into the bootloader",
}
#: The primary's per-transaction timeout at 400 kHz (src/primary/main.cpp MC_TXN_TIMEOUT_US).
TXN_TIMEOUT_S = 1500e-6
#: SERCOM2's longest inactive-bus timeout: 20-21 SCL periods, at 400 kHz (DS40001882 CTRLA.INACTOUT = 3).
INACTOUT_MAX_S = 21 * 2.5e-6


Other = tuple[str, "int | None", str]  # name, worst cycles (None: no bound), why there is none
Urgent = tuple[str, "int | None", "int | None", str]  # name, worst cycles, period in cycles (None: unbounded), why


def _response(name: str, prio: int, own: int, deadline: int, same: list[Other], above: list[Urgent]) -> Response:
    """Fixed-priority response time: R = B + C + sum over more urgent j of ceil(R / T_j) * C_j, iterated to its
    fixed point. ``same``: handlers at the same priority (B is the longest of them: it may be running and cannot
    be pre-empted); ``above``: the more urgent ones."""
    blockers: list[tuple[str, int]] = []
    for n, c, why in same:
        if c is None:
            return Response(name, prio, None, deadline, f"{n} shares priority {prio} and has no bound ({why})")
        blockers.append((n, c))
    urgent: list[tuple[str, int, int]] = []
    for n, c, t, why in above:
        if c is None or t is None:
            what = why if c is None else "nothing bounds its rate"
            return Response(name, prio, None, deadline, f"{n} is more urgent and has no bound ({what})")
        urgent.append((n, c, t))
    block = max((c for _, c in blockers), default=0)
    full = Response(name, prio, None, deadline, "the more urgent handlers alone fill the CPU")
    if sum(c / t for _, c, t in urgent) >= 1:
        return full
    r = block + own
    for _ in range(100_000):
        nxt = block + own + sum(-(-r // t) * c for _, c, t in urgent)
        if nxt == r:
            break
        r = nxt
    else:
        return full  # no fixed point reached: never report a value that is not one
    parts = [f"{n} {c}" for n, c in blockers if c == block and block][:1]
    parts += [f"{n} {c} x {-(-r // t)}" for n, c, t in urgent]
    return Response(name, prio, r, deadline, f"own {own}" + "".join(" + " + p for p in parts))


def cell_budget(
    image: Image, model: CycleModel | None = None, tick_hz: float = TICK_HZ, priorities: dict[str, int] | None = None
) -> Budget:
    """Load of the tick and the encoder edges; with ``priorities`` (vector -> NVIC priority as the image sets
    them, irqmap.effective_priorities) also their worst-case responses."""
    model = model or CycleModel()

    def an(metric: str) -> Analyser:
        return Analyser(image, model, CELL_LOOP_BOUNDS, CELL_INDIRECT, metric)

    cyc, ins = an("cycles"), an("insns")
    exc = Cost(model.exc_entry + model.exc_exit, 0)
    tick_c = cyc.worst("TC3_Handler") + exc
    tick_i = ins.worst("TC3_Handler")
    # one edge = one interrupt: the handler scans all its entries, one callback runs
    cb_c = cyc._max([cyc.worst(n) for n in ENCODER_CALLBACKS])
    cb_i = ins._max([ins.worst(n) for n in ENCODER_CALLBACKS])
    edge_c = cyc.worst("EIC_Handler") + cb_c + exc
    edge_i = ins.worst("EIC_Handler") + cb_i
    b = Budget(
        [
            IsrBudget("TC3_Handler (control tick)", tick_c.cycles, tick_i.insns, tick_hz),
            IsrBudget("EIC_Handler + encoder ISR (per edge)", edge_c.cycles, edge_i.insns, max_edge_rate_hz()),
        ],
        model,
    )
    if priorities is None:
        return b
    b.priorities = dict(priorities)
    # (name, priority, cycles or None, period in cycles or None, why)
    isrs: list[tuple[str, int, int | None, float | None, str]] = [
        ("EIC", priorities["EIC"], edge_c.cycles, F_CPU_HZ / max_edge_rate_hz(), ""),
        ("TC3", priorities["TC3"], tick_c.cycles, F_CPU_HZ / tick_hz, ""),
    ]
    for vec, handler, indirect, rate in OTHER_ISRS:
        prio = SYSTICK_PRIORITY if vec == "SysTick" else priorities.get(vec)
        if prio is None or handler not in image.functions:
            continue
        present = {f: tuple(t for t in ts if t in image.functions) for f, ts in indirect.items()}
        try:
            c: int | None = Analyser(image, model, CELL_LOOP_BOUNDS, present).worst(handler).cycles + exc.cycles
            why = ""
        except (AnalysisError, UnsupportedInsn) as e:
            c, why = None, str(e)
        isrs.append((vec, prio, c, None if rate is None else F_CPU_HZ / rate, why))

    # every function that masks interrupts must be known: its section blocks the edges like a handler at level 0
    masked: list[Other] = []
    for name, f in image.functions.items():
        if not any(i.mnem == "cpsid" for i in f.insns) or any(name.startswith(k) for k in MASKED_ELSEWHERE):
            continue
        if name not in MASKED_RUNTIME:
            masked.append((f"interrupts masked in {name}", None, "not classified in cpubudget.MASKED_RUNTIME"))
            continue
        try:
            masked.append((f"masked {name}", Analyser(image, model, CELL_LOOP_BOUNDS, {}).worst(name).cycles, ""))
        except (AnalysisError, UnsupportedInsn) as e:
            masked.append((f"masked {name}", None, str(e)))

    def resp(target: str, label: str, own: int, deadline: float, blocker_self: bool) -> Response:
        prio = priorities[target]
        same: list[Other] = [(n, c, w) for n, p, c, _, w in isrs if p == prio and (n != target or blocker_self)]
        same += masked  # a masked section holds off every level
        above: list[Urgent] = [(n, c, None if t is None else int(t), w) for n, p, c, t, w in isrs if p < prio]
        return _response(label, prio, own, int(deadline), same, above)

    # an edge must be sampled before its encoder's next edge; the other encoder's edge may be in its handler
    per_encoder = F_CPU_HZ / (max_edge_rate_hz() / ENCODERS)
    b.responses = [
        resp("EIC", "encoder edge (EIC)", edge_c.cycles, per_encoder, True),
        resp("TC3", "control tick (TC3)", tick_c.cycles, F_CPU_HZ / tick_hz, False),
    ]
    # the I2C secondary stretches SCL from an event (address match, data ready) until its handler has run; one
    # event must end well inside the primary's transaction timeout (an addressed image: the bus glue linked)
    sercom = next((i for i in isrs if i[0] == "SERCOM2"), None)
    if sercom is not None and "_ZL10on_requestv" in image.functions:
        own = sercom[2]
        if own is None:
            b.responses.append(Response("I2C secondary event (SERCOM2)", sercom[1], None, 0, sercom[4]))
        else:
            b.responses.append(resp("SERCOM2", "I2C secondary event (SERCOM2)", own, F_CPU_HZ * TXN_TIMEOUT_S, False))
    return b


def format_budget(b: Budget, elf: str) -> str:
    lines = [f"CPU budget of {elf} (worst case, static, at {F_CPU_HZ / 1e6:g} MHz):"]
    lines.append(f"  {'interrupt':<40}{'cycles':>8}{'insns':>7}{'rate/s':>10}{'load':>8}")
    for i in b.isrs:
        lines.append(f"  {i.name:<40}{i.cycles:>8}{i.insns:>7}{i.rate_hz:>10.0f}{i.load:>8.1%}")
    lines.append(f"  {'total':<40}{'':>8}{'':>7}{'':>10}{b.total:>8.1%}")
    m = b.model
    lines.append(
        f"  model: +{m.fetch_wait} wait/insn, +{m.refill_wait} per flow change, +{m.literal_wait} per literal load, "
        f"+{m.apb_extra} per APB or unproven load/store, exception entry {m.exc_entry} + exit {m.exc_exit}"
    )
    if b.priorities is not None:
        order = sorted(b.priorities.items(), key=lambda kv: (kv[1], kv[0]))
        lines.append("  NVIC priorities in force (0 = most urgent): " + ", ".join(f"{k} {v}" for k, v in order))
        lines.append(f"  {'worst response':<40}{'prio':>5}{'cycles':>8}{'us':>7}{'deadline us':>13}")
        for r in b.responses:
            cyc = "-" if r.cycles is None else str(r.cycles)
            us = "-" if r.cycles is None else f"{r.cycles / F_CPU_HZ * 1e6:.1f}"
            verdict = "within" if r.ok else "OVER"
            lines.append(
                f"  {r.name:<40}{r.priority:>5}{cyc:>8}{us:>7}{r.deadline / F_CPU_HZ * 1e6:>13.1f}  {verdict}: {r.why}"
            )
            if r.name.startswith("I2C secondary") and r.cycles is not None:
                longer = r.cycles / F_CPU_HZ > INACTOUT_MAX_S
                lines.append(
                    f"    (a clock stretch of up to {r.cycles / F_CPU_HZ * 1e6:.0f} us: "
                    + ("longer than" if longer else "within")
                    + f" INACTOUT's longest setting, {INACTOUT_MAX_S * 1e6:.1f} us at 400 kHz)"
                )
    return "\n".join(lines)
