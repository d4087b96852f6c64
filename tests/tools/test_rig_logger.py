"""Rig logger: decoding into arrays, gaps from sequence counters, reconnects, scheduled commands (virtual bus)."""

import struct
import threading
import time

import can
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.bus.rig import make_rig
from metacell_tools.rigtools import command, proto
from metacell_tools.rigtools.logger import RigLogger, SampleDecoder

BASE = proto.FRAMES["CELL_SAMPLE"]["base"]


def sample_msg(j, seq, a, b, t128=0, flags=0, ts=0.0):
    return can.Message(
        arbitration_id=BASE + j,
        data=struct.pack("<BhhHB", seq & 0xFF, a, b, t128 & 0xFFFF, flags),
        is_extended_id=False,
        timestamp=ts,
    )


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 255), st.lists(st.booleans(), min_size=5, max_size=600))
def test_gaps_match_the_dropped_samples(seq0, keep):
    """Drop arbitrary samples of cell 2 while cell 1 stays complete: every drop is reported, nothing else."""
    dec = SampleDecoder(n_cells=2, report=lambda t: None)
    for k, kept in enumerate(keep):
        dec.feed(sample_msg(1, seq0 + k, k, -k, t128=k * 70))
        if kept or k == len(keep) - 1:
            dec.feed(sample_msg(2, seq0 + k, 2 * k, 0, t128=k * 70 + 3))
    dec.flush()  # rows wait for the next heartbeat (there is none here)
    got = [(g[1], g[2], g[3]) for g in dec.gaps]
    # reference: consecutive missing cycles of cell 2 between two kept samples
    present = [k for k, kept in enumerate(keep) if kept or k == len(keep) - 1]
    ref = [(2, seq0 + p + 1, q - p - 1) for p, q in zip(present, present[1:]) if q - p > 1]
    assert got == ref
    arr = dec.arrays()
    assert arr["alpha_counts"].shape == (len(keep), 2)
    np.testing.assert_array_equal(arr["alpha_counts"][:, 0], np.arange(len(keep)))
    assert np.sum(~np.isnan(arr["alpha_counts"][:, 1])) == len(present)
    np.testing.assert_allclose(arr["t_s"][:, 0], np.arange(len(keep)) * 70 * 128e-6)


def test_decoded_arrays_equal_the_emulated_cells(tmp_path):
    rig, _ = make_rig("default")
    dec = SampleDecoder(report=lambda t: None)
    truth = []
    for _ in range(50):
        rig.advance_to(rig.t_us + 20_000)
        for fid, data in rig.frames():
            dec.feed(can.Message(arbitration_id=fid, data=data, is_extended_id=False))
        truth.append([rig.solver.cells[j].theta[0] for j in range(16)])
    arr = dec.arrays()
    assert not len(arr["gaps"])
    assert np.all(np.sum(~np.isnan(arr["alpha_counts"]), axis=0) >= 100)
    # the last complete cycle is within a tick or two of the cells' own angles
    last = arr["alpha_counts"][-2]
    assert np.max(np.abs(last - np.array(truth[-1]))) <= 3
    files = dec.save(tmp_path / "run", {"source": "emulator:hil"})
    d = np.load(files[0])
    np.testing.assert_array_equal(d["alpha_counts"], arr["alpha_counts"])
    np.testing.assert_allclose(d["alpha"], arr["alpha_counts"] * 2 * np.pi / 400)
    # the one run layout: he.load reads it back as the same angles, with the label given
    from host_emulator.workbench.datasets import load

    ds = load(files[0])
    assert ds.attrs["source"] == "emulator:hil" and ds["alpha"].dims == ("time", "cell")
    np.testing.assert_allclose(ds["alpha"].values, arr["alpha_counts"] * 2 * np.pi / 400)
    assert np.all(np.diff(ds["time"].values) > 0) and ds["time"].values[0] == 0.0
    lines = files[1].read_text().splitlines()
    assert lines[0].startswith("segment,cycle,cell") and len(lines) == 1 + len(dec.rows)


class FlakyBus:
    """A bus that serves a frame list and fails once in the middle."""

    def __init__(self, frames, fail_at):
        self.frames, self.fail_at, self.i = frames, fail_at, 0

    def recv(self, timeout=None):
        if self.i == self.fail_at:
            self.fail_at = -1
            raise can.CanOperationError("device disconnected")
        if self.i >= len(self.frames):
            time.sleep(0.01)
            return None
        self.i += 1
        return self.frames[self.i - 1]

    def shutdown(self):
        pass


def test_logger_survives_a_disconnect(tmp_path):
    frames = [sample_msg(j, k, k, k) for k in range(20) for j in (1, 2)]
    opened = []
    fails = iter([True, False])

    def open_bus():
        if opened and next(fails):
            raise can.CanInitializationError("port not there yet")
        bus = FlakyBus(
            frames if not opened else [sample_msg(j, k, k, k) for k in range(100, 110) for j in (1, 2)],
            fail_at=25 if not opened else -1,
        )
        opened.append(bus)
        return bus

    msgs = []
    log = RigLogger(
        "virtual", "x", tmp_path / "r", formats=("asc",), reconnect_s=0.01, open_bus=open_bus, report=msgs.append
    )
    log.run(duration=0.5)
    assert log.reconnects == 1 and len(opened) == 2
    assert any("connection lost" in m for m in msgs) and any("cannot open" in m for m in msgs)
    arr = log.arrays
    assert set(arr["segment"]) == {0, 1}
    assert np.sum(~np.isnan(arr["alpha_counts"])) == 25 + 20
    assert (tmp_path / "r.asc").exists() and (tmp_path / "r.npz").exists()


