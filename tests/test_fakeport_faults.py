"""Seeded faults reproduce exactly and the stats account for all damage."""

from itertools import pairwise

import numpy as np
import pytest
import serial

import guardid.fakeport as fp
from guardid.fakeport.faults import Corrupter, DirectionStats

N = fp.EchoDevice.FRAME_LEN


@pytest.fixture(autouse=True)
def echo_factory(monkeypatch):
    monkeypatch.delenv(fp.factory.DEVICE_ENV, raising=False)
    old = fp.register_device_factory(lambda robot, options: fp.EchoDevice())
    yield
    fp.register_device_factory(old)


def _run(query, ticks=2000, slack=0.001):
    """Start streaming and read for ``ticks`` ticks plus ``slack`` [s] simulated."""
    port = serial.serial_for_url(f"sim://guard?{query}", timeout=ticks * 0.015 + slack)
    port.write(b"START")
    data = port.read(10**6)
    stats = port.fault_stats
    port.close()
    return data, stats


def _replay(clean, stats):
    """The stream the stats say was delivered."""
    out = np.frombuffer(clean, dtype=np.uint8).copy()
    for offset, mask in stats.flipped:
        out[offset] ^= mask
    keep = np.ones(len(out), dtype=bool)
    keep[stats.dropped_offsets] = False
    return out[keep].tobytes()


def test_stats_equal_the_damage_and_reproduce():
    clean, clean_stats = _run("seed=5")
    assert clean_stats.down.bytes_dropped == 0 and len(clean) == 5 + 2000 * N
    noisy, stats = _run("seed=5&drop=0.01&flip=0.002")
    d = stats.down
    assert d.bytes_in == len(clean) and d.bytes_out == len(noisy)
    assert d.bytes_dropped == len(d.dropped_offsets) == len(clean) - len(noisy) > 0
    assert d.bits_flipped == sum(bin(m).count("1") for _, m in d.flipped) > 0
    assert _replay(clean, d) == noisy
    again, stats2 = _run("seed=5&drop=0.01&flip=0.002")
    assert again == noisy and stats2 == stats
    other, _ = _run("seed=6&drop=0.01&flip=0.002")
    assert other != noisy
    assert stats.up.bytes_in == 5 and stats.up.bytes_dropped == 0


def test_upstream_faults():
    port = serial.serial_for_url("sim://guard?seed=2&drop=0.5&upstream=1", timeout=0)
    port.write(bytes(range(200)))
    up = port.fault_stats.up
    assert up.bytes_in == 200 and up.bytes_out == 200 - up.bytes_dropped
    assert 50 < up.bytes_dropped < 150
    port.close()


def test_faults_independent_of_chunking():
    data = bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8))
    whole = Corrupter(0.05, 0.01, 9, DirectionStats())
    pieces = Corrupter(0.05, 0.01, 9, DirectionStats())
    out_whole = whole.apply(data)
    cuts = [0, 1, 7, 100, 2500, 4999, 5000]
    out_pieces = b"".join(pieces.apply(data[a:b]) for a, b in pairwise(cuts))
    assert out_whole == out_pieces and whole.stats == pieces.stats


def test_latency_bunches_frames():
    data, stats = _run("latency_ms=16", ticks=21, slack=0.002)
    assert len(data) == 5 + 21 * N  # nothing lost, only delayed
    # START echo (t=0) and tick 1 (15 ms) go out when the timer expires at 16 ms; from
    # then on each timer started by an even tick expires after the next odd tick.
    assert stats.bursts[0] == pytest.approx((0.016, 5 + N))
    assert len(stats.bursts) == 11
    for k, (t, size) in enumerate(stats.bursts[1:]):
        assert t == pytest.approx(0.046 + 0.030 * k) and size == 2 * N


def test_latency_releases_full_packets():
    _, stats = _run("latency_ms=1000", ticks=40)
    assert [size for _, size in stats.bursts] == [62] * 5
