"""Seed 000's flexible-link experiments: simulation, measurements and estimator runs.

Shared by ``seed000_step``, ``seed000_slow`` and ``seed000_fast``. The plant is
:class:`guardid.dynamics.FlexibleLinkModel` (the repaired eq. 24: known hub inertia J_h on
M11, restoring spring +k x2) driven by eq. 26's Schroeder input as printed,
u = 0.5 [sin 2t + sin(2t - 2 pi/3) + sin(5t - 2 pi)] N m, from x(0) = (0, pi/8, 0, 0).
The parameters (alpha, gamma, k) = (m l2^2, m l1 l2, k) follow m(t) and l1(t) of the
experiment; they enter the integration at every Runge-Kutta stage.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from guardid.conditioning.filters import central_derivatives, zero_phase_lowpass
from guardid.dynamics import build_model
from guardid.estimators import Gradient, Hopfield
from guardid.excitation import SchroederMultisine
from guardid.reproduce.common import accel, rk4_step
from guardid.robot import load_robot

T_END = 8 * math.pi
"""Length of every seed 000 experiment [s] (the paper's figures span 0..8 pi s)."""

SUBSTEPS = 1
"""RK4 steps per sample period (h = dt = 0.5 ms; the fastest motion is ~1 Hz)."""

# Measurement noise of the "noisy" runs (the paper only simulates exact measurements).
NOISE_X = 1e-5
"""Position noise, 1 sigma [rad] (x1 and x2)."""
NOISE_U = 1e-3
"""Input torque noise, 1 sigma [N m]."""
CUTOFF_HZ = 10.0
"""Zero-phase 4th-order Butterworth cut-off for the noisy runs [Hz]. Eq. 26 has 0.32 and
0.80 Hz; at 5 Hz the filter's own distortion of x'' after the mass step reached 0.18 rad/s^2,
at 10 Hz it is 0.02 rad/s^2, against 0.017 rad/s^2 (1 sigma) of filtered noise."""
EDGE_S = 0.25
"""Noisy runs: samples this close to either end [s] are skipped (rows zeroed, so the
estimators hold their state): the zero-phase filter and the difference stencils are not
reliable there (x'' errors up to 2.5 rad/s^2 in the first and last 0.05 s)."""

REPAIRS = [
    "hub inertia J_h = 2 kg m^2 added to M11 and moved to the known side (y1 = u - J_h x1''):"
    " eq. 24 as printed has det M = -gamma^2 cos^2 x2 / 4 < 0 (indefinite mass matrix), the"
    " simulation cannot pass t ~ 0.56 s; the three unknowns, theta_n and the axes are kept",
    "spring sign: restoring +k x2 in the second equation; the printed -k x2 makes the rest"
    " position unstable and the state reaches |x| ~ 1e4 by t = 6 s with eq. 26's input",
]


@dataclass
class FlexRun:
    """Sampled experiment: t (N,) [s], x, xd, xdd (N, 2), u (N,) [N m], theta (N, 3) truth."""

    t: np.ndarray
    x: np.ndarray
    xd: np.ndarray
    xdd: np.ndarray
    u: np.ndarray
    theta: np.ndarray
    dt: float


def eq26_input():
    """u(t) [N m] of eq. 26 as a fast scalar function, and its trajectory object."""
    sig = SchroederMultisine.seed000_eq26()
    amp = sig.amplitudes[0].tolist()
    w = (2 * np.pi * sig.frequencies[0]).tolist()
    ph = sig.phases[0].tolist()

    terms = list(zip(amp, w, ph, strict=True))

    def u(t: float) -> float:
        out = 0.0
        for a, wi, p in terms:
            out += a * math.sin(wi * t + p)
        return out

    return u, sig


def simulate(mass_fn, l1_fn, t_end: float = T_END) -> FlexRun:
    """Integrate the flexible link with m(t) [kg] and l1(t) [m]; sample every dt = 0.5 ms.

    Measurements at t_k = k dt are exact: x, x' from the integration, x'' from the model at
    (x_k, x'_k, u(t_k), theta(t_k)).
    """
    desc = load_robot("flexlink")
    model = build_model(desc)
    dt = desc.sample_period
    l2, k = desc.l2, desc.stiffness
    u_fn, _ = eq26_input()

    def params(t):  # Python floats: the same values, faster arithmetic in the model
        return model.physical_params(mass_fn(t), l1_fn(t), l2, k).tolist()

    def tau(t):
        return (u_fn(t), 0.0)

    n = int(math.floor(t_end / dt + 1e-9)) + 1
    out = np.empty((n, 6))
    theta = np.empty((n, 3))
    x = [float(v) for v in desc.initial_state]
    h = dt / SUBSTEPS
    for i in range(n):
        t = i * dt
        th = params(t)
        u = u_fn(t)
        a0, a1 = accel(model, x[:2], x[2:], (u, 0.0), th)
        out[i] = (x[0], x[1], x[2], x[3], a0, a1)
        theta[i] = th
        for j in range(SUBSTEPS):
            x = rk4_step(model, t + j * h, x, h, tau, params)
    t = dt * np.arange(n)
    u = np.array([u_fn(tt) for tt in t])
    return FlexRun(t, out[:, :2], out[:, 2:4], out[:, 4:6], u, theta, dt)


def measurements(run: FlexRun, noisy: bool, rng: np.random.Generator | None = None):
    """Regressor A (N, 2, 3) and output y (N, 2) of eq. 25 with y1 = u - J_h x1''.

    Exact: from the simulated x, x', x''. Noisy: x and u get white Gaussian noise
    (NOISE_X, NOISE_U), both pass the same zero-phase low-pass (CUTOFF_HZ), x', x'' are
    fourth-order central differences of the filtered x, and the rows within EDGE_S of either
    end are zeroed (an estimator step on a zero row changes nothing).
    """
    model = build_model(load_robot("flexlink"))
    x, xd, xdd, u = run.x, run.xd, run.xdd, run.u
    if noisy:
        rng = rng if rng is not None else np.random.default_rng(0)
        fs = 1.0 / run.dt
        xm = x + NOISE_X * rng.standard_normal(x.shape)
        um = u + NOISE_U * rng.standard_normal(u.shape)
        x = zero_phase_lowpass(xm, fs, CUTOFF_HZ)
        u = zero_phase_lowpass(um, fs, CUTOFF_HZ)
        xd, xdd = central_derivatives(x, run.dt)
    A = model.regressor(x, xd, xdd)
    y = np.stack([u, np.zeros_like(u)], 1) - model.known_torque(x, xd, xdd)
    if noisy:
        edge = (run.t < run.t[0] + EDGE_S) | (run.t > run.t[-1] - EDGE_S)
        A[edge] = 0.0
        y[edge] = 0.0
    return A, y


def hopfield(A, y, dt: float, beta: float, integrator: str = "implicit", full: bool = False):
    """Exact per-sample Hopfield run (fit_block=1) from theta_n = (1, 2, 2.4).

    Returns (theta_hat (n, 3) after each sample, samples (n,)), with ``full`` also the sample
    count at which an explicit-Euler run diverged (or None); bounds from flexlink.yaml.
    """
    model = build_model(load_robot("flexlink"))
    est = Hopfield(
        model.nominal,
        bounds=model.bounds.T,
        beta=beta,
        dt=dt,
        fit_block=1,
        history_every=1,
        integrator=integrator,
    )
    est.fit(A, y)
    if full:
        return est.history_, est.history_samples_, est.diverged_at_
    return est.history_, est.history_samples_


def gradient(A, y, dt: float, eta: float, integrator: str = "euler"):
    """Gradient run (eq. 4) from theta_n; returns (history (n, 3), diverged_at)."""
    model = build_model(load_robot("flexlink"))
    est = Gradient(
        eta=eta, dt=dt, theta0=model.nominal, history_every=1, blowup=1e6, integrator=integrator
    )
    est.fit(A, y)
    return est.history_, est.diverged_at_


BETA = 0.001
"""Our Hopfield gain for the seed 000 runs [N^2 m^2 s] (the paper gives none)."""
BETA_DESIGN = 0.003
"""DESIGN.md's reference gain (0.5 pi s after the start, 0.7 pi s after the step)."""
THRESHOLD = 1e-2
"""Squared estimation error level that counts as settled."""


def sq_error(hist, theta) -> np.ndarray:
    """||theta_hat - theta||^2 per sample (N,) [mixed units, as the paper's Fig. 3]."""
    with np.errstate(over="ignore", invalid="ignore"):  # diverged runs
        return np.sum((hist - theta) ** 2, axis=1)


def noise_assumptions() -> list[str]:
    """The measurement assumptions every seed 000 report states."""
    return [
        "input u: eq. 26 as printed, u = 0.5 [sin 2t + sin(2t - 2pi/3) + sin(5t - 2pi)] N m"
        " (two of its three sines share 2 rad/s); x(0) = (0, pi/8, 0, 0), theta_n = (1, 2, 2.4)"
        ", Hopfield box theta_n +- 1 (flexlink.yaml)",
        f"simulation: RK4 with h = {0.5e-3 / SUBSTEPS * 1e3:g} ms, sampled every 0.5 ms over"
        " 8 pi s (50266 samples); parameters follow m(t), l1(t) inside every RK4 stage",
        "exact measurements: x, x' from the integration, x'' from the model at the sample",
        f"noisy measurements: white Gaussian noise on x ({NOISE_X:g} rad) and u ({NOISE_U:g}"
        f" N m), zero-phase 4th-order Butterworth at {CUTOFF_HZ:g} Hz on both, x' and x'' by"
        f" 4th-order central differences; the first and last {EDGE_S:g} s are skipped",
        "Hopfield: exact per-sample steps (fit_block = 1, A and y held over each 0.5 ms);"
        f" our beta = {BETA:g}, DESIGN.md's reference beta = {BETA_DESIGN:g}",
    ]


def gamma_tracking(t, gamma_hat, gamma, t_from: float = 2 * math.pi, w: float | None = None):
    """Tracking of gamma after ``t_from`` [s]: dict rms, max [kg m^2]; with ``w`` [rad/s]
    also the fitted amplitude ratio and phase lag [rad] of the component at w."""
    sel = t >= t_from
    e = gamma_hat[sel] - gamma[sel]
    out = {"rms": float(np.sqrt(np.mean(e**2))), "max": float(np.max(np.abs(e)))}
    if w is not None:
        ts = t[sel]
        X = np.column_stack([np.ones_like(ts), np.sin(w * ts), np.cos(w * ts)])
        ce = np.linalg.lstsq(X, gamma_hat[sel], rcond=None)[0]
        ct = np.linalg.lstsq(X, gamma[sel], rcond=None)[0]
        # a sin(wt) + b cos(wt) = R sin(wt - phi), phi = atan2(-b, a)
        phi_e, phi_t = math.atan2(-ce[2], ce[1]), math.atan2(-ct[2], ct[1])
        out["amp_ratio"] = math.hypot(ce[1], ce[2]) / math.hypot(ct[1], ct[2])
        out["lag"] = (phi_e - phi_t + math.pi) % (2 * math.pi) - math.pi
    return out
