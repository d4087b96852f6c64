"""The image tier's board wiring (host_emulator/image/board.py) against the documented wiring tables, the firmware's
pin definitions and the XIAO variant's pin table; pin_number's parsing."""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import pytest
from hypothesis import given
from hypothesis import strategies as st

from host_emulator.image import board, regtable
from tests.host_emulator.image import vendor

ROOT = Path(__file__).resolve().parents[3]
PIN = re.compile(r"P[AB](?:[0-2][0-9]|3[01])", re.ASCII)

# how the documents name each wired signal (a row of a wiring table names exactly one)
DOC_SIGNAL = {
    "nsleep": r"\bnSLEEP\b",
    "ph_alpha": r"^PH\b.*\balpha driver\b",
    "ph_beta": r"^PH\b.*\bbeta driver\b",
    "en_alpha": r"^EN\b.*\balpha driver\b",
    "en_beta": r"^EN\b.*\bbeta driver\b",
    "sda": r"\bSDA\b",
    "scl": r"\bSCL\b",
    "enc_alpha_a": r"\balpha encoder A\b",
    "enc_alpha_b": r"\balpha encoder B\b",
    "enc_beta_a": r"\bbeta encoder A\b",
    "enc_beta_b": r"\bbeta encoder B\b",
}
# the firmware's CELL_PIN_<NAME> (src/cell/cell_config.h) of each signal
FW_SIGNAL = {
    "NSLEEP": "nsleep",
    "DIR_A": "ph_alpha",
    "DIR_B": "ph_beta",
    "PWM_A": "en_alpha",
    "PWM_B": "en_beta",
    "SDA": "sda",
    "SCL": "scl",
    "ENC_A_A": "enc_alpha_a",
    "ENC_A_B": "enc_alpha_b",
    "ENC_B_A": "enc_beta_a",
    "ENC_B_B": "enc_beta_b",
}


def wiring_rows(path: Path) -> list[tuple[int, str, str]]:
    """(XIAO digital pin, SAMD21 pin, what it connects to) of every D-pin row of a markdown wiring table; a row
    "| D7 / D8 | PB09 / PA07 | alpha encoder A / B |" is two rows."""
    rows = []
    for line in path.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 3 or not re.fullmatch(r"D\d+( / D\d+)*", cells[0]):
            continue
        xiao, pins = cells[0].split(" / "), cells[1].split(" / ")
        what = [cells[2]]
        if len(xiao) > 1:
            m = re.fullmatch(r"(.*)\b(\w) / (\w)", cells[2])
            assert m, f"{path.name}: cannot split {cells[2]!r} over {xiao}"
            what = [m.group(1) + m.group(2), m.group(1) + m.group(3)]
        assert len(xiao) == len(pins) == len(what), f"{path.name}: {line}"
        rows += [(int(x[1:]), p, w.replace("*", "")) for x, p, w in zip(xiao, pins, what)]
    return rows


@pytest.mark.parametrize("doc", ["docs/hardware.md", "README.md"])
def test_the_wiring_is_the_documented_table(doc):
    rows = wiring_rows(ROOT / doc)
    assert sorted(x for x, _, _ in rows) == list(range(11)), f"{doc}: the table does not list D0..D10 once each"
    claimed = {}
    for signal, pattern in DOC_SIGNAL.items():
        hits = [r for r in rows if re.search(pattern, r[2])]
        assert len(hits) == 1, f"{doc}: {signal} is in {len(hits)} rows: {hits}"
        xiao, pin, _ = hits[0]
        assert PIN.fullmatch(pin), f"{doc}: D{xiao}: {pin!r} is not a port pin"
        assert board.CELL_WIRING[signal] == pin, f"{doc}: {signal} on {pin}, board.py wires {board.CELL_WIRING[signal]}"
        claimed[xiao] = signal
    assert len(claimed) == len(rows) == len(board.CELL_WIRING), f"{doc}: rows no signal claims: {rows}"


def test_the_documented_xiao_pins_are_the_variants():
    """The documents' D<n> -> PAxx column against the Seeed core's own table (D<n> is g_APinDescription[n])."""
    pins = vendor.variant_pins()
    for doc in ("docs/hardware.md", "README.md"):
        for xiao, pin, what in wiring_rows(ROOT / doc):
            assert pins[xiao].port_pin == pin, f"{doc}: D{xiao} ({what}) is {pins[xiao].port_pin} in the variant"


def cell_pins() -> dict[str, int]:
    text = (ROOT / "src" / "cell" / "cell_config.h").read_text()
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^#define\s+CELL_PIN_(\w+)\s+(\d+)\b", text, re.M)}


