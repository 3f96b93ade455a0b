"""``seed000-slow``: seed 000 experiment (b), slowly varying l1 (Figs. 6-7).

m = 3 kg, l2 = 0.5 m, k = 2 N m/rad, l1(t) = 1.2 + 0.05 sin(t / 10) m, so
gamma(t) = m l1 l2 = 1.8 + 0.075 sin(t / 10) kg m^2; 0..8 pi s. Printed: when the squared
estimation error settles below 1e-2 (Fig. 6) and how well the estimate of gamma tracks the
truth after the first 2 pi s (rms and largest error, Fig. 7).
"""

from __future__ import annotations

import math

import numpy as np

from guardid.reproduce import flexsim as fs
from guardid.reproduce.common import Report, fmt_time_pi, settle_time

NAME = "seed000-slow"
OMEGA = 0.1
"""Angular frequency of the l1 variation [rad/s]."""


def l1(t: float) -> float:
    """l1(t) [m]."""
    return 1.2 + 0.05 * math.sin(OMEGA * t)


def run(seed: int = 0) -> Report:
    """Simulate, estimate, and build the report."""
    rep = Report(NAME, "seed 000 flexible link, experiment (b): l1 = 1.2 + 0.05 sin(t/10) m")
    return track_report(rep, l1, OMEGA, (fs.BETA, fs.BETA_DESIGN), seed, fit_phase=False)


def track_report(rep: Report, l1_fn, omega, betas, seed: int, fit_phase: bool) -> Report:
    """Shared by the slow and fast experiments: simulate with l1_fn, run Hopfield at each
    beta on exact and noisy measurements, tabulate settling and gamma tracking."""
    rep.repairs = list(fs.REPAIRS)
    rep.assumptions = fs.noise_assumptions() + [
        "gamma tracking is measured after the first 2 pi s (rms and largest |error|)"
        + (
            f"; amplitude ratio and phase lag from a least-squares fit of c + a sin(wt) +"
            f" b cos(wt), w = {omega:g} rad/s, to the estimate and to the truth"
            if fit_phase
            else ""
        ),
    ]
    sim = fs.simulate(lambda t: 3.0, l1_fn)
    t = sim.t
    meas = {
        "exact": fs.measurements(sim, noisy=False),
        "noisy": fs.measurements(sim, noisy=True, rng=np.random.default_rng(seed)),
    }
    rows, summary, series = [], {}, {"t": t, "theta": sim.theta, "betas": list(betas)}
    for label, (A, y) in meas.items():
        for beta in betas:
            hist, _ = fs.hopfield(A, y, sim.dt, beta)
            err = fs.sq_error(hist, sim.theta)
            first, stays = settle_time(t, err, fs.THRESHOLD, 0.0)
            tr = fs.gamma_tracking(t, hist[:, 1], sim.theta[:, 1], w=omega if fit_phase else None)
            summary[(label, beta)] = {"first": first, "stays": stays, **tr}
            series[f"hop_{label}_{beta:g}"] = hist
            row = [label, f"{beta:g}", fmt_time_pi(first), fmt_time_pi(stays)]
            row += [f"{tr['rms']:.4f}", f"{tr['max']:.4f}"]
            if fit_phase:
                row += [f"{tr['amp_ratio']:.3f}", f"{tr['lag']:.3f} rad ({tr['lag']:.3f} s)"]
            rows.append(row)
    header = ["data", "beta", "err^2<1e-2 first", "stays", "gamma rms", "gamma max"]
    if fit_phase:
        header += ["amp ratio", "phase lag"]
        for r in rows:  # lag in s = lag in rad / omega
            lag = summary[(r[0], float(r[1]))]["lag"]
            r[-1] = f"{lag:.3f} rad ({lag / omega:.3f} s)"
    rep.add(
        "Hopfield: squared estimation error settling (< 1e-2) and tracking of gamma"
        " [kg m^2] after 2 pi s:"
    )
    rep.table(header, rows)
    rep.summary, rep.series = summary, series
    return rep.finish()


def plot(rep: Report, out_dir) -> list[str]:
    """Seed 000 Figs. 6-7 (squared error, gamma)."""
    from guardid.reproduce.plots import seed000_track

    return seed000_track(rep, out_dir, figs=("fig6", "fig7"))
