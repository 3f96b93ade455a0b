"""Acceptance figures of the consistent fit (issue 18): LS against ``--consistent``.

    .venv/bin/python bench/bench_consistent.py realdata     # DFKI runs 00-02, leave one out
    .venv/bin/python bench/bench_consistent.py guard SEEDS  # guard captures, SEEDS seeds
    .venv/bin/python bench/bench_consistent.py urdf SEEDS   # guard as URDF against as YAML

Evaluator (independent of guardid.estimators): rows A (M, n, b), torque y (M, n) from the
same conditioning for every set; error = rms(y - A theta) / rms(y) over all joints stacked.
``realdata``: fit LS and the consistent model on two runs, error on the third, each run
held out once; the consistent model's links are checked by hand (mass > 0, inertia about
the COM positive definite, triangle inequality). ``guard``: per seed, a 60 s capture of the
default excitation on ``sim://guard?seed=S`` (fit) and one on seed S + 1000 (held out);
|consistent - LS| / std_LS per base parameter, and the held-out errors.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from guardid.conditioning.options import ConditioningOptions
from guardid.identify.foreign import parse_mapping
from guardid.identify.pipeline import identified_names
from guardid.identify.rows import stacked_rows
from guardid.identify.runs import load_run
from guardid.physical import description_with, fit_consistent
from guardid.robot import load_robot

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "dfki-double-pendulum"
COLUMNS = "time=time,q1=pos_meas1,q2=pos_meas2,tau1=tau_meas1,tau2=tau_meas2"


def rel_error(A, y, theta) -> float:
    """rms(y - A theta) / rms(y), all joints stacked [-]."""
    r = y - np.einsum("mnb,b->mn", A, theta)
    return float(np.sqrt(np.mean(r**2)) / np.sqrt(np.mean(y**2)))


def ls(A, y):
    """(theta, std) by numpy lstsq, sigma^2 = rss / (M - b)."""
    A2, y1 = A.reshape(-1, A.shape[2]), y.reshape(-1)
    theta, *_ = np.linalg.lstsq(A2, y1, rcond=None)
    r = y1 - A2 @ theta
    cov = np.linalg.inv(A2.T @ A2) * (r @ r) / (len(y1) - len(theta))
    return theta, np.sqrt(np.diag(cov))


def links_physical(desc) -> bool:
    for link in desc.links:
        ev = np.linalg.eigvalsh(link.inertia)
        if link.mass <= 0 or ev[0] <= 0 or ev[2] > ev[0] + ev[1]:
            return False
    return True


def realdata() -> None:
    desc = load_robot("dfki_double_pendulum")
    mapping = parse_mapping([COLUMNS])
    rows = {}
    for k in range(3):
        run = load_run(DATA / f"trajectory_0{k}.csv", mapping=mapping, description=desc)
        _, A, y = stacked_rows(
            [(run.t, run.q, run.current)], desc,
            ConditioningOptions(cutoff_hz=5.0, parallel_filter_hz=3.0), effort_is_torque=True,
        )  # fmt: skip
        rows[k] = (A, y)
    print("held out | LS error | consistent error | consistent links physical")
    for out in range(3):
        fit_on = [k for k in range(3) if k != out]
        A = np.concatenate([rows[k][0] for k in fit_on])
        y = np.concatenate([rows[k][1] for k in fit_on])
        theta_ls, _ = ls(A, y)
        fit = fit_consistent(A, y, desc)
        full = description_with(desc, fit.names, fit.standard)
        e_ls, e_c = rel_error(*rows[out], theta_ls), rel_error(*rows[out], fit.base)
        print(f"run 0{out}   | {100 * e_ls:.3f} %  | {100 * e_c:.3f} %          | "
              f"{links_physical(full) and not fit.violations}")  # fmt: skip


def guard(seeds: int) -> None:
    from click.testing import CliRunner

    from guardid.cli import main

    desc = load_robot("guard")
    names = identified_names(desc)
    tmp = Path(tempfile.mkdtemp(prefix="bench-consistent-"))
    run = CliRunner()
    assert run.invoke(main, ["excite", "-o", str(tmp / "traj.yaml")]).exit_code == 0
    worst_std, d_diff, lines = [], [], []
    for seed in range(seeds):
        paths = []
        for s in (seed, seed + 1000):
            p = tmp / f"run{s}.csv"
            args = ["capture", "--trajectory", str(tmp / "traj.yaml"), "--duration", "60"]
            args += ["--quiet", "--port", f"sim://guard?seed={s}", "-o", str(p)]
            res = run.invoke(main, args)
            assert res.exit_code == 0, res.output
            paths.append(p)
        sets = []
        for p in paths:
            r = load_run(p)
            from guardid.online.offline import log_highest_harmonic

            _, A, y = stacked_rows(
                [(r.t, r.q, r.current)], desc, highest_harmonic_hz=log_highest_harmonic(p)
            )
            sets.append((A, y))
        (A, y), held = sets
        theta_ls, std = ls(A, y)
        fit = fit_consistent(A, y, desc)
        z = np.abs(fit.base - theta_ls) / std
        e_ls, e_c = rel_error(*held, theta_ls), rel_error(*held, fit.base)
        worst_std.append(z.max())
        d_diff.append(100 * (e_c - e_ls))
        lines.append(
            f"seed {seed:2d}: max |cons - LS|/std {z.max():.2e} ({names[int(z.argmax())]}), "
            f"held-out LS {100 * e_ls:.3f} %, consistent {100 * e_c:.3f} %, "
            f"physical {links_physical(description_with(desc, fit.names, fit.standard))}"
        )
        print(lines[-1], flush=True)
    print(f"max |cons - LS|/std over base parameters: median {np.median(worst_std):.2e}, "
          f"worst {np.max(worst_std):.2e}")  # fmt: skip
    print(f"held-out error consistent - LS [percentage points]: median {np.median(d_diff):.4f}, "
          f"worst {np.max(d_diff):.4f}")  # fmt: skip


def urdf(seeds: int) -> None:
    """guard written as URDF + side YAML (guardid export), captured from sim:// and identified
    beside the YAML robot, per seed: identical telemetry rows? LS and consistent base values
    (matched by name without the R suffix) and held-out errors."""
    from click.testing import CliRunner

    from guardid.cli import main

    tmp = Path(tempfile.mkdtemp(prefix="bench-urdf-"))
    run = CliRunner()
    assert run.invoke(main, ["excite", "-o", str(tmp / "traj.yaml")]).exit_code == 0
    arm = tmp / "arm.urdf"
    assert run.invoke(main, ["export", "--robot", "guard", "--urdf", str(arm)]).exit_code == 0
    diffs, same_rows = [], 0
    for seed in range(seeds):
        out = {}
        for robot in ("guard", str(arm)):
            p = tmp / f"{Path(robot).stem}{seed}.csv"
            args = ["capture", "--robot", robot, "--trajectory", str(tmp / "traj.yaml")]
            args += ["--duration", "60", "--quiet", "--port", f"sim://{robot}?seed={seed}"]
            res = run.invoke(main, [*args, "-o", str(p)])
            assert res.exit_code == 0, res.output
            desc = load_robot(robot)
            r = load_run(p)
            from guardid.online.offline import log_highest_harmonic

            _, A, y = stacked_rows(
                [(r.t, r.q, r.current)], desc, highest_harmonic_hz=log_highest_harmonic(p)
            )
            theta, std = ls(A, y)
            fit = fit_consistent(A, y, desc)
            names = [n.rstrip("R") for n in identified_names(desc)]
            rows_text = [x for x in p.read_text().splitlines() if not x.startswith("#")][1:]
            out[robot] = (
                {n: (t, sd, c) for n, t, sd, c in zip(names, theta, std, fit.base, strict=True)},
                rows_text,
            )
        (yam, rows_y), (urd, rows_u) = out.values()
        same_rows += rows_y == rows_u
        d_ls = max(abs(yam[k][0] - urd[k][0]) / abs(yam[k][0]) for k in yam)
        d_c = max(abs(yam[k][2] - urd[k][2]) / yam[k][1] for k in yam)
        diffs.append((d_ls, d_c))
        print(f"seed {seed:2d}: rows identical {rows_y == rows_u}, LS base values max relative "
              f"difference {d_ls:.1e}, consistent base values max difference {d_c:.1e} std_LS",
              flush=True)  # fmt: skip
    diffs = np.array(diffs)
    print(f"{same_rows}/{seeds} seeds with identical telemetry; LS relative difference: median "
          f"{np.median(diffs[:, 0]):.1e}, worst {diffs[:, 0].max():.1e}; consistent [std_LS]: "
          f"median {np.median(diffs[:, 1]):.1e}, worst {diffs[:, 1].max():.1e}")  # fmt: skip


if __name__ == "__main__":
    if sys.argv[1:2] == ["realdata"]:
        realdata()
    elif sys.argv[1:2] == ["urdf"]:
        urdf(int(sys.argv[2]) if len(sys.argv) > 2 else 15)
    else:
        guard(int(sys.argv[2]) if len(sys.argv) > 2 else 15)
