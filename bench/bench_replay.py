"""Simulation error of identified parameters on a held-out capture (issue 28, item 1).

    nice -n 10 .venv/bin/python bench/bench_replay.py [--seeds 15] [--variant OPTIONS]

Per seed S: a 60 s capture of the default excitation (``guardid excite``, optimised, made
once) on ``sim://guard?seed=S&VARIANT`` identified with ``--method wls,iv``; a held-out 30 s
capture of another excitation (``excite --kind sines``) on seed S + 1000. Each parameter set
is replayed on the held-out log through ``guardid.replay.replay`` (the closed loop with the
log's setpoints from its first state): the true parameters (the robot YAML's), WLS, IV, and
the YAML's values 30 % off (every base parameter x 1.3: a YAML that is wrong).

Evaluator, independent of guardid's own score: the log's ``counts_*`` columns read with
numpy, the simulated angles times counts per radian from the log header's counts_per_rev;
rms of the difference per joint [counts] (and checked against guardid's ReplayScore).
Prints per seed and, per set and joint, median and worst over the seeds, and the ratio to
the true parameters' own error.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from guardid.cli import main
from guardid.dynamics import build_model
from guardid.identify.runs import load_run
from guardid.identify.validation import load_sets
from guardid.replay import counts_per_rad, replay, score
from guardid.robot import load_robot

SETS = ("true", "WLS", "IV", "30% off")


def run(*args) -> str:
    res = CliRunner().invoke(main, [str(a) for a in args])
    if res.exit_code != 0:
        raise SystemExit(f"guardid {' '.join(map(str, args))}: {res.output}")
    return res.output


def log_counts(path) -> tuple[np.ndarray, np.ndarray]:
    """(counts (N, 2), counts_per_rev (2,)) of a guardid log, by plain text parsing."""
    lines = Path(path).read_text().splitlines()
    head = lines[0].split(",")
    rows = np.array([[float(v) for v in x.split(",")] for x in lines[1:] if not x.startswith("#")])
    k = [head.index("counts_pan"), head.index("counts_tilt")]
    i = next(n for n, x in enumerate(lines) if x.strip() == "#   counts_per_rev:")
    cpr = np.array([int(lines[i + 1].split("-")[1]), int(lines[i + 2].split("-")[1])])
    return rows[:, k], cpr


def one_seed(seed, d: Path, fit_traj, held_traj, variant, desc, truth) -> dict:
    fit_log, held_log, params = d / f"fit{seed}.csv", d / f"held{seed}.csv", d / f"p{seed}.yaml"
    opts = f"&{variant}" if variant else ""
    run("capture", "--port", f"sim://guard?seed={seed}{opts}", "--trajectory", fit_traj,
        "--duration", 60, "--quiet", "-o", fit_log)  # fmt: skip
    run("identify", fit_log, "--method", "wls,iv", "-o", params)
    run("capture", "--port", f"sim://guard?seed={seed + 1000}{opts}", "--trajectory", held_traj,
        "--duration", 30, "--quiet", "-o", held_log)  # fmt: skip
    sets = {s.label.rsplit(":", 1)[-1]: s.values for s in load_sets(params, desc)}
    sets = {"true": truth, **sets, "30% off": {k: 1.3 * v for k, v in truth.items()}}
    held = load_run(held_log)
    counts, cpr = log_counts(held_log)
    out = {}
    for label, values in sets.items():
        q_sim = replay(held, desc, values)
        err = q_sim * cpr / (2 * math.pi) - counts
        rms = np.sqrt(np.mean(err**2, axis=0))
        own = score(label, "held", q_sim, held.q, counts_per_rad(desc)).rms_counts
        assert np.allclose(own, rms, rtol=1e-5, atol=1e-6), (own, rms)
        out[label] = rms
    return out


def main_() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=15)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--variant", default="start=50&supply=0.02&ripple=0.01",
                    help="sim:// options beside seed ('' for none)")  # fmt: skip
    a = ap.parse_args()
    desc = load_robot("guard")
    model = build_model(desc)
    truth = dict(zip(model.base.names, map(float, model.base.values(model.params)), strict=True))
    t0 = time.time()
    per_seed = []
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        fit_traj, held_traj = d / "fit.yaml", d / "held.yaml"
        run("excite", "-o", fit_traj)
        run("excite", "--kind", "sines", "-o", held_traj)
        print(f"variant: sim://guard?seed=S&{a.variant}; fit 60 s default excitation, seed S; "
              "held out 30 s --kind sines, seed S + 1000")  # fmt: skip
        print("rms simulation error on the held-out capture [counts], pan / tilt")
        print(f"{'seed':>5s}" + "".join(f"  {s:>15s}" for s in SETS))
        for seed in range(a.first_seed, a.first_seed + a.seeds):
            r = one_seed(seed, d, fit_traj, held_traj, a.variant, desc, truth)
            per_seed.append(r)
            print(f"{seed:5d}" + "".join(f"  {r[s][0]:6.3f} / {r[s][1]:6.3f}" for s in SETS),
                  flush=True)  # fmt: skip
    print(f"over {a.seeds} seeds: median / worst [counts], and ratio to the true parameters' "
          "error (median / worst)")  # fmt: skip
    for s in SETS:
        e = np.array([r[s] for r in per_seed])
        ratio = e / np.array([r["true"] for r in per_seed])
        cells = []
        for j, name in enumerate(("pan", "tilt")):
            med, worst = np.median(ratio[:, j]), ratio[:, j].max()
            cells.append(f"{name} {np.median(e[:, j]):.3f} / {e[:, j].max():.3f}"
                         f" (x{med:.2f} / x{worst:.2f})")  # fmt: skip
        print(f"  {s:8s} " + "; ".join(cells))
    print(f"wall {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main_()
