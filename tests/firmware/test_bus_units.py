"""Wire units and firmware limits: C constants, the codec and the firmware's verdicts follow protocol/definition.py."""

import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol import codec, wire
from protocol import definition as D

ROOT = Path(__file__).resolve().parents[2]


def test_c_library_constants_are_the_definitions(fw):
    _, lib = fw
    assert lib.MC_COUNTS_PER_REV == D.COUNTS_PER_REV
    assert lib.MC_TORQUE_WIRE_UNM == D.TORQUE_WIRE_UNM
    for name, value in D.LIMITS.items():
        assert getattr(lib, f"MC_{name}") == value
    assert lib.MC_ADDR_BASE == D.ADDR_BASE


def test_every_unit_and_range_is_well_formed():
    for name, u in D.UNITS.items():
        assert ("micro" in u) != ("lsb" in u), name
        assert codec.lsb(name) > 0
    for reg, r in D.REGISTERS.items():
        names = [f[0] for f in r["payload"]]
        for f in r["payload"]:
            assert f[2] is None or f[2] in D.UNITS, (reg, f)
        for field, (lo, hi) in r.get("range", {}).items():
            assert field in names and lo <= hi, (reg, field)
            tlo, thi = wire.TYPE_RANGES[dict((f[0], f[1]) for f in r["payload"])[field]]
            assert tlo <= lo and hi <= thi, (reg, field, "range outside the field's type")


SI_FIELDS = [(reg, f[0]) for reg, r in D.REGISTERS.items() for f in r["payload"] if f[2] in D.UNITS]


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(SI_FIELDS), st.floats(-1e3, 1e3))
def test_codec_round_trips_within_half_an_lsb_or_refuses(field, x):
    reg, name = field
    slo, shi = codec.si_range(reg, name)
    step = codec.lsb(codec.unit_of(reg, name))
    try:
        raw = codec.to_register(reg, name, x)
    except codec.RangeError:
        assert not slo - step / 2 < x < shi + step / 2  # refused only outside the range (rounding at the edge)
        return
    lo, hi = codec.raw_range(reg, name)
    assert lo <= raw <= hi
    assert abs(codec.from_register(reg, name, raw) - x) <= step / 2 * (1 + 1e-9) + 1e-12
    wire.pack_payload(reg, **{f[0]: raw if f[0] == name else 0 for f in D.REGISTERS[reg]["payload"]})


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, "1", None, True])
def test_codec_refuses_non_numbers(bad):
    with pytest.raises(codec.RangeError):
        codec.to_register("K_AB", "value", bad)


def test_codec_refuses_unknown_registers_and_fields():
    with pytest.raises(codec.RangeError, match="unknown register"):
        codec.to_register("NOPE", "value", 0.0)
    with pytest.raises(codec.RangeError, match="no field"):
        codec.to_register("K_AB", "torque", 0.0)
    with pytest.raises(codec.RangeError, match="payload fields"):
        codec.encode("PERTURB", chain=0, torque=0.01)


def test_codec_torque_scale_is_the_wire_unit():
    """An independent statement of the PERTURB torque scale: raw = round(torque / (TORQUE_WIRE_UNM uN*m))."""
    for t in (0.0, 1e-6, 0.02, -0.05, codec.PERTURB_MAX_NM):
        assert codec.to_register("PERTURB", "torque", t) == round(t * 1e6 / D.TORQUE_WIRE_UNM)


@settings(max_examples=200, deadline=None)
@given(st.integers(-(2**15), 2**15 - 1), st.integers(0, 1))
def test_firmware_accepts_a_wire_torque_iff_the_codec_range_does(fw, raw, chain):
    """The compiled cell (torque = raw * MC_TORQUE_WIRE_UNM, |torque| <= MC_PERTURB_MAX_UNM) and the codec agree."""
    ffi, lib = fw
    c = ffi.new("mc_cell_t *")
    lib.mc_cell_init(c)
    lo, hi = codec.raw_range("PERTURB", "torque")
    ok = lib.mc_cell_perturb(c, chain, raw * lib.MC_TORQUE_WIRE_UNM, 1) == lib.MC_OK
    assert ok == (lo <= raw <= hi)


def test_firmware_gain_and_astar_limits_match_the_codec(fw):
    ffi, lib = fw
    c = ffi.new("mc_cell_t *")
    lib.mc_cell_init(c)
    p = ffi.new("mc_reaction_phys_t *")
    for reg, member in (("K_AB", "k_ab_unm"), ("SIGMA", "sigma_unm"), ("ASTAR", "astar_urad")):
        lo, hi = codec.raw_range(reg, "value")
        for v, ok in ((lo, True), (hi, True), (lo - 1, False), (hi + 1, False)):
            lib.mc_cell_default_params(p)
            setattr(p, member, v)
            assert (lib.mc_cell_set_params(c, p) == lib.MC_OK) == ok, (reg, v)


def test_emulator_does_not_import_the_laptop_tools():
    code = (
        "import sys, host_emulator.bus.rig, host_emulator.bus.serve, host_emulator.benchmarks.bus;"
        "import host_emulator.models.hil;"
        "bad = sorted(m for m in sys.modules if m == 'metacell_tools' or m.startswith('metacell_tools.'));"
        "assert not bad, bad"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr


# Wire facts that must come from protocol/ only: a literal restatement anywhere else in the code is a second copy.
RESTATED = [
    re.compile(r"\b131000\b"),  # PERTURB_MAX_UNM
    re.compile(r"\b0\.131\b"),  # the same limit in N*m
    re.compile(r"2 \* (math|np)\.pi / 400\b|\b400 / \(2 \* (math|np)\.pi\)"),  # COUNTS_PER_REV
    re.compile(r"ADDR_BASE\s*=\s*0x"),
    re.compile(r"(1e6|1e-6) / 4\b|\b4e-6\b"),  # the wire torque unit
]
GENERATED = {"lib/metacell/src/bus/mc_proto.h", "lib/metacell/src/mc_units.h"}


def test_no_code_outside_protocol_restates_a_wire_fact():
    files = subprocess.run(
        ["git", "ls-files", "lib", "host_emulator", "metacell_tools"], capture_output=True, text=True, cwd=ROOT
    )
    hits = []
    for rel in files.stdout.split():
        if rel in GENERATED or not rel.endswith((".py", ".c", ".h")):
            continue
        for n, line in enumerate((ROOT / rel).read_text().splitlines(), 1):
            if rel.endswith(".py"):
                code = line.split("#")[0]
            else:  # C comments may name other facts (the 2^22 TU torque clamp is 0.131 N*m too)
                code = "" if line.strip().startswith("*") else line.split("/*")[0].split("//")[0]
            if any(p.search(code) for p in RESTATED):
                hits.append(f"{rel}:{n}: {line.strip()}")
    assert not hits, "\n".join(hits)


def test_codec_can_leave_the_verdict_to_the_cell():
    """firmware=False refuses only what the field cannot carry (the command tool lets the cell answer RANGE)."""
    k = codec.K_MAX_NM_PER_RAD + 0.05
    assert codec.to_register("SIGMA", "value", k, firmware=False) == round(k * 1e6)
    with pytest.raises(codec.RangeError, match="firmware accepts"):
        codec.to_register("SIGMA", "value", k)
    with pytest.raises(codec.RangeError, match="field carries"):
        codec.to_register("SIGMA", "value", 3000.0, firmware=False)