def test_logger_end_to_end_on_virtual_bus_with_scheduled_command(tmp_path):
    """Emulated primary frames on a python-can virtual bus; the logger's --do command gets its CMD_RESULT."""
    rig, _ = make_rig("exp5_rest")
    chan = f"rigtest-{time.time_ns()}"
    stop = threading.Event()

    def primary():
        with can.Bus(interface="virtual", channel=chan) as bus:
            while not stop.is_set():
                while (m := bus.recv(timeout=0)) is not None:
                    rig.feed(b"O\r" + f"t{m.arbitration_id:03X}{m.dlc}{bytes(m.data).hex()}\r".encode())
                rig.advance_to(rig.t_us + 5000)
                for fid, data in rig.frames():
                    bus.send(can.Message(arbitration_id=fid, data=data, is_extended_id=False))
                time.sleep(0.002)

    th = threading.Thread(target=primary, daemon=True)
    th.start()
    try:
        log = RigLogger("virtual", chan, tmp_path / "v", formats=("asc", "csv"), report=lambda t: None)
        log.commands = [(0.2, "enable 4 off"), (0.3, "set 4 sigma 0.3")]
        log.run(duration=1.0)
    finally:
        stop.set()
        th.join(2)
    assert [r for _, _, r in log.command_log] == [{4: "OK"}, {4: "RANGE"}]
    assert rig.solver.cells[3].enabled == 0
    arr = log.arrays
    assert np.all(np.sum(~np.isnan(arr["alpha_counts"]), axis=0) > 10)
    assert (tmp_path / "v.csv").exists()


def test_command_tool_rejects_bad_input():
    assert command.main(["-c", "x", "perturb", "3", "--torque", "1.0", "--duration", "0.1"]) == 2
    assert command.main(["-c", "x", "set", "3", "sigma", "nan"]) == 2
    with pytest.raises(SystemExit):
        command.main(["-c", "x", "enable", "17", "on"])
    reg, vals = command.build(
        command.parser().parse_args(
            ["-c", "x", "perturb", "2", "--torque", "0.02", "--duration", "0.1", "--chain", "beta"]
        )
    )
    # 0.02 N*m in wire LSBs of TORQUE_WIRE_UNM uN*m
    assert (reg, vals) == ("PERTURB", {"chain": 1, "torque": round(20000 / proto.D.TORQUE_WIRE_UNM), "ticks": 200})


def test_command_tool_info_reads_identity_and_parameters(fw):
    """RigClient.info over a virtual bus served by the emulated primary: identity, map id, parameters in force."""
    rig, _ = make_rig("exp5_rest")
    chan = f"riginfo-{time.time_ns()}"
    stop = threading.Event()

    def primary():
        with can.Bus(interface="virtual", channel=chan) as bus:
            while not stop.is_set():
                while (m := bus.recv(timeout=0)) is not None:
                    rig.feed(b"O\r" + f"t{m.arbitration_id:03X}{m.dlc}{bytes(m.data).hex()}\r".encode())
                rig.advance_to(rig.t_us + 5000)
                for fid, data in rig.frames():
                    bus.send(can.Message(arbitration_id=fid, data=data, is_extended_id=False))
                time.sleep(0.002)

    th = threading.Thread(target=primary, daemon=True)
    th.start()
    try:
        with can.Bus(interface="virtual", channel=chan) as bus:
            assert bus.recv(timeout=5) is not None  # the primary side is up
            client = command.RigClient(bus, timeout=2.0)
            assert client.command([7], "K_AB", value=31000) == {7: "OK"}
            info = client.info([7, 8])
    finally:
        stop.set()
        th.join(2)
    _, lib = fw
    for j in (7, 8):
        assert info[j]["results"] == ["OK", "OK"]
        assert info[j]["IDENT"]["addr"] == proto.cell_address(j)
        assert info[j]["IDENT"]["map_id"] == proto.map_id() == lib.MC_PROTO_MAP_ID
    assert (info[7]["PARAMS"]["k_ab"], info[8]["PARAMS"]["k_ab"]) == (31000, 20000)


class LateBus(FlakyBus):
    """Silent for `quiet` seconds after opening, then serves its frames."""

    def __init__(self, frames, quiet):
        super().__init__(frames, fail_at=-1)
        self.t0, self.quiet = time.monotonic(), quiet

    def recv(self, timeout=None):
        if time.monotonic() - self.t0 < self.quiet:
            time.sleep(0.01)
            return None
        return super().recv(timeout)


def test_duration_counts_from_the_first_frame_and_sighup_stops_in_order(tmp_path):
    import os
    import signal

    frames = [sample_msg(j, k, k, k, t128=k * 70) for k in range(200) for j in (1, 2)]
    log = RigLogger(
        "virtual",
        "x",
        tmp_path / "late",
        formats=("asc",),
        open_bus=lambda: LateBus(frames, 0.6),
        report=lambda t: None,
    )
    log.run(duration=0.3)  # the 0.6 s of silence before the first frame do not count
    assert np.sum(~np.isnan(log.arrays["alpha_counts"])) == 400
    log2 = RigLogger(
        "virtual", "x", tmp_path / "hup", formats=("asc",), open_bus=lambda: LateBus(frames, 0.0), report=lambda t: None
    )
    threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGHUP)).start()
    t0 = time.monotonic()
    log2.run(duration=30)
    # --duration 30 would end it too: the signal must end it well before (generous for a loaded machine)
    assert time.monotonic() - t0 < 25 and log2.stop_reason == "SIGHUP"
    assert np.sum(~np.isnan(log2.arrays["alpha_counts"])) == 400
    assert (tmp_path / "hup.npz").exists() and (tmp_path / "hup.asc").read_text().endswith("\n")
