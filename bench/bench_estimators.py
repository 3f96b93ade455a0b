"""Estimator timings (run by hand: ``python bench/bench_estimators.py``).

Prints the per-sample online update time of RLS and Hopfield (p = 12, n_out = 2), the ratio
against padasip's single-output FilterRLS fed the two rows of each sample as two updates,
and the offline identification time of a 240000-sample log with LS, RLS and Hopfield, as a
multiple of real time at 15 ms per sample.
"""

from __future__ import annotations

import time

import numpy as np

from guardid.estimators import RLS, Hopfield, LeastSquares

P, NOUT, N_LOG, TS = 12, 2, 240_000, 0.015


def make_log(n, seed=0):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, NOUT, P)) * np.logspace(0, -1, P)
    th = rng.uniform(-1, 1, P)
    return A, A @ th + 0.01 * rng.normal(size=(n, NOUT)), th


def per_sample_us(fn, n):
    t = time.perf_counter()
    for k in range(n):
        fn(k)
    return (time.perf_counter() - t) / n * 1e6


def main():
    n_on = 20_000
    A, y, th = make_log(n_on)
    box = (-2 * np.ones(P), 2 * np.ones(P))
    rls = RLS(lam=0.999, p0=1e3)
    hop = Hopfield(bounds=box, beta=0.05, dt=TS)
    t_rls = per_sample_us(lambda k: rls.update(A[k], y[k]), n_on)
    t_hop = per_sample_us(lambda k: hop.update(A[k], y[k]), n_on)
    print(
        f"online update, p={P}, n_out={NOUT}: RLS {t_rls:.2f} us/sample, "
        f"Hopfield {t_hop:.2f} us/sample"
    )
    try:
        import padasip as pa
    except ImportError:
        print("padasip not installed")
    else:
        f = pa.filters.FilterRLS(P, mu=0.999, w="zeros")

        def pa_step(k):
            f.adapt(y[k, 0], A[k, 0])
            f.adapt(y[k, 1], A[k, 1])

        t_pa = per_sample_us(pa_step, n_on)
        print(
            f"padasip FilterRLS (2 single-output updates per sample): {t_pa:.2f} us/sample; "
            f"guardid RLS is {t_pa / t_rls:.1f}x faster, Hopfield {t_pa / t_hop:.1f}x"
        )

    A, y, th = make_log(N_LOG, seed=1)
    real = N_LOG * TS
    total = 0.0
    for name, est in [
        ("LS", LeastSquares()),
        ("RLS lam=1", RLS(lam=1.0, p0=1e3)),
        ("RLS lam=0.999", RLS(lam=0.999, p0=1e3)),
        ("Hopfield fit_block=16", Hopfield(bounds=box, beta=0.05, dt=TS)),
    ]:
        t = time.perf_counter()
        est.fit(A, y)
        dt = time.perf_counter() - t
        if name != "RLS lam=0.999":
            total += dt
        err = np.max(np.abs(est.theta_ - th))
        print(
            f"offline {name:22s} {N_LOG} samples: {dt:.3f} s = {N_LOG / dt:,.0f} samples/s, "
            f"max |theta err| {err:.2e}"
        )
    print(
        f"offline LS + RLS + Hopfield: {total:.3f} s for {real:.0f} s of log = "
        f"{real / total:,.0f}x real time (target >= 1000x)"
    )
    t = time.perf_counter()
    Hopfield(bounds=box, beta=0.05, dt=TS, fit_block=1).fit(A, y)
    dt = time.perf_counter() - t
    print(
        f"offline Hopfield fit_block=1 (exact per-sample): {dt:.3f} s = {N_LOG / dt:,.0f} samples/s"
    )
    t = time.perf_counter()
    RLS(lam=0.999, p0=1e3, history_every=1).fit(A, y)
    dt = time.perf_counter() - t
    print(f"offline RLS history at every sample: {dt:.3f} s = {N_LOG / dt:,.0f} samples/s")


if __name__ == "__main__":
    main()
