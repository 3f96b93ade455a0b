"""Online identification on the simulated guard robot: payload tracking and false alarms.

Captures 60 s runs through ``sim://guard?seed=N&phase=1`` (``--fixed-phase``: without
``phase``) with the online tracker live (RLS and Hopfield,
default settings) on two excitations: the tracking one (``guardid excite --base-freq 0.2
--harmonics 3``, 5 s period) and the default one (10 s period). Per excitation: seeds 1..N
with a +1 kg payload at ``--payload-time`` s of plant time, and seeds 1..N without. Prints
per run the settle times of MX2R and MY2 (the estimate stays within 5 % of the new value from
then to the end of the run, in s after the change), the reported change times relative to
the truth and the tracker's cost per row, then a summary per excitation and method.

    python bench/bench_online.py [--seeds 10] [--payload-time 30] [--only tracking|default]
                               [--fixed-phase]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from guardid.capture import capture
from guardid.cli import main as cli
from guardid.estimators.metrics import settle_time
from guardid.excitation import load_trajectory
from guardid.link import Session, open_port
from guardid.log import read_log
from guardid.online import OnlineIdentifier
from guardid.plant.payload import PayloadChange, base_values
from guardid.robot import load_robot

GUARD = load_robot("guard")
GRAVITY = ("MX2R", "MY2")
EXCITATIONS = {
    "tracking": ["--base-freq", "0.2", "--harmonics", "3"],
    "default": [],
}


def run(seed: int, payload: PayloadChange | None, trajectory, tmp: Path, phase: bool = True):
    """One 60 s live capture; returns (tracker, change time on the log's axis or None).
    ``phase``: the seed also places the start pose within an encoder count (``phase=1``),
    so that seeds differ in motion and quantisation, not only in the current's noise."""
    url = f"sim://guard?seed={seed}" + ("&phase=1" if phase else "")
    if payload is not None:
        com = ",".join(f"{c:g}" for c in payload.com)
        url += f"&payload_time={payload.time:g}&payload_mass={payload.mass:g}&payload_com={com}"
    tracker = OnlineIdentifier.for_trajectory(GUARD, ("rls", "hopfield"), trajectory)
    port = open_port(url)
    session = Session(port)
    session.handshake()
    log = tmp / f"{seed}.csv"
    capture(session, GUARD, trajectory, 60.0, log, {"robot": "guard"}, overwrite=True,
            on_row=lambda t, q, v, i: tracker.update(t, q, i, v))  # fmt: skip
    port.close()
    # the log's time axis starts at its first tick
    first_tick = read_log(log).columns["tick"][0]
    t_change = payload.time - first_tick * GUARD.sample_period if payload else None
    return tracker, t_change


def bench(name: str, args, payload: PayloadChange, tmp: Path) -> None:
    traj_path = tmp / f"{name}.yaml"
    cli(["excite", *EXCITATIONS[name], "-o", str(traj_path)], standalone_mode=False)
    trajectory = load_trajectory(traj_path)
    new = base_values(GUARD, payload)
    print(f"\n== {name} excitation ({trajectory.period:g} s period), "
          f"+{payload.mass:g} kg at {payload.time:g} s: settle MX2R / MY2 [s after the change], "
          "report time error")  # fmt: skip
    settle = {"rls": [], "hopfield": []}
    errors, extra_alarms = [], 0
    for seed in range(1, args.seeds + 1):
        tracker, t_change = run(seed, payload, trajectory, tmp, not args.fixed_phase)
        extra_alarms += sum(max(0, len(d.alarms) - 1) for d in tracker.detectors.values())
        parts = []
        for m, tr in tracker.tracks().items():
            st = [
                settle_time(tr.t, tr.theta[:, tracker.names.index(x)], new[x], t_change)
                for x in GRAVITY
            ]
            settle[m].append(st)
            rep = [r.at_s - t_change for r in tracker.reports if r.method == m]
            errors += rep[:1]
            parts.append(f"{m} {st[0]:.2f} / {st[1]:.2f} s, report {rep[0]:+.2f} s"
                         if rep else f"{m} {st[0]:.2f} / {st[1]:.2f} s, NO REPORT")  # fmt: skip
        print(f"  seed {seed}: " + "; ".join(parts) + f"; {tracker.us_per_row:.0f} us/row")
    calm = []
    for seed in range(1, args.seeds + 1):
        tracker, _ = run(seed, None, trajectory, tmp, not args.fixed_phase)
        alarms = sum(len(d.alarms) for d in tracker.detectors.values())
        calm.append((len(tracker.reports), alarms, tracker.us_per_row))
    print(f"  summary over {args.seeds} seeds:")
    for m, rows in settle.items():
        s = np.asarray(rows)
        print(f"    {m}: MX2R {s[:, 0].min():.2f}-{s[:, 0].max():.2f} s (median "
              f"{np.median(s[:, 0]):.2f}); MY2 {s[:, 1].min():.2f}-{s[:, 1].max():.2f} s "
              f"(median {np.median(s[:, 1]):.2f}), "
              f"{int(np.sum(s.max(axis=1) <= 5.0))}/{len(s)} runs both within 5 s")  # fmt: skip
    if errors:
        print(f"    reports: {len(errors)}/{2 * args.seeds}, "
              f"{min(errors):+.2f} to {max(errors):+.2f} s from the truth; "
              f"{extra_alarms} alarms besides the first per estimator")  # fmt: skip
    costs = [c[2] for c in calm]
    print(f"    without a change: {sum(c[0] for c in calm)} reports, "
          f"{sum(c[1] for c in calm)} alarms in {args.seeds} runs; "
          f"{min(costs):.0f}-{max(costs):.0f} us/row")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--payload-time", type=float, default=30.0, help="plant time [s]")
    ap.add_argument("--only", choices=sorted(EXCITATIONS), help="one excitation only")
    ap.add_argument(
        "--fixed-phase",
        action="store_true",
        help="leave phase=1 out: seeds differ only in the current's noise",
    )
    args = ap.parse_args()
    payload = PayloadChange(args.payload_time, 1.0, (0.12, 0.02, 0.0))
    with tempfile.TemporaryDirectory() as d:
        for name in [args.only] if args.only else EXCITATIONS:
            bench(name, args, payload, Path(d))


if __name__ == "__main__":
    main()
