"""``seed000-step``: seed 000 experiment (a), the mass step (Figs. 3-5).

m = 3 kg, l1 = 1 m, l2 = 0.5 m, k = 2 N m/rad; m jumps to 5 kg at t = 4 pi s; the run ends at
8 pi s. The Hopfield estimator runs on exact and on noisy measurements; the printout gives
when the squared estimation error first falls below 1e-2 and from when it stays below,
after the start and after the step.

Gain robustness, fairly: the paper says the gradient method (eq. 4) needs its gain tuned and
the Hopfield network does not. Our Hopfield network is integrated with a linearly implicit
step and the paper's gradient with explicit Euler, which mixes the estimator with the
integrator. So both estimators run over the same gain decades (common rate gain k: beta =
1 / k, eta = k / 2) twice: both with the linearly implicit step, and both with explicit Euler
per sample (each explicit step multiplies the error along the largest direction by
1 - k dt lambda_max(A_k^T A_k), below -1 when that product exceeds 2). Two tables.
"""

from __future__ import annotations

import math

import numpy as np

from guardid.reproduce import common as cm
from guardid.reproduce import flexsim as fs
from guardid.reproduce.common import Report, fmt_time_pi, settle_time

NAME = "seed000-step"
T_STEP = 4 * math.pi
"""Time of the mass step [s]."""
GAINS = (10.0, 30.0, 100.0, 300.0, 1e3, 3e3, 1e4, 3e4, 1e5)
"""Common rate gains k [1 / (N^2 m^2 s)] of the gain-robustness tables: Hopfield beta = 1 / k,
gradient eta = k / 2 (half-decade steps over four decades)."""
INTEGRATOR_TITLES = {
    "implicit": "Gain robustness, both estimators with the same linearly implicit step"
    " (Hopfield's default; gradient integrator='implicit'), exact measurements:",
    "euler": "Gain robustness, both estimators with the paper's explicit Euler per sample"
    " (gradient's default; Hopfield integrator='euler'), exact measurements:",
}


def _gain_run(est: str, integ: str, k: float, A, y, sim) -> dict:
    """One run at rate gain k; returns settle times, divergence and a one-word verdict."""
    t = sim.t
    if est == "hopfield":
        hist, _, div_at = fs.hopfield(A, y, sim.dt, 1.0 / k, integrator=integ, full=True)
    else:
        hist, div_at = fs.gradient(A, y, sim.dt, k / 2.0, integrator=integ)
    n = hist.shape[0]
    err = fs.sq_error(hist, sim.theta[:n])
    s0 = settle_time(t[:n], err, fs.THRESHOLD, 0.0, T_STEP)
    s1 = settle_time(t[:n], err, fs.THRESHOLD, T_STEP) if n > t.searchsorted(T_STEP) else None
    s1 = s1 or (None, None)
    if div_at is not None or not np.all(np.isfinite(err)):
        verdict = "diverges"
    elif s0[1] is None or s1[1] is None:
        verdict = "no"
    else:
        verdict = "settles"
    return {
        "start": s0,
        "step": s1,
        "diverged_at": None if div_at is None else float(t[div_at - 1]),
        "final_err": float(err[-1]),
        "verdict": verdict,
        "hist": hist,
    }


def mass(t: float) -> float:
    """m(t) [kg]: 3 kg, then 5 kg from 4 pi s."""
    return 3.0 if t < T_STEP else 5.0


