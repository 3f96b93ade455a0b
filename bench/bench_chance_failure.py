"""How often does a perfect method fail issue 27's std check by chance? (issue 27, statistics)

``bench/bench_std_check.py`` judges each set on its own: truth within 3 std in >= 99 % of the
(seed, parameter) pairs, and every parameter's |bias|/std and spread/std inside the band that
an unbiased method with an exact std stays within in 95 % of checks (Bonferroni over the
2 x p statistics, :func:`bench_std_check.chance_bands`). With ten sets, a perfect method fails
at least one of them with some probability; this estimates it by simulation in numpy.

A perfect method's errors in std units are Gaussian with the correlation of the reported
covariance: per set, the WLS covariance of ``identify`` (in this process, defaults) on the
set's first kept log (``--keep DIR``, ``SET_SEED.csv``), or independent parameters without
one. Two variants:

* ``independent``: every set draws its own errors;
* ``nested``: the sets of one excitation and robot at several lengths share their seeds, and
  a lock-step capture of T1 s is the first T1 s of the same seed's capture of T2 s (checked
  on the kept logs: ``--check-prefix``), so their errors correlate as sqrt(T1 / T2) (errors
  built from independent increments per stretch of the log, each with the set family's
  correlation: that of its longest set).

Prints per set the chance of failing each bar, then the chance that at least one (two) of
the sets fail, for issue 27's ten sets and with fast120.

    python bench/bench_chance_failure.py [--seeds 40] [--checks 20000] [--keep DIR
        --first-seed 7000] [--check-prefix]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from bench_std_check import EXTRA_SETS, SETS, chance_bands

ORDER = list(SETS) + list(EXTRA_SETS)


def family(name: str) -> str:
    """Sets that share seeds' logs: the same excitation and robot at another length."""
    s = {**SETS, **EXTRA_SETS}[name]
    return " ".join((*s.excite, Path(s.robot).stem))


def correlation(name: str, keep: str | None, seed: int, n_params: int) -> tuple[np.ndarray, str]:
    """The reported WLS covariance's correlation on the set's kept log, else the identity of
    ``n_params`` (identify's parameters: the base ones it can tell from the data)."""
    log = Path(keep) / f"{name}_{seed}.csv" if keep else None
    if log is None or not log.exists():
        return np.eye(n_params), "independent parameters (no log)"
    from guardid.identify.pipeline import IdentifyOptions, identify
    from guardid.identify.runs import load_run
    from guardid.robot import load_robot

    robot = {**SETS, **EXTRA_SETS}[name].robot
    res = identify([load_run(log)], load_robot(robot), IdentifyOptions(methods=("wls",)))
    cov = res.results["wls"].cov
    sd = np.sqrt(np.diag(cov))
    r = cov / np.outer(sd, sd)
    off = np.abs(r[np.triu_indices(len(sd), 1)])
    return r, f"from {log.name}: |corr| median {np.median(off):.2f}, max {off.max():.2f}"


def check_prefix(keep: str, seed: int) -> list[str]:
    """Whether each kept short log is the first rows of the same seed's longer log."""
    lines = []
    for short, long in (
        ("default60", "default300"),
        ("default300", "default1200"),
        ("schroeder60", "schroeder300"),
        ("schroeder300", "schroeder1200"),
    ):
        a, b = Path(keep) / f"{short}_{seed}.csv", Path(keep) / f"{long}_{seed}.csv"
        if not (a.exists() and b.exists()):
            lines.append(f"{short} / {long} seed {seed}: logs missing")
            continue
        rows_a = [r for r in a.read_text().splitlines() if r and r[0].isdigit()]
        rows_b = [r for r in b.read_text().splitlines() if r and r[0].isdigit()]
        same = sum(x == y for x, y in zip(rows_a, rows_b, strict=False))
        lines.append(
            f"{short} / {long} seed {seed}: {same} of {len(rows_a)} data rows identical"
            f" to the longer log's first rows"
        )
    return lines


