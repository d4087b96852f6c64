"""The cost decoder for code not loaded from an ELF (csrc/sam_cost.c, its table from costtable.py) equals the ELF
tables of the cycle model (cycles.block_tables) on every instruction of the shipped images and of the bootloader's
reachable code, and a board running code the model cannot time halts with a note naming the address."""

from __future__ import annotations

import bisect
import os
import re
import shutil
import struct
import subprocess
import tempfile
from pathlib import Path

import pytest
from elftools.elf.elffile import ELFFile

from host_emulator.image import costtable, cycles, elfimage, harness, runtime

from .conftest import images_or_skip


@pytest.fixture(scope="module")
def rt():
    return runtime.load()


def c_cost(rt, flash: bytes, addr: int):
    ffi, lib = rt
    o = ffi.new("sam_insn_cost_t *")
    hw1, hw2 = struct.unpack_from("<HH", flash + b"\xff\xff", addr)
    rc = lib.sam_cost_insn(hw1, hw2, o)
    return rc, o


def table_cost(t: cycles.BlockTables, addr: int) -> tuple[int, int, int, int]:
    """(core, wait, literal, refund) of the instruction at `addr` from the prefix-sum tables."""
    h = addr // 2
    return (
        int(t.core[h + 1] - t.core[h]),
        int(t.wait[h + 1] - t.wait[h]),
        int(t.literal[h + 1] - t.literal[h]),
        int(t.refund[h]),
    )


def compare(rt, flash: bytes, insns: list[cycles.Insn], tables: cycles.BlockTables) -> list[str]:
    """Every difference between the decoder and the tables on these instructions."""
    model = cycles.CycleModel()
    bad = []
    for ins in insns:
        rc, o = c_cost(rt, flash, ins.addr)
        try:
            want = cycles.insn_cost(ins, model)
        except cycles.UnsupportedInsn:
            if rc != 1:  # the tables charge it 1 cycle and list it; the decoder must refuse it
                bad.append(f"{ins.addr:#x} {ins.mnem} {ins.ops}: the model has no time for it, the decoder rc {rc}")
            continue
        got = (o.core, o.wait, o.lit, o.refund)
        if rc != 0 or got != table_cost(tables, ins.addr) or o.size != want.size:
            bad.append(
                f"{ins.addr:#x} {ins.mnem} {ins.ops}: tables {table_cost(tables, ins.addr)} size {want.size}, "
                f"decoder rc {rc} {got} size {o.size}"
            )
    return bad


def code_insns(path: Path, image: cycles.Image) -> list[cycles.Insn]:
    """The disassembly's instructions, without objdump's dumps of data in executable sections (the ELF's $d
    mapping symbols mark them)."""
    with open(path, "rb") as f:
        st = ELFFile(f).get_section_by_name(".symtab")
        marks = sorted((int(s["st_value"]), s.name[:2]) for s in st.iter_symbols() if s.name[:2] in ("$t", "$d"))
    out = []
    for fn in image.functions.values():
        for ins in fn.insns:
            i = bisect.bisect_right(marks, (ins.addr, "~")) - 1
            if i >= 0 and marks[i][1] == "$d":
                continue
            out.append(ins)
    return out


def test_decoder_equals_the_tables_on_every_instruction_of_the_shipped_images(rt):
    images = images_or_skip(16)
    total = 0
    for elf in (*images.cells, images.primary):
        img = elfimage.load_image(elf)
        flash = bytearray(b"\xff" * cycles.FLASH_SIZE)
        for sg in img.segments:
            flash[sg.addr : sg.addr + len(sg.data)] = sg.data
        insns = code_insns(elf, img.disassembly)
        assert len(insns) > 5000, (elf, len(insns))
        assert compare(rt, bytes(flash), insns, img.tables) == [], elf
        total += len(insns)
    assert total > 17 * 5000


# ---------------------------------------------------------------- the bootloader (MC_BOOTLOADER: its .bin)


