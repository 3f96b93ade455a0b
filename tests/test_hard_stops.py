"""Hard stops and the stiction guard, measured from the filter (issue 19: the closed-loop bias).

The guard robot's tilt sags onto its -10 deg stop in closed loop; the stop's contact force
and impact are not in the rigid-body model, and the zero-phase low-pass carries them into
the neighbouring rows. Truth here: a plant without Coulomb friction (no stick/slip) whose
true angles and true period-mean currents are recorded tick by tick; identified from those
noise-free signals, every base parameter must come out at the YAML's value, to a small
fraction of the noisy log's standard deviation.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from scipy.signal import butter, sosfilt

import guardid.plant.plant as plant_module
from guardid.cli import main as cli
from guardid.conditioning.stiction import at_position_limit, guard_periods
from guardid.dynamics import build_model
from guardid.identify import IdentifyOptions, identify, run_from_arrays
from guardid.identify.runs import load_run
from guardid.robot import load_robot
from guardid.robot.loader import shipped_path

# An optimised 5 s excitation (guardid excite --base-freq 0.2 --harmonics 3, seed 0): an input.
TRAJECTORY = {
    "kind": "fourier", "joints": ["pan", "tilt"], "base_freq": 0.2, "harmonics": 3,
    "periods": 1, "q0": [-0.08808754383062498, 0.11318066056031564],
    "a": [[-0.08045790402922078, 0.26080021266988884, -0.18034230864066814],
          [-0.2520305973588437, 0.1654440987230211, 0.08658649863582266]],
    "b": [[-0.007863928384857232, -0.37333408919078376, 0.251510702255475],
          [0.17903336100361764, -0.06088950949916858, -0.019084780668426796]],
}  # fmt: skip


def test_guard_periods_match_the_autocorrelation_of_the_causal_response():
    """filtfilt's impulse response is the autocorrelation of the causal one: an independent
    way to the same span (order 4, 95 % and 99 % of the absolute mass)."""
    fs_per_fc = 400.0
    x = np.zeros(int(60 * fs_per_fc))
    x[0] = 1.0
    h = sosfilt(butter(4, 1.0, fs=fs_per_fc, output="sos"), x)
    acf = np.correlate(h, h, mode="full")[len(h) - 1 :]  # lags 0, 1, ...
    mass = np.abs(acf[0]) + 2.0 * np.cumsum(np.abs(acf[1:]))
    for share in (0.95, 0.99):
        k = int(np.searchsorted(mass / mass[-1], share)) + 1
        assert guard_periods(4, share) == pytest.approx(k / fs_per_fc, abs=0.01)


def test_at_position_limit_by_hand():
    limits = [[np.nan, np.nan], [-0.2, 0.6]]  # joint 1 unlimited; travel 0.8 -> tol 0.8e-3
    q = np.array([[5.0, 0.0], [0.0, -0.1995], [0.0, -0.1990], [0.0, 0.5995], [0.0, 0.7]])
    assert at_position_limit(q, limits).tolist() == [False, True, False, True, True]
    assert at_position_limit(q, limits, resolution=[0.0, 0.001]).tolist() == [
        False, True, True, True, True]  # fmt: skip


@pytest.fixture(scope="module")
def no_coulomb_run(tmp_path_factory):
    """(run, true q (N, 2) [rad], true current (N, 2) [A], description) of a 60 s capture."""
    d = tmp_path_factory.mktemp("stops")
    robot = yaml.safe_load(shipped_path("guard").read_text())
    for joint in robot["joints"]:
        joint["friction"]["coulomb"] = 0.0
    robot_file = d / "guard_no_coulomb.yaml"
    robot_file.write_text(yaml.safe_dump(robot))
    traj = d / "traj.yaml"
    traj.write_text(yaml.safe_dump(TRAJECTORY))
    truth = []
    step = plant_module.Plant.step_sensors

    def recording(self, u):
        counts, v, i, _v_true, i_true = self._measure(*self._integrate(u))
        truth.append((self._tick, *self._q, *i_true))
        return counts, v, i

    plant_module.Plant.step_sensors = recording
    try:
        cli(["capture", "--trajectory", str(traj), "--duration", "60", "--port",
             f"sim://{robot_file}?seed=3", "--quiet", "-o", str(d / "run.csv")],
            standalone_mode=False)  # fmt: skip
    finally:
        plant_module.Plant.step_sensors = step
    run = load_run(d / "run.csv")
    rec = np.array(truth)
    where = {int(t): k for k, t in enumerate(rec[:, 0])}
    rows = np.array([where[int(t)] for t in run.ticks])
    return run, rec[rows, 1:3], rec[rows, 3:5], load_robot(str(robot_file))


def test_the_tilt_meets_its_stop_and_those_rows_are_dropped(no_coulomb_run):
    run, q_true, _, desc = no_coulomb_run
    assert np.degrees(q_true[:, 1].min()) <= -10.0 + 1e-6  # resting on the stop
    result = identify([run], desc, IdentifyOptions(methods=("ls",)))
    assert "at or next to a hard stop" in result.rows_summary
    assert any("position limit (hard stop)" in n for n in result.notes)


def test_noise_free_signals_give_the_truth_despite_the_stop(no_coulomb_run):
    run, q_true, i_true, desc = no_coulomb_run
    model = build_model(desc)
    measured = identify([run], desc, IdentifyOptions(methods=("wls",)))
    values = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    truth = np.array([values[n] for n in measured.names])
    clean = identify(
        [run_from_arrays(run.t, q_true, i_true, highest_harmonic_hz=run.highest_harmonic_hz)],
        desc, IdentifyOptions(methods=("wls",), conditioning=measured.conditioning),
    )  # fmt: skip
    z = (clean.results["wls"].theta - truth) / measured.results["wls"].std
    worst = dict(zip(measured.names, np.round(z, 2), strict=True))
    assert np.all(np.abs(z) < 0.3), worst
