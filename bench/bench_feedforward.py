"""Model-based feedforward on the simulated guard robot: tracking error with and without it.

Per seed N (1..--seeds): an identification capture of the default excitation (unscaled, its
own plant seed 1000 + N, ``--ident-duration`` s) and ``guardid identify --method wls`` on it;
then on ``sim://guard?seed=N&phase=1`` (``firmware=`` py, c or avr) each test excitation is
captured (``--duration`` s) three times: PID alone, feedforward from the identified
parameters, feedforward from the true ones (the robot YAML's, which the simulator runs).
Test excitations: the default (``guardid excite``) and the tracking one (``--base-freq 0.2
--harmonics 3``); both ask the tilt for more than its 12 V supply at their peak (12.7 V and
13.7 V with the true model, which capture --feedforward refuses), so both are scaled about
their centre by the largest factor (steps of 0.05) that keeps the true model's feedforward
within --headroom (0.9) of the supply, the same trajectory for all three runs.

Evaluator (independent of guardid's footer): numpy on the log's columns, the measured joint
angle q_*_rad against the trajectory's exact angle at the row's time, rms per joint over all
rows ("whole run") and over the rows after the first trajectory period ("steady": without
the start, where the tilt has sagged under gravity while the robot was idle for the
handshake, some 0.1-0.4 deg for the first second whatever the feedforward). Prints per
excitation and firmware the median and the worst (largest) over seeds of each joint's rms
[deg], the ratios PID / feedforward(identified) (worst = smallest) and
feedforward(identified) / feedforward(true) (worst = largest).

Payload (--payload): a +MASS kg point mass on the arm at --payload-time s of plant time,
tracking excitation: rms over the rows after the change with PID alone, with the
identified feedforward (stale: identified without the payload) and with a feedforward that
switches to the true post-change model exactly at the change (the best a live update from
the online tracker could do, which also needs a period or so to converge).

    python bench/bench_feedforward.py [--seeds 15] [--firmware py,c] [--avr-seeds 5]
                                      [--duration 30] [--ident-duration 60] [--payload]
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from guardid.capture import capture
from guardid.cli import main as cli
from guardid.excitation import load_trajectory
from guardid.feedforward import FeedforwardModel, load_feedforward, supply_share
from guardid.link import Session, open_port
from guardid.plant.payload import PayloadChange, base_values
from guardid.robot import load_robot

GUARD = load_robot("guard")
EXCITATIONS = {"default": [], "tracking": ["--base-freq", "0.2", "--harmonics", "3"]}
KINDS = ("pid", "ff_ident", "ff_true")
WINDOWS = ("whole run", "steady")


def excite(name: str, tmp: Path):
    path = tmp / f"{name}.yaml"
    cli(["excite", *EXCITATIONS[name], "--force", "-o", str(path)], standalone_mode=False)
    return load_trajectory(path)


def fitting_scale(trajectory, models, headroom: float) -> float:
    """The largest factor (0.05 steps) keeping every model's feedforward within headroom x
    the supply over the scaled trajectory."""
    for k in range(20, 0, -1):
        scaled = trajectory.scaled([0.05 * k] * trajectory.n_joints)
        if max(supply_share(m, scaled)[0] for m in models) <= headroom:
            return 0.05 * k
    raise SystemExit("no scale fits")


def run(url: str, trajectory, duration: float, log: Path, feedforward=None) -> np.ndarray:
    """One capture; returns the evaluator's (rows, n) error q_traj(t) - q_measured [rad] and
    the row times [s]."""
    port = open_port(url)
    try:
        session = Session(port)
        session.handshake()
        capture(session, GUARD, trajectory, duration, log, {"robot": "guard"}, overwrite=True,
                feedforward=feedforward)  # fmt: skip
    finally:
        port.close()
    return evaluate(log, trajectory)


def evaluate(log: Path, trajectory):
    """(times [s], errors (N, n) [rad]) from the CSV with numpy alone: q_*_rad against the
    trajectory at time_s."""
    lines = [ln for ln in log.read_text().splitlines() if not ln.startswith("#")]
    head = lines[0].split(",")
    data = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])
    t = data[:, head.index("time_s")]
    q = data[:, [head.index(f"q_{j.name}_rad") for j in GUARD.joints]]
    return t, trajectory.positions(t) - q


def rms(err) -> np.ndarray:
    return np.sqrt(np.mean(err**2, axis=0))


def identify(seed: int, ident_traj: Path, firmware: str, duration: float, tmp: Path) -> Path:
    log, params = tmp / f"ident_{firmware}_{seed}.csv", tmp / f"ident_{firmware}_{seed}.yaml"
    url = f"sim://guard?seed={1000 + seed}&phase=1&firmware={firmware}"
    cli(["capture", "--port", url, "--trajectory", str(ident_traj), "--duration", str(duration),
         "--quiet", "--force", "-o", str(log)], standalone_mode=False)  # fmt: skip
    cli(["identify", str(log), "--method", "wls", "--force", "-o", str(params)],
        standalone_mode=False)  # fmt: skip
    return params


@dataclass
class Switched:
    """Feedforward from ``before`` until ``t_switch`` [s] of the trajectory, ``after`` then."""

    before: FeedforwardModel
    after: FeedforwardModel
    t_switch: float
    label: str = "switched"

    def trajectory_voltage(self, trajectory, t_s):
        t_s = np.asarray(t_s, dtype=float)
        a = self.before.trajectory_voltage(trajectory, t_s)
        b = self.after.trajectory_voltage(trajectory, t_s)
        return np.where((t_s >= self.t_switch)[:, None], b, a)


def summary(label: str, table: dict) -> None:
    """table: kind -> (seeds, n) rms [rad]."""
    names = [j.name for j in GUARD.joints]
    print(f"  {label}: rms tracking error [deg] per joint, median / worst over "
          f"{len(table['pid'])} seeds")  # fmt: skip
    for kind in KINDS:
        r = np.degrees(np.asarray(table[kind]))
        cells = ", ".join(f"{n} {np.median(r[:, j]):.4f} / {r[:, j].max():.4f}"
                          for j, n in enumerate(names))  # fmt: skip
        print(f"    {kind:9s} {cells}")
    gain = np.asarray(table["pid"]) / np.asarray(table["ff_ident"])
    gap = np.asarray(table["ff_ident"]) / np.asarray(table["ff_true"])
    print("    PID / ff(identified): " + ", ".join(
        f"{n} median {np.median(gain[:, j]):.1f}x, worst {gain[:, j].min():.1f}x"
        for j, n in enumerate(names)))  # fmt: skip
    print("    ff(identified) / ff(true): " + ", ".join(
        f"{n} median {np.median(gap[:, j]):.3f}, worst {gap[:, j].max():.3f}"
        for j, n in enumerate(names)))  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=15)
    ap.add_argument("--firmware", default="py,c", help="comma-separated: py, c, avr")
    ap.add_argument("--avr-seeds", type=int, default=5, help="seeds for firmware=avr (slow)")
    ap.add_argument("--duration", type=float, default=30.0, help="test capture [s]")
    ap.add_argument("--ident-duration", type=float, default=60.0, help="identification [s]")
    ap.add_argument("--headroom", type=float, default=0.9)
    ap.add_argument("--payload", action="store_true", help="also the payload change")
    ap.add_argument("--payload-mass", type=float, default=0.5)
    ap.add_argument("--payload-time", type=float, default=15.0, help="plant time [s]")
    ap.add_argument("--only", choices=sorted(EXCITATIONS), help="one test excitation only")
    args = ap.parse_args()
    true = FeedforwardModel.from_description(GUARD, "the robot YAML (true)")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        excitations = {name: excite(name, tmp) for name in EXCITATIONS}
        if args.only:
            excitations = {args.only: excitations[args.only]}
        ident_traj = tmp / "default.yaml"
        change = PayloadChange(args.payload_time, args.payload_mass, (0.2, 0.0, 0.0))
        names = list(true.model.base.names)
        heavy = FeedforwardModel(
            GUARD, np.array([base_values(GUARD, change)[n] for n in names]),
            true.resistance_ohm, true.ke_v_s_per_rad, "true with the payload", true.model,
        )  # fmt: skip
        scaled = {}
        for name, traj in excitations.items():
            models = [true, heavy] if (args.payload and name == "tracking") else [true]
            s = fitting_scale(traj, models, args.headroom)
            scaled[name] = traj.scaled([s] * traj.n_joints)
            print(f"{name} excitation ({traj.period:g} s period): scaled by {s:.2f}, true "
                  f"feedforward peak {supply_share(true, traj)[0]:.3f} -> "
                  f"{supply_share(true, scaled[name])[0]:.3f} of the supply")  # fmt: skip
        for firmware in args.firmware.split(","):
            n_seeds = args.avr_seeds if firmware == "avr" else args.seeds
            tables = {(name, w): {k: [] for k in KINDS} for name in scaled for w in WINDOWS}
            pay = {k: [] for k in ("pid", "ff_ident", "ff_switched")}
            t_after = change.time  # set from each payload run's first tick below
            for seed in range(1, n_seeds + 1):
                params = identify(seed, ident_traj, firmware, args.ident_duration, tmp)
                ident = load_feedforward(str(params), GUARD)
                url = f"sim://guard?seed={seed}&phase=1&firmware={firmware}"
                for name, traj in scaled.items():
                    for kind, ff in zip(KINDS, (None, ident, true), strict=True):
                        log = tmp / f"{name}_{kind}.csv"
                        t, err = run(url, traj, args.duration, log, ff)
                        tables[name, "whole run"][kind].append(rms(err))
                        tables[name, "steady"][kind].append(rms(err[t >= traj.period]))
                if args.payload and "tracking" in scaled:
                    purl = (f"{url}&payload_time={change.time:g}&payload_mass={change.mass:g}"
                            "&payload_com=0.2,0,0")  # fmt: skip
                    for kind, ff in (("pid", None), ("ff_ident", ident), ("ff_switched", None)):
                        log = tmp / f"payload_{kind}.csv"
                        if kind == "ff_switched":
                            # the plant's change time on the trajectory's axis (the log's)
                            ff = Switched(true, heavy, t_after)
                        t, err = run(purl, scaled["tracking"], args.duration, log, ff)
                        if kind == "pid":
                            t_after = change.time - _first_tick(log) * GUARD.sample_period
                        pay[kind].append(rms(err[t >= t_after]))
                print(f"  firmware={firmware} seed {seed} (steady): " + "; ".join(
                    f"{name} " + " ".join(
                        f"{k} {np.degrees(tables[name, 'steady'][k][-1]).round(4)}"
                        for k in KINDS) for name in scaled))  # fmt: skip
            print(
                f"\n== firmware={firmware}, {args.duration:g} s captures, identification "
                f"on {args.ident_duration:g} s of the default excitation (another seed)"
            )
            for (name, window), table in tables.items():
                summary(f"{name} excitation, {window}", table)
            if args.payload and "tracking" in scaled:
                print(f"  payload +{change.mass:g} kg at (0.2, 0, 0) m on the arm at "
                      f"{change.time:g} s, tracking excitation, rms after the change [deg], "
                      "median / worst:")  # fmt: skip
                for kind, rows in pay.items():
                    r = np.degrees(np.asarray(rows))
                    print(f"    {kind:11s} " + ", ".join(
                        f"{j.name} {np.median(r[:, k]):.4f} / {r[:, k].max():.4f}"
                        for k, j in enumerate(GUARD.joints)))  # fmt: skip


def _first_tick(log: Path) -> int:
    for line in log.read_text().splitlines()[1:]:
        if not line.startswith("#"):
            return int(line.split(",")[0])
    raise SystemExit(f"{log}: no rows")


if __name__ == "__main__":
    main()
