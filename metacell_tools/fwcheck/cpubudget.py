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

import re
from dataclasses import dataclass, field
from pathlib import Path

F_CPU_HZ = 48_000_000
#: The interrupts may take at most this fraction of the CPU (the rest: bus service, USB, the main loop).
BUDGET_LIMIT = 0.5
DEFAULT_ELF = Path(__file__).resolve().parents[2] / ".pio" / "build" / "cell" / "firmware.elf"

# --------------------------------------------------------------------------- parsing

_LABEL = re.compile(r"^([0-9a-f]+) <(.+)>:$")
_LINE = re.compile(r"^\s+([0-9a-f]+):\s+(\S+)\s*(.*)$")
_LITERAL_REF = re.compile(r"@ \(([0-9a-f]+) <")
_TARGET = re.compile(r"^([0-9a-f]+) <([^>+]+)(?:\+0x([0-9a-f]+))?>")
_COND = "eq|ne|cs|cc|hs|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le"
_BCOND = re.compile(rf"^b({_COND})(\.n|\.w)?$")
_REGLIST = re.compile(r"\{([^}]*)\}")


@dataclass(frozen=True)
class Insn:
    addr: int
    mnem: str  # without .n/.w
    ops: str  # operands, comment stripped
    comment: str


@dataclass
class Function:
    name: str
    start: int
    insns: list[Insn] = field(default_factory=list)


@dataclass
class Image:
    functions: dict[str, Function]
    by_addr: dict[int, str]  # start address -> function name
    words: dict[int, int]  # literal-pool address -> 32-bit value


def parse_disassembly(text: str) -> Image:
    """Functions, their instructions and the literal words of ``objdump -d --no-show-raw-insn`` output."""
    funcs: dict[str, Function] = {}
    words: dict[int, int] = {}
    cur: Function | None = None
    for ln in text.splitlines():
        m = _LABEL.match(ln)
        if m:
            cur = Function(m.group(2), int(m.group(1), 16))
            funcs[cur.name] = cur
            continue
        m = _LINE.match(ln)
        if not m or cur is None:
            continue
        addr, mnem, rest = int(m.group(1), 16), m.group(2), m.group(3)
        if mnem == ".word":
            words[addr] = int(rest.split()[0], 16) & 0xFFFFFFFF
            continue
        if mnem.startswith("."):
            continue
        ops, _, comment = rest.partition("@")
        mnem = mnem.removesuffix(".n").removesuffix(".w")
        cur.insns.append(Insn(addr, mnem, ops.strip(), comment.strip()))
    by_addr = {f.start: f.name for f in funcs.values()}
    return Image(funcs, by_addr, words)


# --------------------------------------------------------------------------- cycle model


@dataclass(frozen=True)
class CycleModel:
    """Cycles per instruction class on the SAMD21's Cortex-M0+ at 48 MHz (conservative).

    Core timings are the Cortex-M0+ ones (ARMv6-M): data processing and MULS (the SAMD21 has the
    single-cycle multiplier) 1, load/store 2, LDM/STM/PUSH 1+N, POP with PC 3+N, B taken 2 / not
    taken 1, BL 3, BX/BLX 2, MRS/MSR/barriers 3. On top:

    * ``fetch_wait``: one flash wait state (NVMCTRL RWS=1 at 48 MHz) charged on *every*
      instruction, as if each 16-bit instruction were its own flash read (the core reads 32 bits
      and the NVM cache may hit: real code pays less);
    * ``refill_wait``: a further wait state for every change of flow (taken branch, call, return);
    * ``literal_wait``: a PC-relative load reads flash;
    * ``apb_extra``: a load/store through the AHB-APB bridge; charged whenever the base is not
      proven SRAM, stack or flash (IOBUS PORT accesses are single-cycle, charged as SRAM);
    * ``exc_entry`` / ``exc_exit``: 15 cycles each (zero-wait-state latency), plus the vector
      read and the first fetch (entry) or the refill (exit) from flash.
    """

    fetch_wait: int = 1
    refill_wait: int = 1
    literal_wait: int = 1
    apb_extra: int = 3
    exc_entry: int = 15 + 2
    exc_exit: int = 15 + 1


