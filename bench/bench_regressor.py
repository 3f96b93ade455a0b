"""Benchmark: vectorised regressor throughput and single-sample evaluator cost.

Run by hand: ``python bench/bench_regressor.py``. Prints samples/s of ``regressor`` for
N = 100000 random states (target >= 1e6 samples/s for the guard robot) and the per-call cost
in microseconds of mass_matrix_1 / bias_1 (the simulator calls them ~12 times per 15 ms tick).
"""

from __future__ import annotations

import time

import numpy as np

from guardid.dynamics import build_model


def _best(func, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    """Print the figures for each shipped robot."""
    num = 100_000
    calls = 20_000
    for name in ("guard", "planar2", "flexlink"):
        model = build_model(name)
        rng = np.random.default_rng(0)
        q, qd, qdd = (rng.standard_normal((num, model.n_dof)) for _ in range(3))
        dt = _best(lambda m=model, a=(q, qd, qdd): m.regressor(*a), 5)
        print(
            f"{name:9s} regressor      N={num}: {num / dt / 1e6:6.2f} M samples/s "
            f"({dt * 1e3:.1f} ms)"
        )
        q1, qd1 = q[0].copy(), qd[0].copy()
        p = model.params.copy()
        for label, func, args in (
            ("mass_matrix_1(q)", model.mass_matrix_1, (q1,)),
            ("mass_matrix_1(q, p)", model.mass_matrix_1, (q1, p)),
            ("bias_1(q, qd)", model.bias_1, (q1, qd1)),
            ("bias_1(q, qd, p)", model.bias_1, (q1, qd1, p)),
        ):

            def loop(f=func, a=args):
                for _ in range(calls):
                    f(*a)

            us = _best(loop, 3) / calls * 1e6
            print(f"{name:9s} {label:20s} {us:6.2f} us/call")


if __name__ == "__main__":
    main()
