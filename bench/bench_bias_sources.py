"""Where the closed-loop bias of identify's estimates comes from (issue 19, evidence).

Per seed, one capture through ``sim://guard?seed=N&phase=1`` (``--fixed-phase``: without
``phase``; lock-step, noise on) in this process,
with the plant's true state recorded tick by tick (a wrapper around ``Plant.step_sensors``:
true joint angles and the true period-mean motor current). Then the same identification
(``guardid.identify.identify`` with the log's automatic conditioning, resolved once on the
measured log and reused) on four versions of the log:

* ``measured``: what the log holds (encoder angles, measured current);
* ``true q``: true angles (no quantisation), measured current;
* ``true i``: encoder angles, true current (no current-sensor noise);
* ``both``: true angles and true current: what is left is model error (stiction, filter).

Prints, per base parameter, the mean over seeds of (estimate - truth) / (the measured log's
reported std), and in brackets the rms over seeds. The truth is the simulator's robot YAML;
the statistics are a few lines of numpy here, not guardid's. Each equation form of
``--equations`` (``momentum``: the filtered momentum form, identify's default for guardid
logs; ``acceleration``: the low-pass, twice-differentiated form) gets its own table, its
conditioning resolved on the measured log; the captures are shared.

    python bench/bench_bias_sources.py [--seeds 6] [--duration 60] [--method ls]
                                       [--excitations default,tracking] [--fixed-phase]
                                       [--robot guard] [--port-options OPTS]
                                       [--cutoff HZ] [--equations momentum,acceleration]
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

import guardid.plant.plant as plant_module
from guardid.cli import main as cli
from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import build_model
from guardid.identify.pipeline import IdentifyOptions, identify
from guardid.identify.runs import load_run
from guardid.robot import load_robot

EXCITATIONS = {
    "default": [],
    "tracking": ["--base-freq", "0.2", "--harmonics", "3"],
    "schroeder": ["--kind", "schroeder"],
    "fast": ["--base-freq", "0.25", "--harmonics", "5"],  # bench_std_check's fast120
}
_TRUTH: list = []
_STEP = plant_module.Plant.step_sensors


def _recording_step(self, u):
    counts, v, i, _v_true, i_true = self._measure(*self._integrate(u))
    _TRUTH.append((self._tick, *self._q, *i_true))
    return counts, v, i


def _cli(*args) -> None:
    try:
        cli(list(args), standalone_mode=False)
    except SystemExit as exc:
        if exc.code:
            raise


def capture_with_truth(traj: Path, seed: int, duration: float, log: Path, phase: bool = True,
                       port: str | None = None, robot: str = "guard"):  # fmt: skip
    """Capture ``log``; return (run, true q (N, 2) [rad], true current (N, 2) [A]).
    ``phase``: the seed also places the start pose within an encoder count (``phase=1``);
    ``port``: other fake-port options instead (e.g. ``start=50&supply=0.02``); ``robot``:
    the simulated robot (a name or a YAML path)."""
    _TRUTH.clear()
    plant_module.Plant.step_sensors = lambda self, u: _recording_step(self, u)
    try:
        port = f"sim://{robot}?seed={seed}" + (f"&{port}" if port else "&phase=1" if phase else "")
        _cli("capture", "--trajectory", str(traj), "--duration", f"{duration:g}",
             "--robot", robot, "--port", port, "--quiet", "--force", "-o", str(log))  # fmt: skip
    finally:
        plant_module.Plant.step_sensors = _STEP
    truth = np.array(_TRUTH)
    where = {int(t): k for k, t in enumerate(truth[:, 0])}
    run = load_run(log)
    rows = np.array([where[int(t)] for t in run.ticks])
    return run, truth[rows, 1:3], truth[rows, 3:5]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6, help="seeds 0..N-1")
    ap.add_argument("--duration", type=float, default=60.0, help="capture length [s]")
    ap.add_argument("--method", default="ls", help="ls or wls")
    ap.add_argument("--excitations", default="default,tracking")
    ap.add_argument(
        "--cutoff", type=float, default=None,
        help="low-pass cut-off [Hz] (default: chosen from the measured log)",
    )  # fmt: skip
    ap.add_argument("--equations", default="momentum,acceleration",
                    help="equation forms to compare (comma-separated)")  # fmt: skip
    ap.add_argument(
        "--fixed-phase",
        action="store_true",
        help="leave phase=1 out: every seed starts at the same encoder phase",
    )
    ap.add_argument("--robot", default="guard", help="robot name or YAML path (default guard)")
    ap.add_argument(
        "--port-options",
        default=None,
        help="fake-port options in place of phase=1, e.g. start=50&supply=0.02",
    )
    a = ap.parse_args()
    desc = load_robot(a.robot)
    model = build_model(desc)
    truth = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    m = a.method
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for exc in a.excitations.split(","):
            traj = work / f"traj_{exc}.yaml"
            _cli("excite", "--robot", a.robot, "-o", str(traj), *EXCITATIONS[exc])
            equations = a.equations.split(",")
            z: dict[str, dict[str, list]] = {eq: {} for eq in equations}
            for seed in range(a.seeds):
                run, q_true, i_true = capture_with_truth(traj, seed, a.duration,
                                                         work / f"{exc}_{seed}.csv",
                                                         not a.fixed_phase, a.port_options,
                                                         a.robot)  # fmt: skip
                for eq in equations:
                    given = ConditioningOptions(cutoff_hz=a.cutoff, equation=eq)
                    ref = identify([run], desc, IdentifyOptions(methods=(m,), conditioning=given))
                    tv = np.array([truth[n] for n in ref.names])
                    std = ref.results[m].std
                    for name, q, i in (("measured", run.q, run.current), ("true q", q_true,
                                       run.current), ("true i", run.q, i_true),
                                       ("both", q_true, i_true)):  # fmt: skip
                        r = ref if name == "measured" else identify(
                            [replace(run, q=q, current=i)], desc,
                            IdentifyOptions(methods=(m,), conditioning=ref.conditioning),
                        )  # fmt: skip
                        z[eq].setdefault(name, []).append((r.results[m].theta - tv) / std)
                print(f"  {exc} seed {seed} done", flush=True)
            for eq in equations:
                print(f"\n{exc} excitation, {eq} form, {m.upper()}, {a.seeds} seeds: mean (rms) "
                      "over seeds of (estimate - truth) / the measured log's std")  # fmt: skip
                print(f"{'param':7s}" + "".join(f"{k:>16s}" for k in z[eq]))
                for k, n in enumerate(ref.names):
                    cols = [np.array(v)[:, k] for v in z[eq].values()]
                    cells = "".join(f"{c.mean():+9.2f} ({np.sqrt(np.mean(c**2)):4.2f})"
                                    for c in cols)  # fmt: skip
                    print(f"{n:7s}{cells}")


if __name__ == "__main__":
    main()