def successors(flash: bytes, a: int, size: int) -> list[int]:
    """Where execution goes after the instruction at `a` (direct flow only: an indirect branch or a return ends it;
    BL and BLX return after the call)."""
    hw1, hw2 = struct.unpack_from("<HH", flash + b"\xff\xff", a)
    if hw1 & 0xF000 == 0xD000 and (hw1 >> 8) & 0xF < 0xE:  # B<cond>
        off = (hw1 & 0xFF) - (0x100 if hw1 & 0x80 else 0)
        return [a + 2, a + 4 + 2 * off]
    if hw1 & 0xF800 == 0xE000:  # B
        off = (hw1 & 0x7FF) - (0x800 if hw1 & 0x400 else 0)
        return [a + 4 + 2 * off]
    if hw1 & 0xF800 == 0xF000 and hw2 & 0xD000 == 0xD000:  # BL
        s = (hw1 >> 10) & 1
        j1, j2 = (hw2 >> 13) & 1, (hw2 >> 11) & 1
        i1, i2 = 1 - (j1 ^ s), 1 - (j2 ^ s)
        off = s << 24 | i1 << 23 | i2 << 22 | (hw1 & 0x3FF) << 12 | (hw2 & 0x7FF) << 1
        off -= (1 << 25) if s else 0
        return [a + 4, a + 4 + off]
    if hw1 & 0xFF80 == 0x4700 or hw1 & 0xFF00 == 0xBD00 or hw1 & 0xFF87 in (0x4487, 0x4687):
        return []  # BX, POP {..., pc}, ADD/MOV pc
    if hw1 & 0xFE00 == 0xDE00 or hw1 & 0xFF00 == 0xBE00:
        return []  # UDF, SVC, BKPT
    return [a + size]


def reachable(rt, flash: bytes) -> list[int]:
    """Instruction starts reached from the vector table by direct flow (a recursive-descent walk)."""
    vectors = struct.unpack_from("<48I", flash, 0)[1:]
    todo = [v & ~1 for v in vectors if v & 1 and v < len(flash)]
    seen: set[int] = set()
    while todo:
        a = todo.pop()
        if a in seen or not 0 <= a < len(flash) - 1:
            continue
        rc, o = c_cost(rt, flash, a)
        seen.add(a)
        if rc == 0:
            todo += successors(flash, a, o.size)
    return sorted(seen)


def objdump_at(binary: Path, addrs: list[int]) -> dict[int, cycles.Insn]:
    """objdump's reading of the instruction at each address (a linear sweep, then one from each address the sweep
    did not start an instruction at: the .bin has no mapping symbols, a literal pool can swallow code)."""

    def dump(*extra: str) -> dict[int, cycles.Insn]:
        cmd = ["arm-none-eabi-objdump", "-D", "-b", "binary", "-marm", "-Mforce-thumb", "--no-show-raw-insn"]
        out = subprocess.run([*cmd, *extra, str(binary)], capture_output=True, text=True, check=True).stdout
        return {i.addr: i for f in cycles.parse_disassembly(out).functions.values() for i in f.insns}

    got = dump()
    for a in addrs:
        if a not in got:
            got[a] = dump(f"--start-address={a:#x}", f"--stop-address={a + 4:#x}")[a]
    return got


def test_decoder_equals_the_tables_on_the_bootloaders_reachable_code(rt):
    path = os.environ.get("MC_BOOTLOADER")
    if not path:
        pytest.skip("bootloader cost check skipped: MC_BOOTLOADER (the bootloader's .bin) is not set")
    binary = Path(path)
    flash = binary.read_bytes()
    addrs = reachable(rt, flash)
    assert len(addrs) > 1000
    by_addr = objdump_at(binary, addrs)
    insns = [by_addr[a] for a in addrs]
    image = cycles.Image({"boot": cycles.Function("boot", 0, insns)}, {0: "boot"}, {})
    tables = cycles.block_tables(image)
    assert compare(rt, flash, insns, tables) == []
    rcs = {a: c_cost(rt, flash, a)[0] for a in addrs}
    assert [hex(a) for a, rc in rcs.items() if rc == -1] == []  # nothing reached is undefined


# ---------------------------------------------------------------- the decoder on a running board


def test_table_rows_follow_the_model():
    """Each row's numbers are the model's cost of its representative (the generated table's one source)."""
    model = cycles.CycleModel()
    for row in costtable.ROWS:
        if not row.mnem:
            continue
        rc = costtable.row_cost(row, model)
        ins = cycles.Insn(0, row.mnem, row.ops, "")
        if rc.unsupported:
            with pytest.raises(cycles.UnsupportedInsn):
                cycles.base_cycles(ins)
        else:
            assert rc.core == cycles.insn_cost(ins, model).core
    assert re.search(r"SAM_COST_NROWS \d+", costtable.emit_c())


def _program(extra=None):
    def handlers(a: harness.Asm):
        a.label("loop")
        a.movs(2, 5)
        a.label("again")
        a.ldr_const(3, 0x20000000)
        a.mem("ldr", 4, 3)
        a.adds(2, 255)
        a.b("after")
        a.pool()
        a.label("after")
        a.dsb_isb()
        a.b()
        if extra:
            extra(a)
        return {}

    return harness.stub(handlers)


