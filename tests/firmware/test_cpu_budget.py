"""CPU budget of the cell's interrupts: the static analyser on hand-written disassembly, then on the real image."""

import math
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from metacell_tools.fwcheck import armbuild, cpubudget
from tests.firmware.test_irqmap import addressed_cell_elf  # noqa: F401  (cell 1 as the flash tool builds it)
from tests.firmware.test_pio_build import build_log  # noqa: F401  (the shared, locked real build)

ROOT = Path(__file__).resolve().parents[2]

# A leaf, and a caller with an APB store and a counted loop around a call. Hand costs under the default model
# (core + 1 fetch wait each; +1 refill per flow change; +1 literal; +3 APB) are in the right-hand comments.
SNIPPET = """
00000100 <leaf>:
     100:\tmovs\tr0, #1
     102:\tbx\tlr

00000104 <f>:
     104:\tpush\t{r4, lr}
     106:\tmovs\tr4, #0
     108:\tldr\tr3, [pc, #20]\t@ (120 <f+0x1c>)
     10a:\tstrb\tr4, [r3, #14]
     10c:\tadds\tr4, #1
     10e:\tcmp\tr4, #3
     110:\tbeq.n\t11a <f+0x16>
     112:\tbl\t100 <leaf>
     116:\tstr\tr0, [sp, #4]
     118:\tb.n\t10c <f+0x8>
     11a:\tpop\t{r4, pc}
     11c:\tnop\t\t\t@ (mov r8, r8)
     11e:\tnop\t\t\t@ (mov r8, r8)
     120:\t.word\t0x42002c00

00000124 <diamond>:
     124:\tcmp\tr0, #0
     126:\tbeq.n\t130 <diamond+0xc>
     128:\tmovs\tr1, #1
     12a:\tmovs\tr2, #2
     12c:\tmovs\tr3, #3
     12e:\tbx\tlr
     130:\tstr\tr1, [r0, #0]
     132:\tstr\tr1, [r0, #4]
     134:\tbx\tlr

00000138 <spin>:
     138:\tldr\tr3, [r0, #0]
     13a:\tcmp\tr3, #0
     13c:\tbne.n\t138 <spin>
     13e:\tbx\tlr

00000140 <via_pointer>:
     140:\tpush\t{r4, lr}
     142:\tblx\tr3
     144:\tpop\t{r4, pc}
"""
LEAF = 2 + 4  # movs 1+1; bx lr 2+1+1
ENTRY = 4 + 2 + 4 + 6  # push {r4, lr} 1+2+1; movs 2; ldr literal 2+1+1; strb to 0x42002c0e 2+1+3
PASS = 2 + 2 + 2 + (5 + LEAF) + 3 + 4  # adds, cmp, beq not taken, bl 3+1+1 + leaf, str to the stack 2+1, b 2+1+1
EXIT = 2 + 2 + 4 + 7  # adds, cmp, beq taken 2+1+1, pop {r4, pc} 3+2+1+1


def image():
    return cpubudget.parse_disassembly(SNIPPET)


@given(st.integers(min_value=0, max_value=60))
def test_loop_is_charged_bound_worst_passes_plus_the_way_out(bound):
    a = cpubudget.Analyser(image(), loop_bounds={"f": bound})
    got = a.worst("f")
    assert got.cycles == ENTRY + bound * PASS + EXIT
    assert got.insns == 4 + (6 + 2) * bound + 4  # the pass runs the leaf's two


def test_leaf_and_literal_words_are_parsed():
    img = image()
    assert img.words == {0x120: 0x42002C00}
    assert [i.mnem for i in img.functions["f"].insns][-3:] == ["pop", "nop", "nop"]
    assert cpubudget.Analyser(img).worst("leaf") == cpubudget.Cost(LEAF, 2)


def test_the_metric_decides_which_arm_is_worst():
    """Three register moves (more instructions) against two stores through an unproven pointer (more cycles)."""
    img = image()
    head = 2 + 2  # cmp; beq not taken
    by_cycles = cpubudget.Analyser(img).worst("diamond")
    by_insns = cpubudget.Analyser(img, metric="insns").worst("diamond")
    assert by_cycles == cpubudget.Cost(2 + 4 + 6 + 6 + 4, 5)  # cmp, beq taken 2+1+1, two APB-charged str, bx lr
    assert by_insns == cpubudget.Cost(head + 3 * 2 + 4, 6)


def test_a_loop_without_a_stated_bound_is_an_error():
    with pytest.raises(cpubudget.AnalysisError, match="spin: loop"):
        cpubudget.Analyser(image()).worst("spin")
    assert cpubudget.Analyser(image(), loop_bounds={"spin": 0}).worst("spin").insns == 4


