"""Golden vectors bit-identical between the host build and an emulated Cortex-M0; instructions per tick."""

import shutil

import numpy as np
import pytest

from metacell_tools.fwcheck import armbuild, hostvec, qemu

pytestmark = pytest.mark.skipif(
    shutil.which(armbuild.CC) is None or shutil.which(qemu.QEMU) is None,
    reason="arm-none-eabi-gcc / qemu-system-arm missing (tools/setup.sh installs them)",
)


@pytest.fixture(scope="module")
def host():
    return hostvec.host_vectors(qemu.DEFAULT_SEED)


@pytest.fixture(scope="module")
def ticks():
    return qemu.tick_stats()


def fam(records, f):
    return records[(records[:, 0] >> 24) == f]


def test_xorshift32_matches_the_textbook_recurrence():
    x = 2463534242
    for _ in range(1000):
        y = x ^ ((x << 13) & 0xFFFFFFFF)
        y ^= y >> 17
        y ^= (y << 5) & 0xFFFFFFFF
        assert hostvec.xorshift32(x) == y
        x = y


def test_qemu_run_is_bit_identical_to_the_host_build(host):
    tv = qemu.target_vectors(qemu.DEFAULT_SEED)
    identical, first = qemu.compare_records(host.records, tv.records)
    assert first is None, first
    assert tv.count == len(host.records) == identical >= 100_000
    assert tv.fnv == host.fnv


def test_mismatch_report_names_the_first_differing_vector(host):
    other = host.records.copy()
    other[54321, 9] ^= 1
    other[60000, 3] ^= 4
    identical, first = qemu.compare_records(host.records, other)
    assert identical == len(other) - 2
    assert first.startswith("first mismatch: record 54321, family drive")
    assert "<--" in first
    _, first = qemu.compare_records(host.records, other[:-5])
    assert first is not None


def test_vectors_cover_every_family_and_the_edges(host):
    r = host.records
    counts = {f: len(fam(r, f)) for f in hostvec.FAMILIES}
    assert counts == {1: 40000, 2: 6000, 3: 30000, 4: 10000, 5: 20000}
    rx = fam(r, 1)[:, 1:3].view(np.int32)
    assert rx.min() == np.iinfo(np.int32).min and rx.max() == np.iinfo(np.int32).max
    assert (np.abs(rx.astype(np.int64)) <= 2048).mean() > 0.5
    drv = fam(r, 3)
    assert set(np.unique(drv[:, 5].view(np.int32))) == {0}  # every drive config valid
    assert set(np.unique((drv[:, 0] >> 16) & 0xFF)) == set(range(6))
    sduty, lim = drv[:, 8].view(np.int32), drv[:, 12].view(np.int32)
    assert (sduty == lim).any() and (sduty == -lim).any()  # both voltage clamps hit
    q = fam(r, 4)
    assert q[:, 11].sum() > 0 and (q[:, 9] > 0).sum() > 0  # saturation and glitches seen
    cell = fam(r, 5)
    enabled = (cell[:, 9] >> 24) & 1
    assert 0.1 < enabled.mean() < 0.9  # drive on and off
    for bit in range(6):
        assert ((cell[:, 8] >> bit) & 1).any(), f"fault bit {bit} never raised"


def test_rejected_parameters_leave_the_previous_ones(host):
    p = fam(host.records, 2)
    rc = p[:, 8].view(np.int32)
    unchanged = p[:, 9]
    for sub in range(6):
        sel = ((p[:, 0] >> 16) & 0xFF) == sub
        assert (rc[sel] != 0).any() and (rc[sel] == 0).any(), f"sub {sub}: no accept/reject mix"
    assert (unchanged[rc != 0] == 1).all()


def test_instruction_counter_is_exact_on_known_code(ticks):
    assert ticks.calibration == ticks.expected


def test_every_tick_was_measured(ticks):
    assert len(ticks.ticks) == len(ticks.tags) == 400
    assert ticks.select(enabled=True, fault=False, pert=True)
    assert ticks.select(fault=True) and ticks.select(enabled=False)
    # the drive path costs more than the outputs-off path
    assert min(ticks.select(enabled=True, fault=False)) > max(ticks.select(fault=True))


def test_instructions_per_tick_within_budget(ticks):
    """Every tick of the shipped default configuration (drive on, no fault, back-EMF
    compensation off) fits its budget; with compensation on, every tick fits the larger one."""
    default = ticks.select(**qemu.BUDGET_CASE)
    with_bemf = ticks.select(enabled=True, fault=False, bemf=True)
    assert len(default) >= 100 and len(with_bemf) >= 100
    print(
        f"\ninstructions per mc_cell_tick: default median {np.median(default)} max {max(default)}; "
        f"back-EMF on median {np.median(with_bemf)} max {max(with_bemf)}"
    )
    assert max(default) <= qemu.BUDGET
    assert max(with_bemf) <= qemu.BUDGET_BEMF
    assert np.median(with_bemf) > np.median(default)  # the observer really runs only when on


# --------------------------------------------------------------------------- linked-image lint


def test_lint_passes_a_linked_image_of_the_library():
    elf = qemu.build_image("vectors")
    rep = armbuild.lint_elf(elf)
    # the vector program links every root but mc_vel_update (not in its API table)
    assert rep.ok and rep.roots == [r for r in armbuild.CONTROL_ROOTS if r != "mc_vel_update"]


def test_lint_flags_a_linked_image_that_divides_or_floats(tmp_path):
    src = tmp_path / "bad.c"
    src.write_text(
        "static int __attribute__((noinline)) helper(int a, int b) { return a / b; }\n"
        "float scale(float x) { return x * 0.3f; }\n"
        "int ctl(int a, int b) { return helper(a, b) + (int)scale((float)a); }\n"
    )
    obj = armbuild.compile_objects([src], tmp_path)[0]
    elf = tmp_path / "bad.elf"
    armbuild._run(
        [
            armbuild.CC,
            *armbuild.CPU_FLAGS,
            "-nostdlib",
            "-nostartfiles",
            "-Wl,-e,ctl",
            "-o",
            str(elf),
            str(obj),
            "-lgcc",
        ]
    )
    rep = armbuild.lint_elf(elf, ("ctl",))
    # libgcc's __aeabi_idiv and __divsi3 share one address; objdump names either
    assert [c[:2] for c in rep.division] == [["ctl", "helper"]]
    assert armbuild.DIVISION_RE.match(rep.division[0][-1])
    assert any(chain[-1] == "__aeabi_fmul" for chain in rep.softfloat)
    assert not rep.ok
    assert not armbuild.lint_elf(elf, ("mc_cell_tick",)).ok  # no root present: fails


# --------------------------------------------------------------------------- Unity tests (test/)


@pytest.fixture(scope="module")
def fresh_header():
    from metacell_tools.fwcheck import golden

    return golden.header_text()


def test_golden_header_is_current(fresh_header):
    from metacell_tools.fwcheck import golden

    assert golden.HEADER_PATH.read_text() == fresh_header, (
        "test/test_native_vectors/golden_vectors.h is stale: the library's behaviour changed. "
        "If intended, run `.venv/bin/python -m metacell_tools.fwcheck golden-header` and commit it."
    )