#: The core's own timings only (zero-wait memory): not a bound, a reference for what the surcharges add.
CORE_ONLY = CycleModel(fetch_wait=0, refill_wait=0, literal_wait=0, apb_extra=0, exc_entry=15, exc_exit=15)

LOADS = {"ldr", "ldrb", "ldrh", "ldrsb", "ldrsh"}
STORES = {"str", "strb", "strh"}
_SRAM = (0x2000_0000, 0x2000_8000)
_FLASH = (0x0000_0000, 0x0004_0000)
_IOBUS = (0x6000_0000, 0x6000_0200)


def _nregs(ops: str) -> int:
    m = _REGLIST.search(ops)
    if not m:
        raise ValueError(f"no register list in {ops!r}")
    n = 0
    for part in m.group(1).split(","):
        part = part.strip()
        if "-" in part:
            a, b = (int(x.strip()[1:]) for x in part.split("-"))
            n += b - a + 1
        elif part:
            n += 1
    return n


class UnsupportedInsn(ValueError):
    """An instruction the model has no timing for (e.g. WFI in an interrupt path)."""


def base_cycles(insn: Insn) -> int:
    """Core cycles of one instruction (branches: the not-taken / non-branch part; see edge costs)."""
    m, ops = insn.mnem, insn.ops
    if m in LOADS or m in STORES:
        return 2
    if m in ("push", "stmia", "stm", "ldmia", "ldm"):
        return 1 + _nregs(ops)
    if m == "pop":
        return (3 if "pc" in ops else 1) + _nregs(ops)
    if m in ("mrs", "msr", "isb", "dsb", "dmb"):
        return 3
    if m in ("wfi", "wfe", "svc", "bkpt", "udf", "sev"):
        raise UnsupportedInsn(f"{m} at {insn.addr:#x}")
    if m == "bl":
        return 3
    if m in ("bx", "blx"):
        return 2
    if m == "b":
        return 2
    if _BCOND.match(m) or m in ("beq", "bne"):
        return 1  # not taken; taken adds 1 (edge cost)
    return 1


# --------------------------------------------------------------------------- per-block constants

_REG = r"(r\d+|ip|sl|fp|sp|lr)"
_MEM = re.compile(r"^" + _REG + r", \[" + _REG + r"(?:, (#-?\d+|" + _REG + r"))?\]")


def _imm(s: str) -> int | None:
    s = s.strip()
    if s.startswith("#"):
        try:
            return int(s[1:], 0)
        except ValueError:
            return None
    return None


def _region(value: int | None, base: str) -> str:
    if base == "sp":
        return "sram"
    if base == "pc":
        return "flash"
    if value is None:
        return "unknown"
    for lo_hi, name in ((_SRAM, "sram"), (_FLASH, "flash"), (_IOBUS, "iobus")):
        if lo_hi[0] <= value < lo_hi[1]:
            return name
    return "apb"


