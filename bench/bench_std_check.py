"""Monte Carlo check of the reported standard deviations (issue 19, deliverable 2).

For each excitation, one trajectory (``guardid excite`` with the excitation's options), then
per seed a capture through ``sim://guard?seed=N&phase=1`` (lock-step, noise on; ``phase=1``:
the seed also places the start pose within an encoder count, as on a real robot, so that the
seeds differ in quantisation and motion and not only in the current sensor's noise;
``--fixed-phase`` leaves it out) and ``guardid identify
--method M -o params.yaml`` with its defaults, all through the command line. The truth is the
robot YAML the simulator runs (its base parameters). Per method and base parameter, over the
seeds: the spread of the estimates divided by the mean reported std (1 = honest), the bias
(mean estimate - truth) in units of the mean reported std, and the share of seeds whose truth
lies within 3 reported std; then the share over all (seed, parameter) pairs. The statistics
are computed here with numpy from the params.yaml files, not by guardid. Each table ends
with the band that sampling alone leaves at this many seeds (:func:`chance_bands`): at 20
seeds an unbiased method with an exact std shows a worst |bias| up to 0.69 std and a
spread/std anywhere in [0.53, 1.52] over 12 parameters, and meets issue 19's three bars in
only 7 % of such checks (:func:`chance_of_passing`); 100 seeds narrow the band to 0.31 and
[0.79, 1.22], and such a method meets the bars in 97 %.

    python bench/bench_std_check.py [--seeds 20] [--duration 60] [--methods ls,wls]
                                    [--excitations default,tracking] [--keep DIR [--reuse]]
                                    [--cutoff HZ]
                                    [--fixed-phase]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

from guardid.dynamics import build_model
from guardid.robot import load_robot

EXCITATIONS = {
    "default": [],
    "tracking": ["--base-freq", "0.2", "--harmonics", "3"],
}


def _guardid(*args) -> None:
    res = subprocess.run([sys.executable, "-m", "guardid", *args], capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"guardid {' '.join(args)} failed: {res.stderr.strip()[-400:]}")


def truth_values() -> dict[str, float]:
    """Base parameter name -> value of the robot YAML the simulator runs."""
    model = build_model(load_robot("guard"))
    return dict(zip(model.base.names, model.base.values(model.params), strict=True))


def collect(excitation: str, seeds, duration: float, methods: str, work: Path, phase=True,
            reuse=False, identify_args=()):  # fmt: skip
    """Per method: names (p,), estimates (S, p), stds (S, p) or None over the seeds.
    ``reuse``: a trajectory or log already in ``work`` (an earlier ``--keep``) is used as is;
    ``identify_args``: more options for ``guardid identify`` (e.g. ``--cutoff 8``)."""
    traj = work / f"traj_{excitation}.yaml"
    if not (reuse and traj.exists()):
        _guardid("excite", "--robot", "guard", "--force", "-o", str(traj), *EXCITATIONS[excitation])
    out: dict[str, dict] = {}
    for seed in seeds:
        log = work / f"{excitation}_{seed}.csv"
        params = work / f"{excitation}_{seed}.yaml"
        port = f"sim://guard?seed={seed}" + ("&phase=1" if phase else "")
        if not (reuse and log.exists()):
            _guardid("capture", "--trajectory", str(traj), "--duration", f"{duration:g}",
                     "--port", port, "--quiet", "--force", "-o", str(log))  # fmt: skip
        params.unlink(missing_ok=True)  # identify does not replace a file
        _guardid("identify", str(log), "--method", methods, *identify_args, "-o", str(params))
        data = yaml.safe_load(params.read_text())
        names = [b["name"] for b in data["base_parameters"]]
        for m, entry in data["methods"].items():
            d = out.setdefault(m, {"names": names, "theta": [], "std": []})
            d["theta"].append(entry["values"])
            d["std"].append(entry.get("std"))
        print(f"  {excitation} seed {seed} done", flush=True)
    return {
        m: (d["names"], np.array(d["theta"]), None if None in d["std"] else np.array(d["std"]))
        for m, d in out.items()
    }


def accuracy(results, truth) -> list[str]:
    """Lines: per base parameter and method, the median and worst |estimate - truth| over
    the seeds, in % of the truth (absolute, in the parameter's unit, where the truth is 0)."""
    methods = list(results)
    names = results[methods[0]][0]
    lines = [f"{'param':8s} {'truth':>9s}" + "".join(f" {m.upper() + ' med/worst':>22s}"
                                                    for m in methods)]  # fmt: skip
    for i, n in enumerate(names):
        tv = truth[n]
        cells = []
        for m in methods:
            err = np.abs(results[m][1][:, i] - tv)
            if tv != 0:
                err = 100.0 * err / abs(tv)
            unit = " %" if tv != 0 else "  "
            cells.append(f" {np.median(err):9.3g}/{err.max():9.3g}{unit}")
        lines.append(f"{n:8s} {tv:9.4g}" + "".join(cells))
    return lines


def statistics(names, theta, std, truth):
    """Rows (name, truth, spread/std, bias in std, share within 3 std) and the overall share."""
    tv = np.array([truth[n] for n in names])
    mean_std = std.mean(axis=0)
    spread = theta.std(axis=0, ddof=1) / mean_std
    bias = (theta.mean(axis=0) - tv) / mean_std
    inside = np.abs(theta - tv) <= 3.0 * std
    rows = [(n, tv[i], spread[i], bias[i], inside[:, i].mean()) for i, n in enumerate(names)]
    return rows, float(inside.mean())


def chance_bands(n_seeds: int, n_params: int, level: float = 0.95):
    """What sampling alone does to the statistics: the band that an unbiased method with an
    exact std (and independent seeds) stays within, for every parameter's bias and every
    parameter's spread at once, in ``level`` of such checks: (|bias| bound, spread/std low,
    high) in std. Normal and chi-square quantiles, Bonferroni over the 2 x ``n_params``
    statistics (conservative for correlated parameters).
    """
    from scipy.stats import chi2, norm

    a = (1.0 - level) / (2 * n_params)
    dof = n_seeds - 1
    bias = norm.ppf(1.0 - a / 2) / np.sqrt(n_seeds)
    low = np.sqrt(chi2.ppf(a / 2, dof) / dof)
    high = np.sqrt(chi2.ppf(1.0 - a / 2, dof) / dof)
    return float(bias), float(low), float(high)


def chance_of_passing(n_seeds: int, n_params: int, checks: int = 20000, seed: int = 0):
    """Share of simulated checks in which an unbiased method with an exact std (independent
    parameters and seeds, standard normal errors in std units) meets issue 19's three bars:
    truth within 3 std in >= 99 % of (seed, parameter) pairs, every |bias| < 0.5 std, every
    spread/std within [0.8, 1.25]."""
    rng = np.random.default_rng(seed)
    passed = 0
    for size in [1000] * (checks // 1000) + [checks % 1000]:  # bounded memory
        z = rng.standard_normal((size, n_seeds, n_params))
        inside = (np.abs(z) <= 3.0).mean(axis=(1, 2)) >= 0.99
        bias = np.abs(z.mean(axis=1)).max(axis=1) < 0.5
        spread = z.std(axis=1, ddof=1)
        ok = (spread.min(axis=1) >= 0.8) & (spread.max(axis=1) <= 1.25)
        passed += int(np.sum(inside & bias & ok))
    return passed / checks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="seeds 0..N-1")
    ap.add_argument("--duration", type=float, default=60.0, help="capture length [s]")
    ap.add_argument("--methods", default="ls,wls", help="guardid identify --method")
    ap.add_argument("--excitations", default="default,tracking", help="default,tracking")
    ap.add_argument("--keep", default=None, help="keep logs and params here")
    ap.add_argument("--fixed-phase", action="store_true", help="every seed starts on the grid")
    ap.add_argument("--reuse", action="store_true",
                    help="with --keep: use the trajectories and logs already there")  # fmt: skip
    ap.add_argument("--cutoff", type=float, default=None,
                    help="identify --cutoff HZ (default: chosen from the data)")  # fmt: skip
    a = ap.parse_args()
    truth = truth_values()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(a.keep) if a.keep else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for exc in a.excitations.split(","):
            extra = ("--cutoff", f"{a.cutoff:g}") if a.cutoff else ()
            results = collect(exc, range(a.seeds), a.duration, a.methods, work, not a.fixed_phase,
                              a.reuse and a.keep is not None, extra)  # fmt: skip
            for m, (names, theta, std) in results.items():
                if std is None:
                    continue
                rows, share = statistics(names, theta, std, truth)
                print(f"\n{exc} excitation, {m.upper()}, {theta.shape[0]} seeds,"
                      f" {a.duration:g} s captures (sim://guard?seed=N"
                      f"{'' if a.fixed_phase else '&phase=1'}, lock-step):")  # fmt: skip
                print(f"{'param':8s} {'truth':>9s} {'spread/std':>10s} {'bias/std':>9s}"
                      f" {'in 3 std':>9s}")  # fmt: skip
                for n, tv, sp, b, w in rows:
                    print(f"{n:8s} {tv:9.4g} {sp:10.2f} {b:+9.2f} {100 * w:8.0f} %")
                print(f"truth within 3 std in {100 * share:.1f} % of (seed, parameter) pairs")
                b, lo, hi = chance_bands(theta.shape[0], len(names))
                passing = chance_of_passing(theta.shape[0], len(names))
                print(f"chance alone (unbiased, exact std, {theta.shape[0]} seeds, {len(names)}"
                      f" parameters): in 95 % of checks every |bias| < {b:.2f} and every"
                      f" spread/std within [{lo:.2f}, {hi:.2f}]; such a method meets all"
                      f" three bars in {100 * passing:.0f} % of checks")  # fmt: skip
            print(f"\n{exc} excitation, |estimate - truth| over {a.seeds} seeds, median/worst:")
            print("\n".join(accuracy(results, truth)))


if __name__ == "__main__":
    main()
