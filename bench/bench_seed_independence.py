"""How much of their quantisation error do Monte Carlo seeds share? (issue 27, item 3)

Per ``sim://`` variant, one trajectory (``guardid excite`` defaults) captured through
``guardid capture`` for each seed; then, for seed 0 against every other seed, from the logs
alone (numpy): the share of rows whose encoder counts differ, and the correlation of the
velocity-from-counts residuals (counts differenced over one period, minus a zero-phase
low-pass of themselves at ``--smooth`` Hz: mostly the quantisation error differenced once).
From the simulated plant itself (a recording wrapper around the ``sim://`` plant, through
the public device factory): the correlation of the quantisation error counts / counts_per_rad
minus the true angle, per joint. Rows before the trajectory's first tick are left out.

    python bench/bench_seed_independence.py [--seeds 4] [--duration 60] [--variants
        'phase=1;start=50&supply=0.02&ripple=0.01'] [--smooth 2]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import tempfile
from pathlib import Path

import numpy as np
from scipy.signal import butter, filtfilt

from guardid.cli import main as guardid_main
from guardid.fakeport.factory import register_device_factory
from guardid.firmware.emulator import FirmwareEmulator, require_simulable
from guardid.log import read_log
from guardid.plant import make_plant
from guardid.robot import load_robot

DEFAULT_VARIANTS = (
    "noise=1;phase=1;start=50;supply=0.02;ripple=0.01;start=50&supply=0.02&ripple=0.01"
)


class RecordingPlant:
    """A plant whose every step keeps (tick, true angles [rad], counts) in ``trace``."""

    def __init__(self, plant) -> None:
        self.plant = plant
        self.trace: list[tuple[int, tuple, tuple]] = []

    def step_sensors(self, u):
        counts, volts, amps = self.plant.step_sensors(u)
        self.trace.append((self.plant.tick, self.plant.state.q, tuple(counts)))
        return counts, volts, amps

    def __getattr__(self, name):
        return getattr(self.plant, name)


TRACES: dict[int, RecordingPlant] = {}


def _recording_device(robot: str, options):
    description = load_robot(robot)
    require_simulable(description)
    plant = RecordingPlant(make_plant(description, options))
    TRACES[options.seed] = plant
    return FirmwareEmulator(description, plant)


def _guardid(*args: str) -> None:
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            guardid_main(list(args), standalone_mode=False)
    except SystemExit as exc:
        if exc.code:
            raise


def capture(traj: Path, seed: int, variant: str, duration: float, work: Path):
    """(log signals, plant trace) of one capture: counts (N, 2) from the log, its ticks, and
    per plant tick the true angles and counts."""
    log = work / f"run_{seed}.csv"
    port = f"sim://guard?seed={seed}&{variant}"
    _guardid("capture", "--trajectory", str(traj), "--duration", f"{duration:g}", "--port",
             port, "--quiet", "--force", "-o", str(log))  # fmt: skip
    data = read_log(log)
    ticks = data.columns["tick"]
    counts = data.joint_array("counts").astype(np.int64)
    trace = TRACES.pop(seed).trace
    plant_ticks = np.array([t for t, _, _ in trace])
    q_true = np.array([q for _, q, _ in trace])
    plant_counts = np.array([c for _, _, c in trace])
    return ticks, counts, plant_ticks, q_true, plant_counts


def residual(counts: np.ndarray, period: float, smooth_hz: float) -> np.ndarray:
    """Velocity from counts over one period minus its zero-phase low-pass [counts/s]."""
    v = np.diff(counts.astype(float), axis=0) / period
    b, a = butter(2, smooth_hz * 2.0 * period)
    return v - filtfilt(b, a, v, axis=0)


def corr(a: np.ndarray, b: np.ndarray) -> float:
    if a.std() == 0.0 or b.std() == 0.0:
        return 1.0 if np.array_equal(a, b) else math.nan
    return float(np.corrcoef(a, b)[0, 1])


def compare(runs, per_rad, period, smooth_hz):
    """Rows (other seed, % rows differing pan/tilt/any, residual corr pan/tilt, quantisation
    error corr pan/tilt) of seed runs[0] against each other run."""
    t0, c0, pt0, q0, pc0 = runs[0]
    out = []
    for t1, c1, pt1, q1, pc1 in runs[1:]:
        n = min(len(c0), len(c1))
        assert np.array_equal(t0[:n] - t0[0], t1[:n] - t1[0])
        d = c0[:n] != c1[:n]
        r0, r1 = residual(c0[:n], period, smooth_hz), residual(c1[:n], period, smooth_hz)
        # plant: the same ticks as the log rows
        k0, k1 = np.searchsorted(pt0, t0[:n]), np.searchsorted(pt1, t1[:n])
        e0 = pc0[k0] / per_rad - q0[k0]
        e1 = pc1[k1] / per_rad - q1[k1]
        assert np.array_equal(pc0[k0], c0[:n])  # the recorded ticks are the logged ones
        out.append((100 * d[:, 0].mean(), 100 * d[:, 1].mean(), 100 * d.any(axis=1).mean(),
                    corr(r0[:, 0], r1[:, 0]), corr(r0[:, 1], r1[:, 1]),
                    corr(e0[:, 0], e1[:, 0]), corr(e0[:, 1], e1[:, 1])))  # fmt: skip
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=4, help="seeds 0..N-1 (0 against the rest)")
    ap.add_argument("--duration", type=float, default=60.0, help="capture length [s]")
    ap.add_argument("--variants", default=DEFAULT_VARIANTS, help="';'-separated sim:// options")
    ap.add_argument("--smooth", type=float, default=2.0, help="low-pass of the residual [Hz]")
    a = ap.parse_args()
    register_device_factory(_recording_device)
    description = load_robot("guard")
    per_rad = np.array([j.drive.gear_ratio * j.encoder.counts_per_rev for j in
                        description.joints]) / (2 * math.pi)  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        traj = work / "traj.yaml"
        _guardid("excite", "--robot", "guard", "-o", str(traj))
        print(f"\n{a.seeds} seeds, {a.duration:g} s captures of the default excitation; seed 0"
              " against each other seed, median (min..max) over the pairs")  # fmt: skip
        head = ("rows differing % pan / tilt / any", "residual corr pan / tilt",
                "quantisation error corr pan / tilt")  # fmt: skip
        print(f"{'sim://guard?seed=N&...':36s} | {head[0]:38s} | {head[1]:26s} | {head[2]}")
        for variant in a.variants.split(";"):
            runs = [capture(traj, s, variant, a.duration, work) for s in range(a.seeds)]
            st = compare(runs, per_rad, description.sample_period, a.smooth)
            med, lo, hi = np.median(st, axis=0), st.min(axis=0), st.max(axis=0)

            def cell(i, fmt, med=med, lo=lo, hi=hi):
                return f"{med[i]:{fmt}} ({lo[i]:{fmt}}..{hi[i]:{fmt}})"

            print(f"{variant:36s} | {cell(0, '.0f')} / {cell(1, '.0f')} / {cell(2, '.0f')} | "
                  f"{cell(3, '.2f')} / {cell(4, '.2f')} | {cell(5, '.2f')} / {cell(6, '.2f')}",
                  flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
