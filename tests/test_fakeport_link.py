"""Lock-step and real-time pacing of sim:// ports, with the EchoDevice (15 ms ticks)."""

import time

import pytest
import serial

import guardid.fakeport as fp

frame = fp.EchoDevice.frame
N = fp.EchoDevice.FRAME_LEN


@pytest.fixture(autouse=True)
def echo_factory(monkeypatch):
    monkeypatch.delenv(fp.factory.DEVICE_ENV, raising=False)
    old = fp.register_device_factory(lambda robot, options: fp.EchoDevice())
    yield
    fp.register_device_factory(old)


def test_lockstep_read_semantics():
    port = serial.serial_for_url("sim://guard?seed=1", timeout=0.1)
    assert port.read(1) == b""  # 100 ms simulated: ticks at 15..90 ms
    assert (port.engine.ticks, port.engine.now_ns) == (6, 100_000_000)
    port.write(b"START")
    assert port.in_waiting == 5 and port.engine.ticks == 6
    assert port.read(5) == b"START"
    assert port.read(N) == frame(7, 0)
    assert (port.engine.ticks, port.engine.now_ns) == (7, 105_000_000)
    assert port.read(2 * N) == frame(8, 1) + frame(9, 2)
    port.timeout = 0
    assert port.read(N) == b"" and port.engine.ticks == 9
    port.timeout = 0.02  # until 155 ms: one tick (150 ms)
    assert port.read(100) == frame(10, 3)
    assert port.engine.now_ns == 155_000_000
    port.write(b"STOP")
    assert port.read(4) == b"STOP"
    port.timeout = None
    with pytest.raises(serial.SerialException, match="block forever"):
        port.read(1)
    port.close()
    with pytest.raises(serial.PortNotOpenError):
        port.read(1)


def test_lockstep_buffers_and_pacing_independent_of_host_speed():
    runs = []
    for pause in (0.0, 0.05):
        port = serial.serial_for_url("sim://guard", timeout=1.0)
        port.write(b"START")
        time.sleep(pause)
        port.reset_input_buffer()
        port.reset_output_buffer()
        assert port.in_waiting == 0 and port.out_waiting == 0
        runs.append(port.read(3 * N))
        port.close()
    assert runs[0] == runs[1] == frame(1, 0) + frame(2, 1) + frame(3, 2)


def test_disconnect_after_simulated_time():
    port = serial.serial_for_url("sim://guard?disconnect_s=0.1", timeout=1.0)
    port.write(b"START")
    data = port.read(1000)  # ticks at 15..90 ms arrive, then the link dies at 100 ms
    assert data == b"START" + b"".join(frame(k, k - 1) for k in range(1, 7))
    assert port.fault_stats.disconnected_at_s == pytest.approx(0.1)
    with pytest.raises(serial.SerialException, match="port disconnected"):
        port.read(1)
    with pytest.raises(serial.SerialException, match="port disconnected"):
        port.write(b"x")
    port.close()


def test_disconnect_loses_latency_buffer_and_counts_it():
    port = serial.serial_for_url("sim://guard?disconnect_s=0.1&latency_ms=16", timeout=1.0)
    port.write(b"START")
    data = port.read(1000)
    lost = port.fault_stats.down.bytes_lost_at_disconnect
    assert len(data) + lost == 5 + 6 * N and lost > 0
    port.close()


def _wait_for_bytes(port, n, limit_s=60.0):
    """Wait, without reading, until ``n`` bytes are waiting (a generous limit, not a
    timing check: a real-time port's clock runs whether or not the host reads)."""
    deadline = time.monotonic() + limit_s
    while port.in_waiting < n and time.monotonic() < deadline:
        time.sleep(0.005)
    return port.in_waiting


@pytest.mark.parametrize("pacing", ["realtime", "20"])
def test_realtime_clock_runs_without_reads(pacing):
    """Real-time pacing (or a speed factor): unlike lock-step, the device's ticks happen
    without the host reading; the frames are consecutive ticks, each at its tick's
    simulated time. How fast the clock runs on the wall clock is bench/bench_pacing.py's."""
    port = serial.serial_for_url(f"sim://guard?pacing={pacing}", timeout=60.0)
    port.write(b"START")
    assert _wait_for_bytes(port, 5 + 4 * N) >= 5 + 4 * N
    data = port.read(5 + 4 * N)
    assert data[:5] == b"START"
    ticks = [int.from_bytes(data[5 + i * N + 1 : 5 + i * N + 5], "little") for i in range(4)]
    assert ticks == list(range(ticks[0], ticks[0] + 4))
    assert port.sim_time_s >= (ticks[-1] * 15) * 1e-3
    port.close()
    assert not port.is_open


def test_lockstep_clock_stands_still_without_reads():
    """The contrast: a lock-step port's clock advances only in read()."""
    port = serial.serial_for_url("sim://guard", timeout=1.0)
    port.write(b"START")
    time.sleep(0.05)
    assert port.in_waiting == 5 and port.sim_time_s == 0.0
    port.close()
