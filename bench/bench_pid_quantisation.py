"""Does the closed loop carry the quantisation bias? (issue 27, evidence)

The firmware's PID closes on encoder counts, so the motor voltage (and the current the
identification uses as effort) is a function of the same quantisation error that corrupts the
regressor built from the counts. This script captures, per seed, the same run twice through
``sim://guard?seed=N&start=50&supply=0.02&ripple=0.01`` with the plant's true state recorded:

* ``loop counts``: the firmware as it is (PID on the counts);
* ``loop true``: the PID fed the plant's unquantised angle (in counts, less half a count: the
  floor's mean), in floating point; the log still carries the quantised counts.

Each capture is identified (``guardid.identify.identify``, conditioning resolved on the
measured log) on three versions of its log: ``counts+true i`` (encoder angles, the true
period-mean current: quantisation only), ``true q+true i`` (the model error alone) and
``measured``. Prints per base parameter the mean (rms) over seeds of (estimate - truth) / the
measured log's reported std. Statistics: numpy here.

    python bench/bench_pid_quantisation.py [--seeds 4] [--duration 600] [--method wls]
                                           [--excitation default|schroeder]
"""

from __future__ import annotations

import argparse
import itertools
import tempfile
from dataclasses import replace
from pathlib import Path

import bench_bias_sources as bias_sources
import numpy as np

import guardid.firmware.emulator as emulator_module
from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import build_model
from guardid.firmware.pid import FixedPid
from guardid.identify.pipeline import IdentifyOptions, identify
from guardid.robot import load_robot

EXCITATIONS = {
    "default": [],
    "schroeder": ["--kind", "schroeder"],
    "fast": ["--base-freq", "0.25", "--harmonics", "5"],  # bench_std_check's fast120
}
PORT = "start=50&supply=0.02&ripple=0.01"
_RECORD = bias_sources._recording_step
SCALE = 256
"""Sub-count resolution of the angle fed to the PID in ``loop true`` (its gains divided by
this, the setpoint and position multiplied: the same integer PID, finer input) [-]."""
_STATE = {"pid_on_true": False, "q": [0.0, 0.0], "per_rad": [1.0, 1.0]}


def _recording_step(self, u):
    out = _RECORD(self, u)
    _STATE["q"], _STATE["per_rad"] = list(self._q), self._per_rad  # read by the PID next
    return out


class _TruePid(FixedPid):
    """The firmware's PID, fed the plant's unquantised angle when ``pid_on_true``."""

    _index = itertools.count()

    def __init__(self, limit_mv: int) -> None:
        super().__init__(limit_mv)
        self.joint = next(self._index) % 2

    def set_gains(self, gains_q16) -> None:
        if _STATE["pid_on_true"]:
            gains_q16 = tuple(int(round(g / SCALE)) for g in gains_q16)
        super().set_gains(gains_q16)

    def step(self, setpoint: int, position: int, feedforward_mv: int = 0) -> int:
        if not _STATE["pid_on_true"]:
            return super().step(setpoint, position, feedforward_mv)
        j = self.joint
        fine = int(round(SCALE * (_STATE["q"][j] * _STATE["per_rad"][j] - 0.5)))
        return super().step(setpoint * SCALE, fine, feedforward_mv)


def capture(traj: Path, seed: int, duration: float, log: Path, pid_on_true: bool):
    """Capture ``log`` (:func:`bench_bias_sources.capture_with_truth` through ``PORT``);
    return (run, true q (N, 2) [rad], true current (N, 2) [A])."""
    _STATE["pid_on_true"] = pid_on_true
    bias_sources._recording_step = _recording_step
    emulator_module.FixedPid = _TruePid
    try:
        return bias_sources.capture_with_truth(traj, seed, duration, log, port=PORT)
    finally:
        bias_sources._recording_step = _RECORD
        emulator_module.FixedPid = FixedPid
        _STATE["pid_on_true"] = False


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--first-seed", type=int, default=7000)
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--method", default="wls")
    ap.add_argument("--excitation", default="default", choices=sorted(EXCITATIONS))
    a = ap.parse_args()
    desc = load_robot("guard")
    model = build_model(desc)
    truth = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    m = a.method
    z: dict[str, list] = {}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        traj = work / "traj.yaml"
        bias_sources._cli("excite", "--robot", "guard", "-o", str(traj), *EXCITATIONS[a.excitation])
        for seed in range(a.first_seed, a.first_seed + a.seeds):
            for loop, on_true in (("loop counts", False), ("loop true", True)):
                run, q_true, i_true = capture(traj, seed, a.duration, work / "x.csv", on_true)
                given = ConditioningOptions(equation="momentum")
                ref = identify([run], desc, IdentifyOptions(methods=(m,), conditioning=given))
                tv = np.array([truth[n] for n in ref.names])
                std = ref.results[m].std
                err = np.abs(np.floor(q_true * np.array(_STATE["per_rad"])) / _STATE["per_rad"]
                             - run.q).max()  # fmt: skip
                assert err < 1e-9, "log counts are not the floor of the true angle"
                for name, q, i in (("measured", run.q, run.current),
                                   ("counts+true i", run.q, i_true),
                                   ("true q+true i", q_true, i_true)):  # fmt: skip
                    r = ref if name == "measured" else identify(
                        [replace(run, q=q, current=i)], desc,
                        IdentifyOptions(methods=(m,), conditioning=ref.conditioning),
                    )  # fmt: skip
                    z.setdefault(f"{loop}: {name}", []).append((r.results[m].theta - tv) / std)
            print(f"  seed {seed} done", flush=True)
    print(f"\n{a.excitation}, {a.duration:g} s, {m.upper()}, {a.seeds} seeds: mean (rms) over "
          "seeds of (estimate - truth) / the measured log's std")  # fmt: skip
    keys = list(z)
    for k in keys:
        print(f"  [{keys.index(k)}] {k}")
    print(f"{'param':7s}" + "".join(f"{'[' + str(c) + ']':>14s}" for c in range(len(keys))))
    for k, n in enumerate(ref.names):
        cols = [np.array(z[key])[:, k] for key in keys]
        print(f"{n:7s}" + "".join(f"{c.mean():+7.2f} ({np.sqrt(np.mean(c**2)):4.2f})"
                                  for c in cols))  # fmt: skip


if __name__ == "__main__":
    main()
