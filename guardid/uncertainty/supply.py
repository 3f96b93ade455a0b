"""The supply voltage a guardid log's motors ran on, measured from the log itself: the
firmware's PID replayed on the log's counts and setpoints gives the voltage it commanded
each period (:func:`~guardid.closedloop.simulate.started_firmware`); the voltage sensor
reports that command times the supply's factor. Per joint the ratio measured / commanded
has the run's supply level as its mean; the tick-to-tick ripple, common to every motor, is
the covariance of the two joints' ratios (their sensors' noise is independent and drops
out). The ripple dithers the closed loop and sets how much of the quantisation error
repeats, so the replicas (:mod:`guardid.uncertainty.replicas`) run with it."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

MIN_COMMAND_V = 1.0
"""Periods whose commanded voltage is below this on a joint are not used [V]: the voltage
sensor's resolution (29 mV on the guard) would dominate the ratio."""


class MeasuredSupply(NamedTuple):
    """A supply of factor ``level`` x (1 + ``ripple`` z) per tick, z standard normal
    (fractions), for the plant (``supply=``, as :class:`guardid.plant.SupplyVariation`)."""

    level: float = 1.0
    ripple: float = 0.0

    @property
    def active(self) -> bool:
        return self.level != 1.0 or self.ripple > 0.0

    def factors(self, seed: int):
        """Endless iterator of per-tick supply factors drawn from ``seed``."""
        rng = np.random.default_rng(seed)
        while True:
            for z in rng.standard_normal(4096):
                yield self.level * (1.0 + self.ripple * float(z))


class _LogPlant:
    """The log's own sensors, one row per tick, for the firmware emulator."""

    def __init__(self, counts, volts, amps) -> None:
        self._rows = zip(counts[1:].tolist(), volts[1:].tolist(), amps[1:].tolist(), strict=True)
        self._first = counts[0].tolist()

    def counts(self):
        return tuple(self._first)

    def step_sensors(self, u):
        return next(self._rows)


def commanded_volts(run, description) -> np.ndarray:
    """(N - 1, n) [V]: the voltage the firmware commanded for each period between the
    first rows of ``run`` one tick apart (before the supply's factor), by its PID on the
    log's counts and setpoints."""
    from guardid.closedloop.rows import start_of
    from guardid.closedloop.simulate import started_firmware
    from guardid.replay import counts_per_rad

    ticks = np.asarray(run.ticks, dtype=np.int64)
    steps = np.flatnonzero(np.diff(ticks) != 1)
    end = int(steps[0]) + 1 if steps.size else len(ticks)  # the first stretch without gaps
    counts = np.rint(np.asarray(run.q[:end]) * counts_per_rad(description)).astype(np.int64)
    _, _, u0, following = start_of(run, description)
    plant = _LogPlant(counts, run.voltage[:end], run.current[:end])
    fw, sp, _, _ = started_firmware(description, plant, run.setpoint[:end], u0, following)
    out = np.empty((end - 1, counts.shape[1]))
    for k in range(1, end):
        out[k - 1] = fw.applied_mv  # held over the period ending at row k
        fw.buffer.append((fw.tick + 1, sp[k].tolist(), False))
        fw.advance()
    return out * 1e-3


def measured_supply(run, description) -> MeasuredSupply:
    """The supply's level and ripple in ``run`` (a guardid log with setpoints, counts and
    voltages); level 1 and ripple 0 where the log has too few usable periods."""
    cmd = commanded_volts(run, description)
    meas = np.asarray(run.voltage, dtype=float)[1 : len(cmd) + 1]
    usable = np.all(np.abs(cmd) >= MIN_COMMAND_V, axis=1)
    if np.count_nonzero(usable) < 100:
        return MeasuredSupply()
    ratio = meas[usable] / cmd[usable]
    level = float(np.mean(ratio))
    dev = ratio / np.mean(ratio, axis=0) - 1.0
    ripple2 = float(np.mean(dev[:, 0] * dev[:, 1])) if dev.shape[1] >= 2 else 0.0
    return MeasuredSupply(level, float(np.sqrt(max(ripple2, 0.0))))
