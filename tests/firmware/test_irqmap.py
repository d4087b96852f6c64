"""`fwcheck irq` on linked images: a fake image per defect, then the real cell and primary images."""

import fcntl
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from metacell_tools.fwcheck import irqmap
from tests.firmware.test_pio_build import PIO, _how, build_log  # noqa: F401  (the shared, locked real build)

ROOT = Path(__file__).resolve().parents[2]
CC = "arm-none-eabi-gcc"

# A stand-in image with the shape fwcheck irq reads: the vector table, the fault path, the priority table and setup's
# calls. Each -D turns one thing wrong.
FAKE = r"""
#include <stdint.h>
#define NOINL __attribute__((noinline, used))
volatile uint32_t sink;
NOINL void Reset_Handler(void) { sink = 1; }
NOINL void Dummy_Handler(void) { sink = 2; }
NOINL void NMI_Handler(void) { sink = 3; }
NOINL void SysTick_Handler(void) { sink = 4; }
NOINL void USB_Handler(void) { sink = 5; }
NOINL void SERCOM2_Handler(void) { sink = 6; }
NOINL void SERCOM4_Handler(void) { sink = 7; }
NOINL void EIC_Handler(void) { sink = 8; }
NOINL void TC3_Handler(void) { sink = 9; }
NOINL void hw_drivers_off(void) { sink = 10; }
NOINL void other(void) { sink = 11; }
NOINL void sys_safe_outputs(void) {
#ifndef SAFE_EMPTY
    hw_drivers_off();
#endif
    sink = 12;
}
NOINL void sys_fault(void) {
#ifdef LATE_SAFE
    other();
#endif
    sys_safe_outputs();
    sink = 13;
}
NOINL void sys_fault_entry(void) { sys_fault(); sink = 14; }
#ifdef USB_PRIO0
const uint8_t hw_irq_priority[4][2] = {{4, 0}, {18, 1}, {11, 2}, {7, 0}};
#else
const uint8_t hw_irq_priority[4][2] = {{4, 0}, {18, 1}, {11, 2}, {7, 3}};
#endif
NOINL void hw_irq_priorities(void) { sink = hw_irq_priority[sink & 3][1]; }
NOINL void hw_encoders_init(void) { sink = 20; }
NOINL void hw_tick_start(void) { sink = 21; }
NOINL void bus_setup(void) { sink = 22; }
NOINL void setup(void) {
    hw_encoders_init();
    hw_tick_start();
#ifndef LATE_BUS
    bus_setup();
#endif
    hw_irq_priorities();
#ifdef LATE_BUS
    bus_setup();
#endif
    sink = 23;
}
extern uint32_t __StackTop;
#define F sys_fault_entry
#ifdef DUMMY_SERCOM0
#define S0 Dummy_Handler
#else
#define S0 F
#endif
#ifdef NO_HARDFAULT
#define HF Dummy_Handler
#else
#define HF F
#endif
void *const exception_table[45] = {
    &__StackTop, Reset_Handler, NMI_Handler, HF, 0, 0, 0, 0, 0, 0, 0, F, 0, 0, F, SysTick_Handler,
    F, F, F, F, EIC_Handler, F, F, USB_Handler, F, S0, F, SERCOM2_Handler, F, SERCOM4_Handler, F,
    F, F, F, TC3_Handler, F, F, F, F, F, F, F, F, F, 0};
"""


def fake_elf(tmp_path: Path, *defines: str, record: int = 0x2000_7800) -> Path:
    src, elf = tmp_path / "fake.c", tmp_path / f"fake{''.join(defines)}{record:x}.elf"
    src.write_text(FAKE)
    link = ["__StackTop=0x20008000", "__bss_end__=0x20000400", "__HeapLimit=0x20000400", f"mc_fault_record={record:#x}"]
    cmd = [CC, "-mcpu=cortex-m0plus", "-mthumb", "-Os", "-nostdlib", "-ffunction-sections", *defines]
    cmd += ["-Wl,-Ttext=0x2000", "-Wl,-e,Reset_Handler", *(f"-Wl,--defsym={d}" for d in link), str(src), "-o", str(elf)]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return elf


needs_cc = pytest.mark.skipif(shutil.which(CC) is None, reason=f"{CC} missing (tools/setup.sh installs it)")


@needs_cc
def test_the_fake_image_passes_as_it_is(tmp_path):
    rep = irqmap.check(fake_elf(tmp_path), "cell")
    assert rep.ok, rep.errors
    assert rep.priorities == {"EIC": 0, "TC3": 1, "SERCOM2": 2, "USB": 3}