def access_cycles(insns: list[Insn], image: Image, model: CycleModel) -> list[int]:
    """Extra cycles of each instruction of one basic block for the memory it touches."""
    regs: dict[str, int | None] = {}
    out = []
    for ins in insns:
        extra = 0
        m, ops = ins.mnem, ins.ops
        parts = [p.strip() for p in ops.split(",")]
        if m in LOADS or m in STORES:
            mm = _MEM.match(ops)
            if "[pc" in ops:
                extra = model.literal_wait
                ref = _LITERAL_REF.search("@ " + ins.comment)
                val = image.words.get(int(ref.group(1), 16)) if ref else None
                if m == "ldr":
                    regs[parts[0]] = val
            elif mm:
                base, off = mm.group(2), mm.group(3)
                bval = regs.get(base)
                # a register offset (a table index) is taken to stay in the base's region
                offv = _imm(off) if off and off.startswith("#") else 0
                addr = None if bval is None or offv is None else (bval + offv) & 0xFFFFFFFF
                region = _region(addr if base not in ("sp", "pc") else None, base)
                if region == "flash":
                    extra = model.literal_wait
                elif region in ("apb", "unknown"):
                    extra = model.apb_extra
                if m in LOADS:
                    regs[mm.group(1)] = None
            else:
                extra = model.apb_extra
        elif m in ("movs", "mov") and len(parts) == 2:
            v = _imm(parts[1])
            regs[parts[0]] = v if v is not None else regs.get(parts[1])
        elif m in ("lsls", "lsrs", "adds", "subs") and len(parts) in (2, 3):
            dst = parts[0]
            src = parts[1] if len(parts) == 3 else parts[0]
            v, k = regs.get(src), _imm(parts[-1])
            if v is None or k is None:
                regs[dst] = None
            elif m == "lsls":
                regs[dst] = (v << k) & 0xFFFFFFFF
            elif m == "lsrs":
                regs[dst] = v >> k
            elif m == "adds":
                regs[dst] = (v + k) & 0xFFFFFFFF
            else:
                regs[dst] = (v - k) & 0xFFFFFFFF
        elif m in ("ldmia", "ldm", "stmia", "stm"):
            base = parts[0].rstrip("!")
            if base != "sp" and _region(regs.get(base), base) in ("apb", "unknown"):
                extra = model.apb_extra * _nregs(ops)
            regs = {}
        elif m in ("bl", "blx", "pop"):
            regs = {}  # caller-saved registers are gone; callee-saved ones are not tracked across calls
        elif m in ("cmp", "cmn", "tst", "push"):
            pass
        elif parts and re.fullmatch(_REG, parts[0]):
            regs[parts[0]] = None
        out.append(extra)
    return out


# --------------------------------------------------------------------------- control flow


class AnalysisError(ValueError):
    """The path cannot be bounded: an unbounded loop, an unresolved indirect call, recursion."""


@dataclass
class Cost:
    cycles: int
    insns: int

    def __add__(self, o: Cost) -> Cost:
        return Cost(self.cycles + o.cycles, self.insns + o.insns)

    def scale(self, k: int) -> Cost:
        return Cost(self.cycles * k, self.insns * k)


def _is_cond_branch(m: str) -> bool:
    return bool(_BCOND.match(m))