def run(seed: int = 0, seeds: int = cm.DEFAULT_SEEDS) -> Report:
    """Simulate, estimate (noisy rows over ``seeds`` noise draws from ``seed``), report."""
    draws = cm.noise_seeds(seed, seeds)
    rep = Report(NAME, "seed 000 flexible link, experiment (a): mass 3 -> 5 kg at t = 4 pi s")
    rep.repairs = list(fs.REPAIRS)
    rep.assumptions = fs.noise_assumptions() + [
        f"gain tables: common rate gain k in {', '.join(f'{k:g}' for k in GAINS)}"
        " (Hopfield beta = 1 / k, gradient eta = k / 2), both from theta_n, exact measurements,"
        " each estimator with the linearly implicit step and with explicit Euler per sample",
        f"noisy rows: median and worst (latest time, largest end error) over {len(draws)} noise"
        f" seeds ({draws[0]}..{draws[-1]}); the plots show the first seed",
    ]
    sim = fs.simulate(mass, lambda t: 1.0)
    t = sim.t
    meas = {"exact": [fs.measurements(sim, noisy=False)]}
    meas["noisy"] = [fs.measurements(sim, noisy=True, rng=np.random.default_rng(s)) for s in draws]
    rep.add(
        "Hopfield, squared estimation error ||theta_hat - theta||^2 < 1e-2 (paper Fig. 3:"
        " 'vanishes after a short transient'; DESIGN.md at beta = 0.003: ~0.5 pi s after the"
        " start, ~0.7 pi s after the step):"
    )
    rows, summary, series = [], {"hopfield": {}, "gradient": {}}, {"t": t, "theta": sim.theta}
    for label, sets in meas.items():
        for beta in (fs.BETA, fs.BETA_DESIGN):
            per_seed = []
            for k, (A, y) in enumerate(sets):
                hist, _ = fs.hopfield(A, y, sim.dt, beta)
                err = fs.sq_error(hist, sim.theta)
                per_seed.append({
                    "start": settle_time(t, err, fs.THRESHOLD, 0.0, T_STEP - fs.EDGE_S),
                    "step": settle_time(t, err, fs.THRESHOLD, T_STEP),
                    "final_err": float(err[-1]),
                    "final": hist[-1],
                })  # fmt: skip
                if k == 0:
                    series[f"hop_{label}_{beta:g}"] = hist
            if label == "exact":
                summary["hopfield"][(label, beta)] = r = per_seed[0]
                rows.append([label, f"{beta:g}", *_cells(r)])
                continue
            med, wst = {}, {}
            for key in ("start", "step"):
                pairs = [cm.median_worst([r[key][i] for r in per_seed], "time") for i in (0, 1)]
                med[key] = tuple(p[0] for p in pairs)
                wst[key] = tuple(p[1] for p in pairs)
            med["final_err"], wst["final_err"] = cm.median_worst([r["final_err"] for r in per_seed])
            summary["hopfield"][(label, beta)] = {**med, "median": med, "worst": wst,
                                                  "per_seed": per_seed}  # fmt: skip
            rows.append([f"noisy median ({len(draws)})", f"{beta:g}", *_cells(med)])
            rows.append([f"noisy worst ({len(draws)})", f"{beta:g}", *_cells(wst)])
    rep.table(
        ["data", "beta", "start: first", "start: stays", "step: first", "step: stays", "end"],
        rows,
    )
    rep.add(
        f"  ('start: stays' is judged up to {fs.EDGE_S:g} s before the step: the zero-phase"
        " filter of the noisy run spreads the step that far back in time; 'end' = error at 8 pi)"
    )
    summary["seeds"] = draws
    A, y = meas["exact"][0]
    lam_max = float(np.linalg.eigvalsh(np.einsum("nji,njk->nik", A, A))[:, -1].max())
    summary["gains"] = {}
    for integ, title in INTEGRATOR_TITLES.items():
        rep.add("", title)
        rows = []
        for k in GAINS:
            row = [f"{k:g}", f"{k * sim.dt * lam_max:.3g}"]
            for est in ("hopfield", "gradient"):
                r = _gain_run(est, integ, k, A, y, sim)
                summary["gains"].setdefault((est, integ), {})[k] = r
                if est == "gradient" and integ == "euler":
                    series[f"grad_{k / 2:g}"] = r.pop("hist")
                r.pop("hist", None)
                row += [fmt_time_pi(r["start"][1]), fmt_time_pi(r["step"][1]), r["verdict"]]
            rows.append(row)
        rep.table(
            ["gain", "k dt lam", "Hop start", "Hop step", "Hopfield", "grad start", "grad step"]
            + ["gradient"],
            rows,
        )
    rep.add(
        "  (gain k [1 / (N^2 m^2 s)]: Hopfield beta = 1 / k, gradient eta = k / 2, so that near"
        " the box centre (S = 1 here) both follow dtheta/dt = k A^T (y - A theta); 'start' /"
        " 'step' = time after the start / the step from which ||theta_hat - theta||^2 stays"
        f" below {fs.THRESHOLD:g}; 'k dt lam' = largest per-sample explicit-Euler factor"
        " k dt lambda_max(A_k^T A_k), above 2 explicit Euler overshoots and alternates in sign)",
        "Settling range (gains at which the run settles after the start and after the step):",
    )
    for (est, integ), runs in summary["gains"].items():
        ok = [k for k, r in runs.items() if r["verdict"] == "settles"]
        span = f"{min(ok):g} .. {max(ok):g} ({math.log10(max(ok) / min(ok)):.1f} decades)"
        rep.add(f"  {est:9s} {integ:9s} {span if ok else 'none'}")
    rep.summary, rep.series = summary, series
    return rep.finish()


def _cells(r) -> list[str]:
    """Settling times (after the start, after the step) and the end error of one row."""
    s0, s1 = r["start"], r["step"]
    return [fmt_time_pi(s0[0]), fmt_time_pi(s0[1]), fmt_time_pi(s1[0]), fmt_time_pi(s1[1]),
            f"{r['final_err']:.1e}"]  # fmt: skip


def plot(rep: Report, out_dir) -> list[str]:
    """Seed 000 Figs. 3-5 (squared error, alpha, gamma) plus the gradient runs."""
    from guardid.reproduce.plots import seed000_step

    return seed000_step(rep, out_dir)
