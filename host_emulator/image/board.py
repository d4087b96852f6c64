"""The image tier's side of the cell board's wiring: the pins of metacell_common.target.wiring (the rig's wiring, one
definition) set into the emulated board's configuration (sam_world_cfg_t)."""

from __future__ import annotations

from metacell_common.target.wiring import BUS_SERCOM, CELL_WIRING, PRIMARY_WIRING, pin_number

__all__ = ["BUS_SERCOM", "CELL_WIRING", "PRIMARY_WIRING", "pin_number", "wire"]


def wire(cfg) -> None:
    """Set the wiring fields of a sam_world_cfg_t."""
    p = {k: pin_number(v) for k, v in CELL_WIRING.items()}
    cfg.pin_nsleep = p["nsleep"]
    cfg.pin_ph = [p["ph_alpha"], p["ph_beta"]]
    cfg.pin_en = [p["en_alpha"], p["en_beta"]]
    cfg.pin_enc = [[p["enc_alpha_a"], p["enc_alpha_b"]], [p["enc_beta_a"], p["enc_beta_b"]]]
    cfg.pin_sda = p["sda"]
    cfg.pin_scl = p["scl"]
    cfg.bus_sercom = int(BUS_SERCOM.removeprefix("SERCOM"))