def test_an_unresolved_indirect_call_is_an_error_and_a_resolved_one_charges_its_worst_target():
    with pytest.raises(cpubudget.AnalysisError, match="indirect call"):
        cpubudget.Analyser(image()).worst("via_pointer")
    a = cpubudget.Analyser(image(), indirect={"via_pointer": ("leaf", "diamond")})
    own = 4 + (2 + 1 + 1) + 7  # push, blx 2+1+1, pop {r4, pc}
    assert a.worst("via_pointer").cycles == own + max(a.worst("leaf").cycles, a.worst("diamond").cycles)


def test_the_edge_rate_is_the_no_load_speed_times_the_counts():
    rev_s = 49.8 * 5.86 / (2 * math.pi)
    assert rev_s == pytest.approx(46.4, abs=0.05)
    assert cpubudget.max_edge_rate_hz() == pytest.approx(2 * 400 * rev_s)
    assert 37_000 < cpubudget.max_edge_rate_hz() < 37_300


@given(
    own=st.integers(1, 5000),
    block=st.integers(0, 5000),
    urgent=st.lists(st.tuples(st.integers(1, 2000), st.integers(2000, 50_000)), max_size=3),
)
def test_a_response_is_the_least_fixed_point_of_the_interference_equation(own, block, urgent):
    """R = B + C + sum ceil(R / T) C_j: the value returned satisfies it, and no smaller R >= B + C does."""

    def rhs(r):
        return block + own + sum(-(-r // t) * c for c, t in urgent)

    above = [(f"j{i}", c, t, "") for i, (c, t) in enumerate(urgent)]
    r = cpubudget._response("x", 1, own, 10**9, [("b", block, "")], above)
    if sum(c / t for c, t in urgent) < 0.9:  # otherwise the busy period may be enormous: only check it is consistent
        assert r.cycles is not None
    if sum(c / t for c, t in urgent) >= 1:
        assert r.cycles is None and "fill the CPU" in r.why  # no finite response exists
    if r.cycles is not None:
        assert rhs(r.cycles) == r.cycles
        assert all(rhs(x) > x for x in range(block + own, r.cycles, max(1, (r.cycles - block - own) // 50)))


def test_a_handler_without_a_bound_at_the_same_or_a_higher_priority_leaves_no_bound():
    same = cpubudget._response("edge", 0, 400, 2600, [("EIC", 400, ""), ("USB", None, "busy-waits")], [])
    assert same.cycles is None and not same.ok and "USB shares priority 0" in same.why
    above = cpubudget._response("tick", 1, 1600, 24000, [], [("USB", None, None, "busy-waits")])
    assert above.cycles is None and "USB is more urgent" in above.why
    rate = cpubudget._response("tick", 1, 1600, 24000, [], [("X", 100, None, "")])
    assert rate.cycles is None and "nothing bounds its rate" in rate.why


TINY = """
00000200 <TC3_Handler>:
     200:\tbx\tlr

00000202 <EIC_Handler>:
     202:\tbx\tlr

00000204 <hw_isr_encoder_alpha>:
     204:\tbx\tlr

00000206 <hw_isr_encoder_beta>:
     206:\tbx\tlr

00000208 <mc_quad_snapshot>:
     208:\tmrs\tr3, PRIMASK
     20c:\tcpsid\ti
     20e:\tldr\tr2, [r0, #0]
     210:\tldr\tr1, [r0, #4]
     212:\tldr\tr1, [r0, #8]
     214:\tldr\tr1, [r0, #12]
     216:\tldr\tr1, [r0, #16]
     218:\tldr\tr1, [r0, #20]
     21a:\tmsr\tPRIMASK, r3
     21e:\tbx\tlr
"""


def test_a_masked_section_holds_off_the_edges_and_an_unknown_one_leaves_no_bound():
    prio = {"EIC": 0, "TC3": 1, "SERCOM2": 2, "USB": 3}
    img = cpubudget.parse_disassembly(TINY)
    b = cpubudget.cell_budget(img, priorities=prio)
    masked = cpubudget.Analyser(img).worst("mc_quad_snapshot").cycles
    edge_c = b.isrs[1].cycles
    assert masked > edge_c  # a bare handler costs less than the copy here, so the copy is the blocking term
    assert b.responses[0].cycles == masked + edge_c and "masked mc_quad_snapshot" in b.responses[0].why
    unknown = TINY + "\n00000220 <mystery>:\n     220:\tcpsid\ti\n     222:\tbx\tlr\n"
    b = cpubudget.cell_budget(cpubudget.parse_disassembly(unknown), priorities=prio)
    assert [r.cycles for r in b.responses] == [None, None]
    assert "interrupts masked in mystery" in b.responses[0].why


# ---------------------------------------------------------------------------- the real image

ELF = ROOT / ".pio" / "build" / "cell" / "firmware.elf"


def test_real_cell_image_interrupts_stay_within_the_budget(build_log):  # noqa: F811
    img = cpubudget.parse_disassembly(cpubudget.disassemble(ELF))
    b = cpubudget.cell_budget(img)
    tick, edge = b.isrs
    # cycles can never be fewer than instructions plus the exception entry and exit
    for isr in b.isrs:
        assert isr.cycles >= isr.insns + b.model.exc_entry + b.model.exc_exit
    assert tick.rate_hz == 2000 and edge.rate_hz == cpubudget.max_edge_rate_hz()
    assert b.total == pytest.approx(sum(i.cycles * i.rate_hz for i in b.isrs) / 48e6)
    assert b.total < cpubudget.BUDGET_LIMIT, cpubudget.format_budget(b, str(ELF))
    r = subprocess.run(
        [sys.executable, "-m", "metacell_tools.fwcheck", "cpu-budget", "--elf", str(ELF)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "limit 50%: within" in r.stdout


@pytest.mark.skipif(
    shutil.which(armbuild.CC) is None or shutil.which("qemu-system-arm") is None,
    reason="arm-none-eabi-gcc / qemu-system-arm missing (tools/setup.sh installs them)",
)
def test_static_worst_instructions_bound_every_tick_counted_under_qemu():
    """Cross-check without PlatformIO: on the QEMU bench image, the longest path by instructions is at least
    the most instructions any traced mc_cell_tick / mc_quad_update / mc_quad_snapshot executed."""
    from metacell_tools.fwcheck import qemu

    elf = qemu.build_image("bench")
    s = qemu.tick_stats(elf)
    a = cpubudget.Analyser(
        cpubudget.parse_disassembly(cpubudget.disassemble(elf)),
        loop_bounds=cpubudget.CELL_LOOP_BOUNDS,
        metric="insns",
    )
    assert a.worst("mc_cell_tick").insns >= max(s.ticks)
    assert a.worst("mc_quad_update").insns >= max(s.quad_update)
    assert a.worst("mc_quad_snapshot").insns >= max(s.snapshot)


def test_real_cell_image_responses_under_its_own_priorities(build_log):  # noqa: F811
    """With the priorities the image sets, an edge is sampled before its encoder's next edge and the tick ends
    before the next one; with USB back beside the EIC (the core's map) neither has a bound: the USB handler's
    busy-waits are on the path."""
    from metacell_tools.fwcheck import irqmap

    img = cpubudget.parse_disassembly(cpubudget.disassemble(ELF))
    prio = irqmap.effective_priorities(ELF)
    assert prio["EIC"] < prio["TC3"] < prio["USB"]
    b = cpubudget.cell_budget(img, priorities=prio)
    edge, tick = b.responses
    tick_c, edge_c = (i.cycles for i in b.isrs)
    assert edge.ok and edge.cycles == 2 * edge_c  # the other encoder's entry, then its own
    assert tick.ok and tick.cycles >= tick_c + edge_c
    assert edge.deadline == int(48e6 / (cpubudget.max_edge_rate_hz() / 2)) and tick.deadline == 24_000
    core = cpubudget.cell_budget(img, priorities={**prio, "USB": prio["EIC"]})
    assert [r.cycles for r in core.responses] == [None, None]
    assert "USB shares priority" in core.responses[0].why and "USB is more urgent" in core.responses[1].why


def test_real_addressed_cell_image_bounds_the_i2c_secondary_event(addressed_cell_elf):  # noqa: F811
    """With the bus glue linked, one SERCOM2 event (its handler, the callbacks, a SysTick beside it, the edges and
    the tick above it) ends inside the primary's transaction timeout, and lasts longer than INACTOUT's longest
    setting: the reason that timeout stays off on the primary."""
    from metacell_tools.fwcheck import irqmap

    img = cpubudget.parse_disassembly(cpubudget.disassemble(addressed_cell_elf))
    b = cpubudget.cell_budget(img, priorities=irqmap.effective_priorities(addressed_cell_elf))
    names = [r.name for r in b.responses]
    assert names == ["encoder edge (EIC)", "control tick (TC3)", "I2C secondary event (SERCOM2)"]
    i2c = b.responses[2]
    assert i2c.ok and i2c.priority == 2 and i2c.deadline == int(48e6 * cpubudget.TXN_TIMEOUT_S)
    assert i2c.cycles > cpubudget.INACTOUT_MAX_S * 48e6
    assert "EIC" in i2c.why and "TC3" in i2c.why  # the edges and the tick pre-empt it
    text = cpubudget.format_budget(b, str(addressed_cell_elf))
    assert "longer than INACTOUT's longest setting" in text
