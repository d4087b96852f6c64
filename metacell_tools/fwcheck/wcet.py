"""Worst-case cycles (and instructions) of a function and everything it calls, by static analysis of a linked image's
disassembly: basic blocks, the memory each load/store may reach (per-block constant tracking), the longest path
with stated loop bounds and indirect-call resolutions. The method is in cpubudget's docstring and docs/hardware.md
("CPU budget"); the cycle model per instruction is the target's (metacell_common.target.cycles)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from metacell_common.target.board import FLASH, IOBUS, SRAM
from metacell_common.target.cycles import (
    BCOND,
    BRANCH_TARGET,
    LITERAL_REF,
    LOADS,
    STORES,
    CycleModel,
    Function,
    Image,
    Insn,
    base_cycles,
    nregs,
)

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
    for lo_hi, name in ((SRAM, "sram"), (FLASH, "flash"), (IOBUS, "iobus")):
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
                ref = LITERAL_REF.search("@ " + ins.comment)
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
                extra = model.apb_extra * nregs(ops)
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
    return bool(BCOND.match(m))


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
            t = BRANCH_TARGET.match(ins.ops)
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
        t = BRANCH_TARGET.match(ins.ops)
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