def test_a_board_without_tables_runs_on_the_decoders_costs_exactly():
    prog = _program()
    bare = harness.Program(**{**prog.__dict__, "tables": None})
    runs = []
    for p in (prog, bare):
        h = harness.Harness(program=p)
        h.write("PM.APBCMASK", h.read("PM.APBCMASK") | 1 << 11)
        loop = p.labels["loop"]
        r1, t0 = h.ffi.new("uint32_t *"), h.ffi.new("uint64_t *")
        assert h.lib.sam_harness_call(h._w, 0, loop, p.labels["after"] + 8, 0, r1, t0) == 0, h.error()
        h.advance(1e-4)
        runs.append((h.now(), h.info().cycles, h.read("PM.APBCMASK")))
    assert runs[0] == runs[1]


def test_code_the_model_cannot_time_halts_the_board_with_a_note():
    def wfi(a: harness.Asm):
        a.label("wfi")
        a.movs(0, 1)
        a._h(0xBF30, "wfi")
        a.b()

    p = _program(wfi)
    p = harness.Program(**{**p.__dict__, "tables": None})
    h = harness.Harness(program=p)
    r1, t0 = h.ffi.new("uint32_t *"), h.ffi.new("uint64_t *")
    at = p.labels["wfi"]
    h.lib.sam_harness_call(h._w, 0, at, at + 6, 0, r1, t0)
    assert h.info().lockup == 1
    assert any(f"no cycle model for `wfi` at 0x{at + 2:05x}" in n for n in h.notes()), h.notes()


@pytest.mark.parametrize("tables", [True, False])
def test_rewritten_flash_is_costed_from_its_new_bytes(tables):
    """A routine run, then rewritten (two MOVS become PUSH {r0-r7}, POP {r0-r7}): the second run costs the new code,
    the same with or without the ELF's tables (they are dropped for rewritten code)."""
    p = _program()
    if not tables:
        p = harness.Program(**{**p.__dict__, "tables": None})
    h = harness.Harness(program=p)
    r1, t0 = h.ffi.new("uint32_t *"), h.ffi.new("uint64_t *")
    loop, end = p.labels["loop"], p.labels["after"] + 8

    def run() -> int:
        c0 = h.info().cycles
        assert h.lib.sam_harness_call(h._w, 0, loop, end, 0, r1, t0) == 0, h.error()
        return h.info().cycles - c0

    run()  # the NVM cache warm from here on
    before = run()
    assert run() == before
    code = struct.pack("<HH", 0xB4FF, 0xBCFF)  # push {r0-r7}; pop {r0-r7}: 9 + 9 core cycles
    at = p.labels["loop"]  # MOVS r2, #5 (1) and the literal LDR r3 (2, a flash read) become the push and the pop
    assert h.lib.sam_harness_flash(h._w, 0, at, code, len(code)) == 0
    rws = (h.read("NVMCTRL.CTRLB") >> 1) & 0xF  # the wait states of the literal load that is gone
    assert run() == before + 15 - rws


# ---------------------------------------------------------------- every encoding against objdump

#: what objdump decodes in ARMv6-M mode that ARMv6-M does not define (the decoder: undefined)
NOT_ARMV6M = ("cbz", "cbnz", "hlt", "setend", "setpan", "bxns", "blxns")
#: the special registers of ARMv6-M (SYSm): APSR, IAPSR, EAPSR, XPSR, IPSR, EPSR, IEPSR, MSP, PSP, PRIMASK, CONTROL
SYSM = (0, 1, 2, 3, 5, 6, 7, 8, 9, 16, 20)


def _canonical_msr_mrs(hw1: int, hw2: int) -> bool:
    """MSR <reg>, Rn / MRS Rd, <reg> as ARMv6-M encodes them, every should-be bit as it should be."""
    if hw1 & 0xFFF0 == 0xF380:
        return hw2 & 0xFF00 == 0x8800 and hw2 & 0xFF in SYSM
    return hw1 == 0xF3EF and hw2 & 0xF000 == 0x8000 and hw2 & 0xFF in SYSM


#: the 32-bit instructions of ARMv6-M
WIDE_ARMV6M = ("bl", "msr", "mrs", "dsb", "dmb", "isb", "udf")