@needs_cc
@pytest.mark.parametrize(
    "define,role,message",
    [
        ("-DDUMMY_SERCOM0", "cell", "SERCOM0: vector is Dummy_Handler"),
        ("-DNO_HARDFAULT", "cell", "HardFault: vector is Dummy_Handler"),
        ("-DUSB_PRIO0", "cell", "USB is not below the tick"),
        ("-DLATE_BUS", "cell", "setup calls ['bus_setup'] after hw_irq_priorities"),
        ("-DLATE_SAFE", "cell", "first call is ['other'], not sys_safe_outputs"),
        ("-DSAFE_EMPTY", "cell", "does not call hw_drivers_off"),
        # the primary handles neither the EIC nor TC3: an image that does is not the primary's
        ("", "primary", "EIC: vector is EIC_Handler, not sys_fault_entry"),
    ],
)
def test_each_wrong_thing_in_an_image_is_named(tmp_path, define, role, message):
    rep = irqmap.check(fake_elf(tmp_path, *([define] if define else [])), role)
    assert not rep.ok
    assert any(message in e for e in rep.errors), rep.errors


@needs_cc
@pytest.mark.parametrize("record", [0x2000_0200, 0x2000_4F00, 0x2000_7C00, 0x2000_7802])
def test_a_fault_record_the_bootloader_or_the_boot_stack_can_overwrite_is_refused(tmp_path, record):
    rep = irqmap.check(fake_elf(tmp_path, record=record), "cell")
    assert any("mc_fault_record" in e for e in rep.errors), rep.errors


@needs_cc
def test_the_cli_exits_1_on_a_wrong_image_and_2_without_one(tmp_path):
    bad = fake_elf(tmp_path, "-DUSB_PRIO0")
    run = [sys.executable, "-m", "metacell_tools.fwcheck", "irq", "--role", "cell", "--elf"]
    r = subprocess.run([*run, str(bad)], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 1 and "FAILED" in r.stdout
    r = subprocess.run([*run, str(tmp_path / "none.elf")], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 2 and "--elf must name a linked image" in r.stderr


# ---------------------------------------------------------------------------- the real images


@pytest.fixture(scope="module")
def addressed_cell_elf(build_log, tmp_path_factory):  # noqa: F811
    """Cell 1 as `python -m metacell_tools.flash` builds it (its own build dir, the per-cell defines): only such an
    image calls bus_setup, the last priority setter before the cell's table."""
    shared = tmp_path_factory.getbasetemp().parent
    out = shared / "pio-cell01"
    elf = out / "cell" / "firmware.elf"
    with open(shared / "pio_build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not elf.exists():
            cmd, _ = _how()
            env = dict(
                os.environ,
                PIO=str(PIO),
                PATH=f"{PIO.parent}{os.pathsep}{os.environ.get('PATH', '')}",
                PIO_OFFLINE_WORK=str(shared / "pio-cell01-work"),
                PLATFORMIO_BUILD_DIR=str(out),
                PLATFORMIO_BUILD_SRC_FLAGS="-DMC_CELL_INDEX=1 -DMC_CELL_ADDR=0x10",
            )
            args = ["run", "-e", "cell"]
            r = subprocess.run(
                [*(cmd or [str(PIO)]), *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=900
            )
            assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
    return elf


@pytest.mark.parametrize("role", ["cell", "primary"])
def test_real_images_route_every_unhandled_vector_to_the_fault_entry(build_log, role):  # noqa: F811
    elf = ROOT / ".pio" / "build" / role / "firmware.elf"
    rep = irqmap.check(elf, role)
    assert rep.ok, irqmap.format_report(rep, str(elf))
    assert rep.vectors["HardFault"] == irqmap.FAULT_ENTRY
    assert {s for s, h in rep.vectors.items() if h != irqmap.FAULT_ENTRY} == irqmap.LIVE[role]
    assert rep.record == 0x2000_7800


def test_real_addressed_cell_image_sets_its_priorities_last(addressed_cell_elf):
    sym = irqmap.symbols(addressed_cell_elf)
    seq = irqmap.calls(addressed_cell_elf, "setup", sym)
    assert "bus_setup" in seq and seq.index("bus_setup") < seq.index(irqmap.APPLY)
    rep = irqmap.check(addressed_cell_elf, "cell")
    assert rep.ok, irqmap.format_report(rep, str(addressed_cell_elf))
    assert rep.priorities == {"EIC": 0, "TC3": 1, "SERCOM2": 2, "USB": 3}
    r = subprocess.run(
        [sys.executable, "-m", "metacell_tools.fwcheck", "irq", "--role", "cell", "--elf", str(addressed_cell_elf)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0 and "NVIC priorities (0 = most urgent): EIC 0, TC3 1, SERCOM2 2, USB 3" in r.stdout
