"""The Monte Carlo's kept logs identified with the current as logged (whole mA) and with the
current put back on the ADC's levels (issue 27, evidence; docs/std_residuals.md).

A guardid log's current is the ADC's value (step 2 x range / 2^bits: 3.90625 mA on the guard)
rounded to whole mA by the telemetry. The step being above 1 mA, the code is recovered as
round(i / step). Per kept log ``DIR/SET_N.csv``: WLS on the log, then WLS on the recovered
levels with the same conditioning; prints over the seeds (numpy): truth within 3 std,
|bias|/std and spread/std per base parameter.

    python bench/bench_current_codes.py [--keep /tmp/mc_std/keep] [--set default1200]
                                        [--seeds 5000-5039]
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import build_model
from guardid.identify.pipeline import IdentifyOptions, identify
from guardid.identify.runs import load_run
from guardid.robot import load_robot


def current_levels(current_a, full_range_a: float, bits: int) -> np.ndarray:
    """The logged current [A] back on the ADC's levels (code x step); SystemExit when a
    value is not the whole-mA rounding of a level."""
    step = 2.0 * full_range_a / (1 << bits)
    code = np.round(np.asarray(current_a) / step)
    if np.any(np.abs(current_a - np.floor(code * step * 1000.0 + 0.5) / 1000.0) > 1e-9):
        raise SystemExit("the log's current is not the whole-mA rounding of ADC levels")
    return code * step


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", type=Path, default=Path("/tmp/mc_std/keep"))
    ap.add_argument("--set", default="default1200")
    ap.add_argument("--seeds", default="5000-5039")
    a = ap.parse_args()
    first, last = (int(x) for x in a.seeds.split("-"))
    desc = load_robot("guard")
    model = build_model(desc)
    truth = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    sensor = desc.joints[0].current_sensor
    z = []
    for seed in range(first, last + 1):
        run = load_run(a.keep / f"{a.set}_{seed}.csv")
        opts = IdentifyOptions(methods=("wls",), conditioning=ConditioningOptions())
        logged = identify([run], desc, opts)
        levels = replace(run, current=current_levels(run.current, sensor.range, sensor.adc_bits))
        coded = identify([levels], desc, replace(opts, conditioning=logged.conditioning))
        tv = np.array([truth[n] for n in logged.names])
        z.append([(r.results["wls"].theta - tv) / r.results["wls"].std for r in (logged, coded)])
    z = np.array(z)
    names = logged.names
    for p, label in enumerate(("current as logged (mA)", "current on the ADC's levels")):
        m, s = z[:, p].mean(0), z[:, p].std(0, ddof=1)
        print(f"{label}: within 3 std {100 * np.mean(np.abs(z[:, p]) <= 3):.1f} %, |bias| "
              f"median {np.median(np.abs(m)):.2f} worst {np.abs(m).max():.2f} "
              f"({names[int(np.abs(m).argmax())]}), spread median {np.median(s):.2f} "
              f"range {s.min():.2f}-{s.max():.2f}")  # fmt: skip
        print("   " + " ".join(f"{n} {m[i]:+.2f}/{s[i]:.2f}" for i, n in enumerate(names)))


if __name__ == "__main__":
    main()