@dataclass
class Analyser:
    """Worst-case cycles (and instructions) of functions of an :class:`Image`.

    ``loop_bounds``: function -> largest number of back-edge traversals per call (one number
    for all the function's loops). ``indirect``: function -> the functions its ``blx rN`` may
    call (an empty tuple: the call's own cost only, the callees are charged elsewhere).
    ``metric``: "cycles" or "insns", what the longest path maximises.
    """

    image: Image
    model: CycleModel = field(default_factory=CycleModel)
    loop_bounds: dict[str, int] = field(default_factory=dict)
    indirect: dict[str, tuple[str, ...]] = field(default_factory=dict)
    metric: str = "cycles"
    _memo: dict[str, Cost] = field(default_factory=dict)
    _active: set[str] = field(default_factory=set)

    def _key(self, c: Cost) -> int:
        return c.cycles if self.metric == "cycles" else c.insns

    def _max(self, costs: list[Cost]) -> Cost:
        return max(costs, key=self._key) if costs else Cost(0, 0)

    def worst(self, name: str) -> Cost:
        """Worst path through ``name`` and everything it calls (exception entry/exit not included)."""
        if name in self._memo:
            return self._memo[name]
        if name in self._active:
            raise AnalysisError(f"recursion through {name}")
        if name not in self.image.functions:
            raise AnalysisError(f"{name} is not in the image")
        self._active.add(name)
        try:
            c = self._function(self.image.functions[name])
        finally:
            self._active.discard(name)
        self._memo[name] = c
        return c

    def _function(self, f: Function) -> Cost:
        insns = f.insns
        if not insns:
            raise AnalysisError(f"{f.name} has no instructions")
        index = {ins.addr: i for i, ins in enumerate(insns)}
        m = self.model
        end = insns[-1].addr + 4

        def local(ins: Insn) -> int | None:
            t = _TARGET.match(ins.ops)
            if not t:
                return None
            a = int(t.group(1), 16)
            return a if a in index else None

        # leaders
        leaders = {insns[0].addr}
        for i, ins in enumerate(insns):
            if ins.mnem == "b" or _is_cond_branch(ins.mnem):
                tgt = local(ins)
                if tgt is not None:
                    leaders.add(tgt)
                if i + 1 < len(insns):
                    leaders.add(insns[i + 1].addr)
            elif ins.mnem in ("bx",) or (ins.mnem == "pop" and "pc" in ins.ops):
                if i + 1 < len(insns):
                    leaders.add(insns[i + 1].addr)
        order = sorted(leaders)
        blocks: dict[int, list[Insn]] = {}
        for j, a in enumerate(order):
            nxt = order[j + 1] if j + 1 < len(order) else end + 1
            blocks[a] = [ins for ins in insns[index[a] :] if ins.addr < nxt]

        # block cost (without the terminal branch's taken penalty) and successor edges (target, extra cost)
        node_cost: dict[int, Cost] = {}
        falloff: set[int] = set()
        succ: dict[int, list[tuple[int, Cost]]] = {}
        for a, body in blocks.items():
            acc = access_cycles(body, self.image, m)
            c = Cost(0, 0)
            edges: list[tuple[int, Cost]] = []
            falls = True
            for ins, extra in zip(body, acc):
                c = c + Cost(base_cycles(ins) + m.fetch_wait + extra, 1)
                mn = ins.mnem
                if mn == "bl":
                    c = c + Cost(m.refill_wait, 0) + self._callee(f, ins)
                elif mn == "blx":
                    c = c + Cost(m.refill_wait, 0) + self._indirect(f, ins)
                elif mn == "bx" or (mn == "pop" and "pc" in ins.ops):
                    if not (mn == "bx" and ins.ops.startswith("lr")) and mn != "pop":
                        raise AnalysisError(f"{f.name}: indirect jump {mn} {ins.ops} at {ins.addr:#x}")
                    c = c + Cost(m.refill_wait, 0)
                    falls = False
                elif mn == "b":
                    tgt = local(ins)
                    c = c + Cost(m.refill_wait, 0)
                    if tgt is None:  # tail call
                        c = c + self._callee(f, ins)
                    else:
                        edges.append((tgt, Cost(0, 0)))
                    falls = False
                elif _is_cond_branch(mn):
                    tgt = local(ins)
                    if tgt is None:
                        raise AnalysisError(f"{f.name}: conditional branch out of the function at {ins.addr:#x}")
                    edges.append((tgt, Cost(1 + m.refill_wait, 0)))
            last = body[-1]
            if falls:
                nxt_i = index[last.addr] + 1
                if nxt_i < len(insns):
                    edges.append((insns[nxt_i].addr, Cost(0, 0)))
                else:
                    falloff.add(a)  # an error only if reachable (padding after the last return is not)
            node_cost[a] = c
            succ[a] = edges
        return self._longest(f.name, order[0], node_cost, succ, falloff)

    def _callee(self, f: Function, ins: Insn) -> Cost:
        t = _TARGET.match(ins.ops)
        if not t:
            raise AnalysisError(f"{f.name}: call without a target at {ins.addr:#x}")
        a = int(t.group(1), 16)
        name = self.image.by_addr.get(a)
        if name is None:
            raise AnalysisError(f"{f.name}: call into the middle of {t.group(2)} at {ins.addr:#x}")
        return self.worst(name)

    def _indirect(self, f: Function, ins: Insn) -> Cost:
        if f.name not in self.indirect:
            raise AnalysisError(f"{f.name}: unresolved indirect call {ins.mnem} {ins.ops} at {ins.addr:#x}")
        return self._max([self.worst(t) for t in self.indirect[f.name]])

    def _longest(
        self,
        fname: str,
        entry: int,
        node: dict[int, Cost],
        succ: dict[int, list[tuple[int, Cost]]],
        falloff: set[int],
    ) -> Cost:
        # back edges by iterative DFS from the entry
        back: set[tuple[int, int]] = set()
        state: dict[int, int] = {}  # 1 on stack, 2 done
        topo: list[int] = []
        stack: list[tuple[int, int]] = [(entry, 0)]
        state[entry] = 1
        while stack:
            n, i = stack.pop()
            edges = succ[n]
            if i < len(edges):
                stack.append((n, i + 1))
                t = edges[i][0]
                if state.get(t) == 1:
                    back.add((n, t))
                elif t not in state:
                    state[t] = 1
                    stack.append((t, 0))
            else:
                state[n] = 2
                topo.append(n)
        topo.reverse()
        reach = set(topo)
        if reach & falloff:
            raise AnalysisError(f"{fname}: falls off its end at {min(reach & falloff):#x}")
        if back and fname not in self.loop_bounds:
            heads = sorted({h for _, h in back})
            raise AnalysisError(f"{fname}: loop(s) at {', '.join(hex(h) for h in heads)} without a stated bound")
        bound = self.loop_bounds.get(fname, 0)
        fwd = {n: [(t, c) for t, c in succ[n] if (n, t) not in back] for n in reach}
        pos = {n: i for i, n in enumerate(topo)}

        # natural loops, smallest first (inner loops are charged before their enclosing loop's body)
        loops: list[tuple[int, set[int], list[tuple[int, int]]]] = []
        preds: dict[int, list[int]] = {n: [] for n in reach}
        for n in reach:
            for t, _ in fwd[n]:
                preds[t].append(n)
        for h in sorted({h for _, h in back}):
            latches = [(u, h) for u, v in back if v == h]
            body = {h}
            work = [u for u, _ in latches]
            while work:
                x = work.pop()
                if x not in body:
                    body.add(x)
                    work.extend(preds[x])
            loops.append((h, body, latches))
        loops.sort(key=lambda t: len(t[1]))
        cost = dict(node)
        for h, body, latches in loops:
            # worst pass: h -> ... -> latch -> (back edge) h, inside the body, forward edges only
            best: dict[int, Cost] = {h: cost[h]}
            for n in sorted(body, key=pos.__getitem__):
                if n not in best:
                    continue
                for t, c in fwd[n]:
                    if t in body:
                        cand = best[n] + c + cost[t]
                        if t not in best or self._key(cand) > self._key(best[t]):
                            best[t] = cand
            passes = []
            for u, _ in latches:
                ec = next(c for t, c in succ[u] if t == h)
                passes.append(best[u] + ec)
            cost[h] = cost[h] + self._max(passes).scale(bound)

        dist: dict[int, Cost] = {entry: cost[entry]}
        for n in topo:
            if n not in dist:
                continue
            for t, c in fwd[n]:
                cand = dist[n] + c + cost[t]
                if t not in dist or self._key(cand) > self._key(dist[t]):
                    dist[t] = cand
        exits = [dist[n] for n in reach if not succ[n] and n in dist]
        if not exits:
            raise AnalysisError(f"{fname}: no path returns")
        return self._max(exits)


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

# Highest encoder edge rate: no-load speed constant 49.8 rad/(V s) at the 5.86 V supply,
# 400 counts (edges of both channels) per revolution, two encoders per cell.
NO_LOAD_RAD_PER_V_S = 49.8
SUPPLY_V = 5.86
COUNTS_PER_REV = 400
ENCODERS = 2
TICK_HZ = 2000


def max_edge_rate_hz() -> float:
    """Encoder interrupts per second of one cell at no-load speed (both encoders)."""
    import math

    rev_s = NO_LOAD_RAD_PER_V_S * SUPPLY_V / (2 * math.pi)
    return rev_s * COUNTS_PER_REV * ENCODERS


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


def disassemble(elf: Path) -> str:
    from .armbuild import _run

    return _run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", str(elf)])


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
