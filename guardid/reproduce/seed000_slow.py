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
from guardid.reproduce.common import (
    DEFAULT_SEEDS,
    Report,
    fmt_time_pi,
    median_worst,
    noise_seeds,
    settle_time,
)

NAME = "seed000-slow"
OMEGA = 0.1
"""Angular frequency of the l1 variation [rad/s]."""


def l1(t: float) -> float:
    """l1(t) [m]."""
    return 1.2 + 0.05 * math.sin(OMEGA * t)


def run(seed: int = 0, seeds: int = DEFAULT_SEEDS) -> Report:
    """Simulate, estimate over ``seeds`` noise draws from ``seed``, and build the report."""
    rep = Report(NAME, "seed 000 flexible link, experiment (b): l1 = 1.2 + 0.05 sin(t/10) m")
    return track_report(rep, l1, OMEGA, (fs.BETA, fs.BETA_DESIGN), seed, False, seeds)


WORST = {"first": "time", "stays": "time", "rms": "max", "max": "max", "amp_ratio": "dev1",
         "lag": "abs"}  # fmt: skip
"""How each figure is worst over seeds (:func:`median_worst`)."""


def track_report(rep: Report, l1_fn, omega, betas, seed: int, fit_phase: bool,
                 seeds: int = DEFAULT_SEEDS) -> Report:  # fmt: skip
    """Shared by the slow and fast experiments: simulate with l1_fn, run Hopfield at each
    beta on exact measurements and on noisy ones drawn with ``seeds`` seeds from ``seed``,
    tabulate settling and gamma tracking (noisy: median and worst over the seeds)."""
    draws = noise_seeds(seed, seeds)
    rep.repairs = list(fs.REPAIRS)
    rep.assumptions = fs.noise_assumptions() + [
        "gamma tracking is measured after the first 2 pi s (rms and largest |error|)"
        + (
            f"; amplitude ratio and phase lag from a least-squares fit of c + a sin(wt) +"
            f" b cos(wt), w = {omega:g} rad/s, to the estimate and to the truth"
            if fit_phase
            else ""
        ),
        f"noisy rows: median and worst over {len(draws)} noise seeds ({draws[0]}.."
        f"{draws[-1]}; worst = latest time, largest error"
        + (", amplitude ratio farthest from 1, largest |lag|" if fit_phase else "")
        + "); the plots show the first seed",
    ]
    sim = fs.simulate(lambda t: 3.0, l1_fn)
    t = sim.t
    rows, summary, series = [], {}, {"t": t, "theta": sim.theta, "betas": list(betas)}
    keys = ["first", "stays", "rms", "max"] + (["amp_ratio", "lag"] if fit_phase else [])

    def one(A, y, beta):
        hist, _ = fs.hopfield(A, y, sim.dt, beta)
        first, stays = settle_time(t, fs.sq_error(hist, sim.theta), fs.THRESHOLD, 0.0)
        tr = fs.gamma_tracking(t, hist[:, 1], sim.theta[:, 1], w=omega if fit_phase else None)
        return hist, {"first": first, "stays": stays, **tr}

    def cells(r):
        row = [fmt_time_pi(r["first"]), fmt_time_pi(r["stays"]), f"{r['rms']:.4f}",
               f"{r['max']:.4f}"]  # fmt: skip
        if fit_phase:
            row += [f"{r['amp_ratio']:.3f}", f"{r['lag']:.3f} rad ({r['lag'] / omega:.3f} s)"]
        return row

    exact = fs.measurements(sim, noisy=False)
    noisy = [fs.measurements(sim, noisy=True, rng=np.random.default_rng(s)) for s in draws]
    for beta in betas:
        hist, r = one(*exact, beta)
        summary[("exact", beta)] = r
        series[f"hop_exact_{beta:g}"] = hist
        rows.append(["exact", f"{beta:g}", *cells(r)])
    for beta in betas:
        per_seed = []
        for k, meas in enumerate(noisy):
            hist, r = one(*meas, beta)
            per_seed.append(r)
            if k == 0:
                series[f"hop_noisy_{beta:g}"] = hist
        med, wst = {}, {}
        for key in keys:
            med[key], wst[key] = median_worst([r[key] for r in per_seed], WORST[key])
        summary[("noisy", beta)] = {**med, "median": med, "worst": wst, "per_seed": per_seed}
        rows.append([f"noisy median ({len(draws)})", f"{beta:g}", *cells(med)])
        rows.append([f"noisy worst ({len(draws)})", f"{beta:g}", *cells(wst)])
    header = ["data", "beta", "err^2<1e-2 first", "stays", "gamma rms", "gamma max"]
    if fit_phase:
        header += ["amp ratio", "phase lag"]
    rep.add(
        "Hopfield: squared estimation error settling (< 1e-2) and tracking of gamma"
        " [kg m^2] after 2 pi s:"
    )
    rep.table(header, rows)
    rep.summary, rep.series = summary, series
    rep.summary["seeds"] = draws
    return rep.finish()


def plot(rep: Report, out_dir) -> list[str]:
    """Seed 000 Figs. 6-7 (squared error, gamma)."""
    from guardid.reproduce.plots import seed000_track

    return seed000_track(rep, out_dir, figs=("fig6", "fig7"))
