"""``seed000-step``: seed 000 experiment (a), the mass step (Figs. 3-5).

m = 3 kg, l1 = 1 m, l2 = 0.5 m, k = 2 N m/rad; m jumps to 5 kg at t = 4 pi s; the run ends at
8 pi s. The Hopfield estimator runs on exact and on noisy measurements; the printout gives
when the squared estimation error first falls below 1e-2 and from when it stays below,
after the start and after the step. The gradient method (eq. 4, explicit Euler per
sample) runs at three gains to show the tuning the paper says it needs: too small is slow,
too large oscillates (each sample's Euler step multiplies the error along the largest
direction by 1 - 2 eta dt lambda_max(A_k^T A_k), below -1 when that product exceeds 2) and
diverges.
"""

from __future__ import annotations

import math

import numpy as np

from guardid.reproduce import flexsim as fs
from guardid.reproduce.common import Report, fmt_time_pi, settle_time

NAME = "seed000-step"
T_STEP = 4 * math.pi
"""Time of the mass step [s]."""
GRAD_ETAS = (30.0, 100.0, 200.0)
"""Gradient gains shown [1 / (N^2 m^2 s) in the units of A]: slow, converging, oscillating."""


def mass(t: float) -> float:
    """m(t) [kg]: 3 kg, then 5 kg from 4 pi s."""
    return 3.0 if t < T_STEP else 5.0


def run(seed: int = 0) -> Report:
    """Simulate, estimate, and build the report."""
    rep = Report(NAME, "seed 000 flexible link, experiment (a): mass 3 -> 5 kg at t = 4 pi s")
    rep.repairs = list(fs.REPAIRS)
    rep.assumptions = fs.noise_assumptions() + [
        f"gradient (eq. 4): explicit Euler per sample from theta_n, gains eta = {GRAD_ETAS}"
        " on the exact measurements",
    ]
    sim = fs.simulate(mass, lambda t: 1.0)
    t = sim.t
    meas = {
        "exact": fs.measurements(sim, noisy=False),
        "noisy": fs.measurements(sim, noisy=True, rng=np.random.default_rng(seed)),
    }
    rep.add(
        "Hopfield, squared estimation error ||theta_hat - theta||^2 < 1e-2 (paper Fig. 3:"
        " 'vanishes after a short transient'; DESIGN.md at beta = 0.003: ~0.5 pi s after the"
        " start, ~0.7 pi s after the step):"
    )
    rows, summary, series = [], {"hopfield": {}, "gradient": {}}, {"t": t, "theta": sim.theta}
    for label, (A, y) in meas.items():
        for beta in (fs.BETA, fs.BETA_DESIGN):
            hist, _ = fs.hopfield(A, y, sim.dt, beta)
            err = fs.sq_error(hist, sim.theta)
            s0 = settle_time(t, err, fs.THRESHOLD, 0.0, T_STEP - fs.EDGE_S)
            s1 = settle_time(t, err, fs.THRESHOLD, T_STEP)
            summary["hopfield"][(label, beta)] = {
                "start": s0,
                "step": s1,
                "final_err": float(err[-1]),
                "final": hist[-1],
            }
            series[f"hop_{label}_{beta:g}"] = hist
            rows.append(
                [label, f"{beta:g}", fmt_time_pi(s0[0]), fmt_time_pi(s0[1])]
                + [fmt_time_pi(s1[0]), fmt_time_pi(s1[1]), f"{err[-1]:.1e}"]
            )
    rep.table(
        ["data", "beta", "start: first", "start: stays", "step: first", "step: stays", "end"],
        rows,
    )
    rep.add(
        f"  ('start: stays' is judged up to {fs.EDGE_S:g} s before the step: the zero-phase"
        " filter of the noisy run spreads the step that far back in time; 'end' = error at 8 pi)"
    )
    A, y = meas["exact"]
    lam_max = np.linalg.eigvalsh(np.einsum("nji,njk->nik", A, A))[:, -1]
    rep.add("", "Gradient (eq. 4) on the exact measurements:")
    rows = []
    for eta in GRAD_ETAS:
        hist, div_at = fs.gradient(A, y, sim.dt, eta)
        n = hist.shape[0]
        err = fs.sq_error(hist, sim.theta[:n])
        factor = 2 * eta * sim.dt * lam_max
        s0 = settle_time(t[:n], err, fs.THRESHOLD, 0.0, T_STEP)
        s1 = settle_time(t[:n], err, fs.THRESHOLD, T_STEP) if n > t.searchsorted(T_STEP) else None
        s1 = s1 or (None, None)
        if div_at is not None:
            first_bad = float(t[np.argmax(factor > 2)])
            verdict = (
                f"oscillates (Euler factor > 2 from t = {first_bad / math.pi:.2f} pi s),"
                f" diverges at {t[div_at - 1] / math.pi:.2f} pi s"
            )
        elif s0[1] is None or s1[1] is None or s0[1] > 1.5 * math.pi:
            verdict = "slow"
        else:
            verdict = "converges"
        summary["gradient"][eta] = {
            "start": s0,
            "step": s1,
            "diverged_at": None if div_at is None else float(t[div_at - 1]),
            "max_factor": float(factor.max()),
            "verdict": verdict.split(" ")[0],
        }
        series[f"grad_{eta:g}"] = hist
        rows.append(
            [f"{eta:g}", f"{factor.max():.2f}", fmt_time_pi(s0[0]), fmt_time_pi(s1[0]), verdict]
        )
    rep.table(["eta", "max 2 eta dt lam", "start: first", "step: first", "verdict"], rows)
    rep.add(
        "  (max 2 eta dt lam = largest per-sample Euler factor 2 eta dt lambda_max(A_k^T A_k);"
        " above 2 the step overshoots and alternates in sign)"
    )
    rep.summary, rep.series = summary, series
    return rep.finish()


def plot(rep: Report, out_dir) -> list[str]:
    """Seed 000 Figs. 3-5 (squared error, alpha, gamma) plus the gradient runs."""
    from guardid.reproduce.plots import seed000_step

    return seed000_step(rep, out_dir)
