"""Online identification on the simulated guard robot: payload tracking and false alarms.

Captures 60 s runs through ``sim://guard`` on the default excitation (``guardid excite``
defaults) with the online tracker live (RLS and Hopfield, default settings): seeds 1..N with
a +1 kg payload at 30 s of plant time, and seeds 1..N without. Prints per run the settle
times of MX2R and MY2 (the estimate stays within 5 % of the new value from then to the end
of the run, in s after the change), the reported change times relative to the truth, and the
tracker's cost per row.

    python bench/bench_online.py [--seeds 5]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

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
PAYLOAD = PayloadChange(30.0, 1.0, (0.12, 0.02, 0.0))
GRAVITY = ("MX2R", "MY2")


def run(seed: int, payload: bool, trajectory, tmp: Path):
    url = f"sim://guard?seed={seed}"
    if payload:
        url += "&payload_time=30&payload_mass=1.0&payload_com=0.12,0.02,0"
    tracker = OnlineIdentifier(GUARD, ("rls", "hopfield"), highest_harmonic_hz=0.5)
    port = open_port(url)
    session = Session(port)
    session.handshake()
    log = tmp / f"{seed}.csv"
    capture(session, GUARD, trajectory, 60.0, log, {"robot": "guard"},
            on_row=lambda t, q, v, i: tracker.update(t, q, i, v))  # fmt: skip
    port.close()
    # the log's time axis starts at its first tick
    first_tick = read_log(log).columns["tick"][0]
    t_change = PAYLOAD.time - first_tick * GUARD.sample_period if payload else None
    return tracker, t_change


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    args = ap.parse_args()
    new = base_values(GUARD, PAYLOAD)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        cli(["excite", "-o", str(tmp / "traj.yaml")], standalone_mode=False)
        trajectory = load_trajectory(tmp / "traj.yaml")
        print("payload +1 kg at 30 s: settle MX2R / MY2 [s after the change], report time error")
        for seed in range(1, args.seeds + 1):
            tracker, t_change = run(seed, True, trajectory, tmp)
            parts = []
            for m, tr in tracker.tracks().items():
                st = [
                    settle_time(tr.t, tr.theta[:, tracker.names.index(x)], new[x], t_change)
                    for x in GRAVITY
                ]
                rep = [r.time_s - t_change for r in tracker.reports if r.method == m]
                parts.append(f"{m} {st[0]:.2f} / {st[1]:.2f} s, report {rep[0]:+.2f} s"
                             if rep else f"{m} {st[0]:.2f} / {st[1]:.2f} s, NO REPORT")  # fmt: skip
            print(f"  seed {seed}: " + "; ".join(parts) + f"; {tracker.us_per_row:.0f} us/row")
        print("no change: reports and alarms per run")
        for seed in range(1, args.seeds + 1):
            tracker, _ = run(seed, False, trajectory, tmp)
            alarms = sum(len(d.alarms) for d in tracker.detectors.values())
            print(f"  seed {seed}: {len(tracker.reports)} reports, {alarms} alarms; "
                  f"{tracker.us_per_row:.0f} us/row")  # fmt: skip


if __name__ == "__main__":
    main()
