"""Estimator timings (run by hand: ``python bench/bench_estimators.py [--online-only]``).

Prints the per-sample online update time of RLS, Hopfield (the paper's per-sample weights)
and the windowed Hopfield network of the online tracker (``lam``; p = 12, n_out = 2) and of
padasip's single-output FilterRLS fed the two rows of each sample as two updates, all on the
same 20000 rows in the same run, and the ratios; then the offline identification time of a
240000-sample log with LS, RLS and Hopfield, as a multiple of real time at 15 ms per sample.

Online timing: ``REPEATS`` passes over the rows, each with fresh estimators, the three
methods interleaved within every pass so that they see the same machine load. Reported per
method: the median over the passes and the best pass (the quieter-time figure on a shared
machine); the ratios are padasip / guardid for each.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from guardid.estimators import RLS, Hopfield, LeastSquares

P, NOUT, N_LOG, TS = 12, 2, 240_000, 0.015
N_ONLINE, REPEATS = 20_000, 7


def make_log(n, seed=0):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, NOUT, P)) * np.logspace(0, -1, P)
    th = rng.uniform(-1, 1, P)
    return A, A @ th + 0.01 * rng.normal(size=(n, NOUT)), th


def online(A, y, th, box, chunk=500):
    """Per-sample online update times (us/sample), median and best over REPEATS passes.

    Within a pass the methods alternate every ``chunk`` samples (each continuing its own
    state), so that all three see the same machine load; a pass's time for a method is the
    sum of its chunks.
    """
    try:
        import padasip as pa
    except ImportError:
        pa = None
        print("padasip not installed")
    n = A.shape[0]
    names = ["RLS", "Hopfield", "Hop-window"] + (["padasip"] if pa is not None else [])
    times = {name: [] for name in names}
    final = {}
    clock = time.perf_counter
    for _ in range(REPEATS):
        rls = RLS(lam=0.999, p0=1e3)
        hop = Hopfield(bounds=box, beta=0.05, dt=TS)
        win = Hopfield(bounds=box, beta=0.05, dt=TS, lam=0.999)
        steps = {"RLS": rls.update, "Hopfield": hop.update, "Hop-window": win.update}
        if pa is not None:  # same forgetting factor and initial P = 1000 I as the RLS above
            f = pa.filters.FilterRLS(P, mu=0.999, eps=1e-3, w="zeros")

            def pa_step(A_k, y_k, adapt=f.adapt):
                adapt(y_k[0], A_k[0])
                adapt(y_k[1], A_k[1])

            steps["padasip"] = pa_step
        total = dict.fromkeys(names, 0.0)
        for k0 in range(0, n, chunk):
            rows = range(k0, min(k0 + chunk, n))
            for name in names:
                step = steps[name]
                t = clock()
                for k in rows:
                    step(A[k], y[k])
                total[name] += clock() - t
        for name in names:
            times[name].append(total[name] / n * 1e6)
        final = {"RLS": rls.theta_, "Hopfield": hop.theta_, "Hop-window": win.theta_}
        if pa is not None:
            final["padasip"] = f.w
    print(
        f"online update, p={P}, n_out={NOUT}, {n} samples, {REPEATS} passes "
        "(padasip: 2 single-output updates per sample):"
    )
    stats = {}
    for name in names:
        t = times[name]
        stats[name] = (float(np.median(t)), min(t))
        err = np.max(np.abs(final[name] - th))
        print(
            f"  {name:9s} median {stats[name][0]:6.2f} us/sample, best {stats[name][1]:6.2f} "
            f"us/sample (passes: {', '.join(f'{x:.2f}' for x in t)}); max |theta err| {err:.1e}"
        )
    if pa is not None:
        for name in ("RLS", "Hopfield", "Hop-window"):
            r_med = stats["padasip"][0] / stats[name][0]
            r_best = stats["padasip"][1] / stats[name][1]
            r_min = min(a / b for a, b in zip(times["padasip"], times[name], strict=True))
            print(
                f"  padasip / {name}: {r_med:.2f}x (medians), {r_best:.2f}x (best passes), "
                f"worst single pass {r_min:.2f}x (target >= 2x)"
            )


def main():
    box = (-2 * np.ones(P), 2 * np.ones(P))
    online(*make_log(N_ONLINE), box)
    if "--online-only" in sys.argv[1:]:
        return

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
