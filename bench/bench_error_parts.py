"""Each seed's WLS error split into its quantisation part and its current-noise part (issue 27).

Per seed N, a capture through ``sim://guard?seed=N&start=50&supply=0.02&ripple=0.01`` (the
Monte Carlo's port options, bench/bench_std_check.py; with ``--kept DIR`` the log is
compared with DIR's ``SET_N.csv`` of that Monte Carlo, which it reproduces bit for bit) with
the plant's true angles and period-mean currents recorded
(:func:`bench_pid_quantisation.capture`). ``identify`` (WLS, momentum form, its conditioning
resolved on the measured log) gives the reported std and the per-joint weights; then, with
those weights fixed (so the estimate is linear in the effort), the rows of the same
conditioning are fitted on:

* ``meas``: the log (encoder angles, measured current): identify's own estimate (the
  rounding's noise compensated as identify does by default, on every fit of the counts);
* ``true i``: encoder angles, the true current: the quantisation's part;
* ``true q``: true angles and current: the model's own error;
* ``plant noise`` = meas - true i: the part of the current sensor's noise as the plant drew it;
* ``fresh noise``: true i plus white Gaussian noise of the sensor's sigma drawn here (numpy,
  seeded by N), minus true i: the same part for an independent draw (the control).

Prints per base parameter the mean (sd) over the seeds of each part in units of the
measured log's reported std; statistics in numpy here. ``--save F.npz`` keeps the per-seed
values.

    python bench/bench_error_parts.py [--first-seed 5000] [--seeds 10] [--duration 1200]
        [--kind fourier|schroeder] [--kept /tmp/mc_std/keep] [--save parts.npz]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import bench_pid_quantisation as loop
import numpy as np

from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import build_model
from guardid.estimators import WeightedLeastSquares
from guardid.estimators._base import as_blocks
from guardid.identify.pipeline import IdentifyOptions, identify
from guardid.identify.prepare import current_on_adc_levels
from guardid.identify.rows import stacked_rows
from guardid.identify.runs import load_run
from guardid.robot import load_robot

SENSOR_SIGMA_A = 0.008
"""The guard's current sensor noise [A] (guardid/robots/guard.yaml, current_sensor.noise)."""
PARTS = ("meas", "true i", "true q", "plant noise", "fresh noise")


def seed_parts(run, q_true, i_true, desc, truth, seed: int):
    """((5, b) the :data:`PARTS` of one seed in units of the measured log's WLS std, the
    identified parameters' names)."""
    opts = IdentifyOptions(methods=("wls",), conditioning=ConditioningOptions(equation="momentum"))
    ref = identify([run], desc, opts)
    run = current_on_adc_levels(run, desc)  # the current identify fits (its ADC's levels)
    tv = np.array([truth[n] for n in ref.names])
    std = ref.results["wls"].std

    def blocks(q, current):
        rows = stacked_rows([(run.t, q, current)], desc, ref.conditioning,
                            in_current_units=False, effort_is_torque=False,
                            highest_harmonic_hz=run.highest_harmonic_hz)  # fmt: skip
        return (*as_blocks(rows.A, rows.y), rows.column_noise)

    A3, y_meas, noise = blocks(run.q, run.current)  # noise: the rounding's (identify's default)
    w = WeightedLeastSquares(column_noise=noise).fit(A3, y_meas).weights_

    def fit(A3, y2, noise):
        """The WLS estimate with the weights fixed (compensated like identify's when the
        rows carry the rounding's noise): linear in y."""
        M = (A3 * w[None, :, None]).reshape(-1, A3.shape[2])
        G, h = M.T @ M, M.T @ (y2 * w).reshape(-1)
        if noise is not None:
            G = G - np.einsum("j,jab->ab", w**2, noise.gram)
            h = h - (w**2) @ noise.cross
        return np.linalg.solve(G, h)

    meas = fit(A3, y_meas, noise)
    if not np.allclose(meas, ref.results["wls"].theta, rtol=1e-6, atol=1e-12):
        raise SystemExit("the fixed-weight fit does not reproduce identify's WLS")
    true_i = fit(A3, blocks(run.q, i_true)[1], noise)
    true_q = fit(*blocks(q_true, i_true))  # true angles: off the encoder's grid, no noise
    noisy = i_true + np.random.default_rng(seed).normal(0.0, SENSOR_SIGMA_A, i_true.shape)
    fresh = fit(A3, blocks(run.q, noisy)[1], noise)
    parts = (meas - tv, true_i - tv, true_q - tv, meas - true_i, fresh - true_i)
    return np.array(parts) / std, ref.names


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--first-seed", type=int, default=5000)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--duration", type=float, default=1200.0, help="capture length [s]")
    ap.add_argument("--kind", default="default", choices=sorted(loop.EXCITATIONS))
    ap.add_argument("--kept", type=Path, default=None, help="the Monte Carlo's kept logs")
    ap.add_argument("--save", type=Path, default=None, help="per-seed parts (.npz)")
    a = ap.parse_args()
    desc = load_robot("guard")
    model = build_model(desc)
    truth = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        traj = Path(tmp) / "traj.yaml"
        loop.bias_sources._cli("excite", "--robot", "guard", "-o", str(traj),
                               *loop.EXCITATIONS[a.kind])  # fmt: skip
        for seed in range(a.first_seed, a.first_seed + a.seeds):
            run, q_true, i_true = loop.capture(traj, seed, a.duration, Path(tmp) / "x.csv", False)
            note = ""
            kept = a.kept / f"{a.kind}{a.duration:g}_{seed}.csv" if a.kept else None
            if kept is not None and kept.exists():
                k = load_run(kept)
                same = np.array_equal(k.q, run.q) and np.array_equal(k.current, run.current)
                note = f", {'identical to' if same else 'DIFFERS from'} {kept}"
            parts, names = seed_parts(run, q_true, i_true, desc, truth, seed)
            out.append(parts)
            print(f"  seed {seed} done{note}; parts x 100:", *(" ".join(f"{x:+.0f}" for x in
                  100 * p) for p in parts), sep="\n    ", flush=True)  # fmt: skip
    z = np.array(out)  # (seeds, parts, b)
    if a.save:
        np.savez(a.save, parts=z, names=np.array(names), first_seed=a.first_seed)
    print(f"\n{a.kind}, {a.duration:g} s, seeds {a.first_seed}-{a.first_seed + a.seeds - 1}, "
          "WLS with the measured log's weights: mean (sd) over seeds / reported std")  # fmt: skip
    print(f"{'param':7s}" + "".join(f"{p:>15s}" for p in PARTS))
    for k, n in enumerate(names):
        cells = "".join(f"{z[:, p, k].mean():+7.2f} ({z[:, p, k].std(ddof=1):4.2f})"
                        for p in range(len(PARTS)))  # fmt: skip
        print(f"{n:7s}{cells}")


if __name__ == "__main__":
    main()
