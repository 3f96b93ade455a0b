"""guardid doctor over seeds: each simulated wiring fault found and named, no false alarm.

Issue 29's acceptance check for ``doctor``. For every fault (and none) and every seed, the
checks run on ``sim://guard?seed=S&phase=1&ripple=R&wiring=F&firmware=FW`` (the encoder
phase and a supply ripple make the seeds differ in motion, not only in noise); the set of
failed (check, joint) rows is compared with the one the injected fault must give (the
truth here is the injection, not guardid's). The counts per revolution that doctor
measures for ``cpr:pan=96`` are summarised against 96 (median and worst relative error).

    python bench/bench_doctor.py [--seeds 15] [--firmware py] [--ripple 0.02]
"""

from __future__ import annotations

import argparse

import numpy as np

from guardid.doctor import run_checks
from guardid.link import Session, open_port
from guardid.robot import load_robot

EXPECTED = {
    "": set(),
    "encoder_reversed:tilt": {("encoder direction vs motor voltage", "tilt")},
    "motor_reversed:pan": {("encoder direction vs motor voltage", "pan")},
    "current_offset:pan=0.1": {("current offset at rest", "pan")},
    "current_gain:tilt=0.5": {("current sign under load", "tilt")},
    "cpr:pan=96": {("counts per revolution", "pan")},
    "stuck:tilt": {("encoder counts under voltage", "tilt")},
}


def run(url: str, description):
    port = open_port(url)
    try:
        session = Session(port)
        session.handshake()
        return run_checks(session, description)
    finally:
        port.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=15)
    ap.add_argument("--firmware", default="py", choices=["py", "c", "avr"])
    ap.add_argument("--ripple", type=float, default=0.02)
    args = ap.parse_args()
    guard = load_robot("guard")
    cpr_err = []
    print(f"{'wiring':24s} {'as expected':>12s}  other outcomes")
    for wiring, expected in EXPECTED.items():
        right, other = 0, []
        for seed in range(args.seeds):
            url = f"sim://guard?seed={seed}&phase=1&ripple={args.ripple}&firmware={args.firmware}"
            checks = run(url + (f"&wiring={wiring}" if wiring else ""), guard)
            failed = {(c.name, c.joint) for c in checks if c.verdict == "FAIL"}
            if failed == expected:
                right += 1
            else:
                other.append(sorted(failed))
            if wiring.startswith("cpr:"):
                name = ("counts per revolution", "pan")
                row = next(c for c in checks if (c.name, c.joint) == name)
                cpr_err.append(float(row.measured.split()[0].lstrip("~")) / 96.0 - 1.0)
        print(f"{wiring or '(clean)':24s} {right:>5d} of {args.seeds:<3d}  {other or ''}")
    err = np.abs(cpr_err)
    print(f"cpr:pan=96 measured: median |error| {np.median(err):.1%}, worst {err.max():.1%}")


if __name__ == "__main__":
    main()
