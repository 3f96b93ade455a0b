"""Optimised Fourier excitation for the guard robot over a few seeds (cond and run time).

Run: python bench/bench_excitation.py [seeds]   (default 5). Prints per seed the first seeded
guess's cond, the best seeded guess's cond, the optimised cond and the wall time [s].
"""

from __future__ import annotations

import sys

from guardid.dynamics import build_model
from guardid.excitation import optimise_fourier
from guardid.robot import load_robot


def main(seeds: int = 5) -> None:
    desc = load_robot("guard")
    model = build_model(desc)
    print("seed  first-guess  best-guess  optimised  first/opt  best/opt  time[s]")
    for seed in range(seeds):
        r = optimise_fourier(model, desc, harmonics=5, base_freq=0.1, seed=seed)
        best = min(r.guess_conds)
        print(
            f"{seed:4d} {r.start_cond:12.1f} {best:11.1f} {r.cond:10.1f} "
            f"{r.start_cond / r.cond:10.1f} {best / r.cond:9.2f} {r.seconds:8.1f}"
        )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