def failures(z: np.ndarray, bands) -> np.ndarray:
    """(checks, 3) booleans: coverage, bias, spread bar failed; ``z`` (checks, seeds, p)."""
    b, lo, hi = bands
    cover = (np.abs(z) <= 3.0).mean(axis=(1, 2)) < 0.99
    bias = np.abs(z.mean(axis=1)).max(axis=1) > b
    spread = z.std(axis=1, ddof=1)
    return np.stack([cover, bias, (spread.min(axis=1) < lo) | (spread.max(axis=1) > hi)], axis=1)


def simulate(sets, corr, n_seeds, checks, nested, rng, chunk=500):
    """(checks, sets, 3) failure flags of a perfect method."""
    lengths = {n: {**SETS, **EXTRA_SETS}[n].duration_s for n in sets}
    fams: dict[str, list[str]] = {}
    for n in sets:
        fams.setdefault(family(n) if nested else n, []).append(n)
    out = []
    for start in range(0, checks, chunk):
        c = min(chunk, checks - start)
        flags = {}
        for members in fams.values():
            members = sorted(members, key=lengths.get)
            edges = [0.0] + [lengths[m] for m in members]
            chol = np.linalg.cholesky(corr[members[-1]] if len(members) > 1 else corr[members[0]])
            p = chol.shape[0]
            u = rng.standard_normal((len(members), c, n_seeds, p)) @ chol.T
            seg = np.sqrt(np.diff(edges))[:, None, None, None] * u  # increments, var ~ length
            total = np.cumsum(seg, axis=0)
            for k, m in enumerate(members):
                z = total[k] / np.sqrt(edges[k + 1])
                flags[m] = failures(z, chance_bands(n_seeds, p))
        out.append(np.stack([flags[n] for n in sets], axis=1))
    return np.concatenate(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--checks", type=int, default=20000)
    ap.add_argument("--keep", default=None, help="kept logs of bench_std_check (correlations)")
    ap.add_argument("--first-seed", type=int, default=7000)
    ap.add_argument("--check-prefix", action="store_true")
    ap.add_argument("--rng", type=int, default=0)
    ap.add_argument(
        "--params", type=int, default=12, help="parameters per set without a kept log (guard: 12)"
    )
    a = ap.parse_args()
    if a.check_prefix and a.keep:
        print("\n".join(check_prefix(a.keep, a.first_seed)))
    corr = {}
    for n in ORDER:
        corr[n], how = correlation(n, a.keep, a.first_seed, a.params)
        print(f"{n:14s} {len(corr[n])} parameters, correlation {how}")
    b, lo, hi = chance_bands(a.seeds, a.params)
    print(
        f"\nperfect method, {a.seeds} seeds, {a.checks} simulated checks; band"
        f" ({a.params} parameters) |bias| <= {b:.2f}, spread/std {lo:.2f}-{hi:.2f},"
        " truth within 3 std >= 99 %"
    )
    for nested in (False, True):
        rng = np.random.default_rng(a.rng)
        f = simulate(ORDER, corr, a.seeds, a.checks, nested, rng)
        print(f"\n{'nested lengths share their seeds' if nested else 'independent sets'}:")
        print(f"{'set':14s} {'P(fail)':>8s} {'coverage':>9s} {'bias':>6s} {'spread':>7s}")
        for k, n in enumerate(ORDER):
            any_k = f[:, k].any(axis=1).mean()
            print(
                f"{n:14s} {100 * any_k:7.1f}% "
                + " ".join(f"{100 * x:7.1f}%" for x in f[:, k].mean(axis=0))
            )
        for label, idx in (
            ("issue 27's ten sets", slice(0, len(SETS))),
            ("with fast120", slice(None)),
        ):
            fails = f[:, idx].any(axis=2).sum(axis=1)
            print(
                f"{label}: P(at least one set fails) {100 * (fails >= 1).mean():.1f} %, "
                f"P(two or more) {100 * (fails >= 2).mean():.1f} %"
            )


if __name__ == "__main__":
    main()