def test_the_firmware_drives_and_reads_the_wired_pins_through_the_variant():
    fw = cell_pins()
    assert set(fw) == set(FW_SIGNAL), f"cell_config.h pins not mapped to a signal here: {set(fw) ^ set(FW_SIGNAL)}"
    pins = vendor.variant_pins()
    for name, arduino in fw.items():
        signal = FW_SIGNAL[name]
        assert pins[arduino].port_pin == board.CELL_WIRING[signal], (
            f"CELL_PIN_{name} = D{arduino} = {pins[arduino].port_pin}; board.py wires {signal} to "
            f"{board.CELL_WIRING[signal]}"
        )


def test_the_firmwares_own_port_facts_are_the_wiring():
    """samd21_hw.cpp's fast paths use port/bit facts ({CELL_PIN_X, PA|PB, bit}) checked against the variant at
    start-up; they must name the same pins."""
    text = (ROOT / "src" / "cell" / "samd21_hw.cpp").read_text()
    facts = re.findall(r"\{\s*CELL_PIN_(\w+)\s*,\s*(PA|PB)\s*,\s*(\d+)\s*\}", text)
    assert len(facts) >= 9, facts
    for name, port, bit in facts:
        assert f"{port}{int(bit):02d}" == board.CELL_WIRING[FW_SIGNAL[name]], name


def test_the_bus_pins_of_both_roles_are_the_cores_wire_pins():
    """Both images reach the bus through the core's Wire on the variant's PIN_WIRE_SDA/SCL."""
    pins = vendor.variant_pins()
    sda, scl = vendor.variant_define("PIN_WIRE_SDA"), vendor.variant_define("PIN_WIRE_SCL")
    for wiring in (board.CELL_WIRING, board.PRIMARY_WIRING):
        assert (wiring["sda"], wiring["scl"]) == (pins[sda].port_pin, pins[scl].port_pin)
    fw = cell_pins()
    assert (fw["SDA"], fw["SCL"]) == (sda, scl)


def test_every_wired_pin_is_distinct():
    assert len(set(board.CELL_WIRING.values())) == len(board.CELL_WIRING)


def test_wire_sets_the_runtime_config_by_motor_and_channel():
    cfg = SimpleNamespace()
    board.wire(cfg)
    n = {k: board.pin_number(v) for k, v in board.CELL_WIRING.items()}
    assert cfg.pin_nsleep == n["nsleep"]
    assert list(cfg.pin_ph) == [n["ph_alpha"], n["ph_beta"]]
    assert list(cfg.pin_en) == [n["en_alpha"], n["en_beta"]]
    assert [list(p) for p in cfg.pin_enc] == [[n["enc_alpha_a"], n["enc_alpha_b"]], [n["enc_beta_a"], n["enc_beta_b"]]]
    assert (cfg.pin_sda, cfg.pin_scl) == (n["sda"], n["scl"])
    assert f"SERCOM{cfg.bus_sercom}" == board.BUS_SERCOM


def test_the_bus_sercom_is_the_one_the_wiring_table_names():
    """The runtime's I2C bus is the SERCOM board.BUS_SERCOM names (no instance is wired in the C); docs/hardware.md's
    SDA row says which ("I2C secondary (SERCOMn)"). Its pads on SDA/SCL: test_regtable's bus-pins test."""
    sda = board.CELL_WIRING["sda"]
    rows = [line for line in (ROOT / "docs/hardware.md").read_text().splitlines() if f"| {sda} |" in line]
    assert len(rows) == 1, rows
    named = re.findall(r"\((SERCOM\d)\)", rows[0])
    assert named == [board.BUS_SERCOM], rows[0]


# ---------------------------------------------------------------- pin_number


@given(st.sampled_from("AB"), st.integers(0, 31))
def test_pin_number_of_every_port_pin(port, n):
    name = f"P{port}{n:02d}"
    num = board.pin_number(name)
    assert num == (32 if port == "B" else 0) + n
    assert regtable.PinFunction(num, 0, "", "").name == name + "A"  # the register table names it back


# a port-like prefix and a short tail, often of digits of any script (str.isdigit accepts "٠١" and "¹²")
near_pin = st.builds(
    lambda a, b: a + b,
    st.sampled_from(["PA", "PB", "Pa", "pB", "PC", "P", "", " PA"]),
    st.one_of(st.text(max_size=3), st.text(st.characters(categories=("Nd", "No")), max_size=3)),
)


@given(st.one_of(st.text(max_size=6), near_pin))
def test_pin_number_rejects_anything_else_with_a_clear_error(text):
    if PIN.fullmatch(text):
        return
    with pytest.raises(ValueError) as e:
        board.pin_number(text)
    assert repr(text) in str(e.value) and "PA10" in str(e.value)


@pytest.mark.parametrize(
    "name", ["PA32", "PB99", "PC01", "pa01", "PA1", "PA001", "PB-1", " PA01", "PA01 ", "PA+1", "PA٠١", "PA¹²", ""]
)
def test_pin_number_rejects_near_misses(name):
    with pytest.raises(ValueError, match="expected a SAMD21 port pin"):
        board.pin_number(name)
