"""The committed snapshot of the register table (regsnapshot.SNAPSHOT) is what the vendor's headers give today: it can
never go stale silently. Needs the headers (MC_PIO_TREE); without them it skips in one line like the other checks."""

from __future__ import annotations

from host_emulator.image import regsnapshot, regtable
from tests.host_emulator.image import vendor


def test_the_snapshot_equals_a_fresh_one_from_the_headers():
    vendor.include_dirs()  # skips with one line when the headers are absent
    fresh = regsnapshot.fresh_snapshot_text()
    assert regsnapshot.SNAPSHOT.read_text() == fresh, (
        f"{regsnapshot.SNAPSHOT.name} is stale: regenerate it with "
        "`MC_PIO_TREE=<tree> python -m host_emulator.image.regsnapshot --write` and commit it"
    )


def test_the_snapshot_table_emits_the_same_c_table_as_the_headers():
    vendor.include_dirs()
    headers, snap = regtable.load(), regsnapshot.load_snapshot()
    assert snap.source == regsnapshot.SOURCE and snap.vendor_macros
    assert regtable.emit_c(snap) == regtable.emit_c(headers)
    assert [r.kind for r in snap.registers()] == [r.kind for r in headers.registers()]


def test_the_snapshot_keeps_every_vendor_macro_the_runtime_uses_as_the_headers_define_it():
    atmel, _ = vendor.include_dirs()
    macros = regsnapshot._vendor_macros(atmel)
    snap = regsnapshot.load_snapshot().vendor_macros or ()
    names = [body.split()[0].split("(")[0] for body in snap]
    assert {"TC_CTRLA_MODE_Pos", "EIC_CONFIG_SENSE0_FALL_Val", "WDT_CLEAR_CLEAR_KEY", "PM_RCAUSE_WDT"} <= set(names)
    assert all(macros[n] == body for n, body in zip(names, snap))


def test_without_the_headers_the_table_comes_from_the_snapshot(tmp_path, monkeypatch):
    monkeypatch.delenv("MC_PIO_TREE", raising=False)
    monkeypatch.delenv("PLATFORMIO_CORE_DIR", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    t = regsnapshot.load_or_snapshot(str(tmp_path))
    assert t.source == regsnapshot.SOURCE
    assert t.reg("TC3", "COUNT16.CC[0]").offset == 0x18 and t.periph("TC3").base == 0x42002C00
    h = regtable.emit_vendor_h(t)
    assert "#define TC_CTRLA_MODE_Pos 2\n" in h and "#include" not in h