def _objdump_words(data: bytes, step: int) -> dict[int, tuple[cycles.Insn | None, str]]:
    """objdump's reading (ARMv6-M, Thumb) of the instruction at each `step` bytes of `data`, and its text."""
    with tempfile.NamedTemporaryFile(suffix=".bin") as f:
        f.write(data)
        f.flush()
        cmd = ["arm-none-eabi-objdump", "-D", "-b", "binary", "-marmv6s-m", "-Mforce-thumb", "--no-show-raw-insn"]
        out = subprocess.run([*cmd, f.name], capture_output=True, text=True, check=True).stdout
    insns = {i.addr: i for fn in cycles.parse_disassembly(out).functions.values() for i in fn.insns}
    text = {}
    for ln in out.splitlines():
        head, _, rest = ln.partition(":")
        if re.fullmatch(r"\s*[0-9a-f]+", head):
            text[int(head, 16)] = rest.strip()
    return {a: (insns.get(a), text.get(a, "")) for a in range(0, len(data), step)}


def _check(rt, hw1: int, hw2: int, ins: cycles.Insn | None, text: str, model: cycles.CycleModel) -> str | None:
    rc, o = c_cost(rt, struct.pack("<HH", hw1, hw2), 0)
    mnem = ins.mnem.replace("<und>", "") if ins else ""
    wide = hw1 >> 11 >= 0b11101
    undefined = (
        ins is None
        or "UNDEFINED" in text
        or "UNDEF:" in text
        or "<unknown>" in text
        or mnem in NOT_ARMV6M
        or mnem.startswith("it")
        or (wide and mnem not in WIDE_ARMV6M)
    )
    if mnem in ("msr", "mrs") and not _canonical_msr_mrs(hw1, hw2):
        return None  # UNPREDICTABLE forms (should-be bits, reserved SYSm): objdump reads the A profile's
    if undefined:
        return None if rc == -1 else f"{hw1:04x} {hw2:04x} {text!r}: not ARMv6-M, the decoder rc {rc}"
    assert ins is not None
    try:
        k = cycles.insn_cost(cycles.Insn(0, mnem, ins.ops, ""), model)
    except cycles.UnsupportedInsn:
        return None if rc == 1 else f"{hw1:04x} {hw2:04x} {text!r}: the model has no time for it, rc {rc}"
    if rc == 0 and (o.core, o.wait, o.lit, o.refund, o.size) == (k.core, k.wait, k.literal, k.refund, k.size):
        return None
    return f"{hw1:04x} {hw2:04x} {text!r}: model {k}, decoder rc {rc} {(o.core, o.wait, o.lit, o.refund, o.size)}"


def test_every_16_bit_encoding_and_32_bit_samples_cost_as_objdump_reads_them(rt):
    """The decode table's rows against objdump: every 16-bit encoding (the IT instructions, which ARMv6-M lacks and
    which would condition the next ones in objdump's sweep, on their own), and each 32-bit first halfword with
    second halfwords covering BL, MSR, MRS and the barriers: the model's cost of objdump's instruction, its
    refusal, or (not an ARMv6-M instruction) undefined."""
    if shutil.which("arm-none-eabi-objdump") is None:
        pytest.skip("encoding sweep skipped: arm-none-eabi-objdump not found")
    model = cycles.CycleModel()
    it = [hw for hw in range(0xBF01, 0xC000) if hw & 0xF]
    narrow = [hw if hw not in it else 0xBF00 for hw in range(0xE800)]
    seen = _objdump_words(struct.pack(f"<{len(narrow)}H", *narrow), 2)
    bad = [e for hw in narrow if (e := _check(rt, hw, 0, *seen[2 * hw], model))]
    bad += [f"{hw:04x}: IT, not ARMv6-M" for hw in it if c_cost(rt, struct.pack("<H", hw), 0)[0] != -1]
    seconds = (0xD000, 0xD800, 0xF800, 0x8800, 0x8F4F, 0x8F5F, 0x8F6F, 0x8F3F, 0x8000, 0x8810, 0xA000, 0xF000, 0)
    seconds += (0xFFFF,)
    pairs = [(hw1, hw2) for hw1 in range(0xE800, 0x10000) for hw2 in seconds]
    pairs += [(0xF380 | r, 0x8800 | m) for r in range(16) for m in SYSM]  # every MSR
    pairs += [(0xF3EF, 0x8000 | r << 8 | m) for r in range(16) for m in SYSM]  # every MRS
    seen = _objdump_words(b"".join(struct.pack("<HH", *p) for p in pairs), 4)
    bad += [e for k, (hw1, hw2) in enumerate(pairs) if (e := _check(rt, hw1, hw2, *seen[4 * k], model))]
    assert bad == [], f"{len(bad)} encodings differ: {bad[:10]}"
