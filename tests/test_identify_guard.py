"""Identification acceptance on the simulated guard robot (known truth = the YAML).

One optimised excitation (``guardid excite``), captured twice for 60 s from sim://guard:
the default seed (identification) and seed 2 on a second trajectory (validation).
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from guardid.dynamics import build_model
from guardid.estimators import LeastSquares, d_tau
from guardid.identify import HopfieldSettings, IdentifyOptions, identification_rows, identify
from guardid.identify.methods import run_hopfield
from guardid.identify.pipeline import identified_names
from guardid.identify.prepare import prepared_runs
from guardid.identify.runs import load_run, trajectory_highest_harmonic
from guardid.log import read_log
from guardid.robot import load_robot

GUARD = load_robot("guard")


def _cli(*args):
    subprocess.run([sys.executable, "-m", "guardid", *args], check=True, capture_output=True)


@pytest.fixture(scope="module")
def logs(tmp_path_factory, excitation):
    d = tmp_path_factory.mktemp("ident")
    out = {}
    for name, seed, port in (("a", 0, "sim://guard"), ("b", 1, "sim://guard?seed=2")):
        traj = excitation() if seed == 0 else excitation("--seed", seed)  # a: the main job's
        log = d / f"run_{name}.csv"
        _cli("capture", "--trajectory", str(traj), "--duration", "60", "--port", port,
             "--quiet", "-o", str(log))  # fmt: skip
        out[name] = log
    return out


@pytest.fixture(scope="module")
def truth():
    model = build_model(GUARD)
    values = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    return np.array([values[n] for n in identified_names(GUARD)])


def _hh(log):
    return trajectory_highest_harmonic(read_log(log).header.get("trajectory"))


@pytest.fixture(scope="module")
def result(logs):
    return identify([load_run(logs["a"])], GUARD)


def test_offsets_declared_absent_are_not_identified(result):
    assert "Fo1" not in result.names and "Fo2" not in result.names
    # the momentum form's filter: 2 x the excitation's highest harmonic (0.5 Hz), at least 2 Hz
    assert result.conditioning.equation == "momentum"
    assert result.cutoff_hz == pytest.approx(2.0)


@pytest.mark.parametrize("method", ["ls", "wls"])
def test_well_determined_parameters_and_all_within_3_sigma(result, truth, method):
    """At least 8 parameters under 5 % relative std (inertias, gravity, the four friction
    parameters) and every parameter within 3 std of the truth. No fixed percentage bar: a
    parameter at 2-5 % relative std misses 2 % at ordinary 1-3 std scatter on about two
    seeds in three, and even the excitation differs in its last digits with the BLAS thread
    count (a 5 % bar held with one and failed by 0.06 % with the other); the calibration
    over seeds is bench/bench_std_check.py's."""
    r = result.results[method]
    assert (r.rel_std_pct < 5.0).sum() >= 8
    z = (r.theta - truth) / r.std
    assert np.all(np.abs(z) < 3.0), dict(zip(result.names, np.round(z, 2), strict=True))


def test_rls_ends_on_ls(result, logs):
    """RLS (no forgetting) ends on least squares of the same rows; the reported LS removes
    the encoder rounding's noise from its normal equations besides (RLS cannot), which moves
    it by less than its std on this log."""
    from dataclasses import replace

    plain_opts = IdentifyOptions(
        methods=("ls",), conditioning=replace(result.conditioning, quantisation=False)
    )
    plain = identify([load_run(logs["a"])], GUARD, plain_opts).results["ls"].theta  # fmt: skip
    ls, rls = result.results["ls"], result.results["rls"].theta
    assert result.conditioning.quantisation is True
    assert np.max(np.abs(rls - plain) / np.abs(plain)) < 1e-3
    assert np.all(np.abs(ls.theta - plain) < ls.std)


def test_dtau_on_second_run_below_5pct(result, logs):
    run = load_run(logs["b"])
    _, A, y = identification_rows(run.t, run.q, run.current, GUARD, result.conditioning)
    for m in ("ls", "wls"):
        assert d_tau(A, y, result.results[m].theta) < 0.05


def test_motors_r_and_ke_within_3pct(result):
    assert len(result.motors) == 2
    for motor, joint in zip(result.motors, GUARD.joints, strict=True):
        assert motor.resistance == pytest.approx(joint.drive.resistance, rel=0.03)
        assert motor.ke == pytest.approx(joint.drive.ke, rel=0.03)


@pytest.mark.parametrize("beta", [1e-4, 1e-3, 1e-2, 1e-1, 1.0])
def test_hopfield_stable_for_every_beta(logs, truth, beta):
    for log in logs.values():
        run = load_run(log)
        c, A, y = identification_rows(
            run.t, run.q, run.current, GUARD, highest_harmonic_hz=_hh(log)
        )
        dt = float(np.median(np.diff(c.t[c.mask])))
        for nominal in (truth, 0.7 * truth):
            h = run_hopfield(A, y, nominal, beta, dt, passes=3)
            assert np.all(np.isfinite(h.history_)) and np.all(np.isfinite(h.theta_))
            assert np.all(np.abs(h.s_) < 1.0)


def test_hopfield_ends_within_1pct_of_ls(logs, truth):
    """From a wrong prior (0.7 x truth) the network runs over the log, then settles with the
    log's weights: its equilibrium is the LS estimate (inside the box)."""
    run = load_run(logs["a"])
    c, A, y = identification_rows(run.t, run.q, run.current, GUARD, highest_harmonic_hz=0.5)
    dt = float(np.median(np.diff(c.t[c.mask])))
    ls = LeastSquares().fit(A, y)
    h = run_hopfield(A, y, 0.7 * truth, 0.1, dt)
    online = np.array(h.theta_)
    h.settle(A, y)
    big = np.abs(ls.theta_) > 3 * ls.std_  # relative error is meaningless for ~0 values
    assert np.max(np.abs(h.theta_ - ls.theta_)[big] / np.abs(ls.theta_[big])) < 0.01
    assert np.max(np.abs(h.theta_ - ls.theta_) / ls.std_) < 0.01
    # the online pass alone is already in the neighbourhood (a few standard deviations)
    assert np.max(np.abs(online - ls.theta_) / np.maximum(ls.std_, 1e-3 * np.abs(ls.theta_))) < 50


def test_cli_identify_and_validate(logs, tmp_path):
    params = tmp_path / "p.yaml"
    res = subprocess.run([sys.executable, "-m", "guardid", "identify", str(logs["a"]), "-o",
                          str(params)], capture_output=True, text=True, check=True)  # fmt: skip
    assert "cut-off 4 Hz" in res.stdout and "Fo1" not in res.stdout
    res = subprocess.run(
        [sys.executable, "-m", "guardid", "validate", str(logs["b"]), "--params", str(params)],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert "LS" in res.stdout


def test_two_logs_fit_the_motors_on_both(logs, result):
    """Stacked logs: the motor equations of both runs form one fit (no row spans the two
    runs), so R and Ke use every row of both and are at least as certain as from one."""
    runs = [load_run(logs[k]) for k in ("a", "b")]
    ls = IdentifyOptions(methods=("ls",))
    single_b = identify(runs[1:], GUARD, ls).motors
    both = identify(runs, GUARD, ls).motors
    for m, a, b, joint in zip(both, result.motors, single_b, GUARD.joints, strict=True):
        assert m.rows == a.rows + b.rows
        assert m.resistance == pytest.approx(joint.drive.resistance, rel=0.03)
        assert m.ke == pytest.approx(joint.drive.ke, rel=0.03)
        assert m.resistance_std < min(a.resistance_std, b.resistance_std)


def test_hopfield_column_is_the_network_not_least_squares(result, logs):
    """The Hopfield column is the network's own end value; its equilibrium on the whole log
    (which is least squares, checked against numpy's lstsq) is only reported when asked,
    under its own name."""
    hop, ls = result.results["hopfield"], result.results["ls"]
    np.testing.assert_array_equal(hop.theta, hop.settings["online_end"])
    assert "hopfield-eq" not in result.results
    # a fixed-gain network's end value is not the batch optimum (it sits a few std away)
    assert np.max(np.abs(hop.theta - ls.theta) / ls.std) > 0.1
    run = load_run(logs["a"])
    settle = IdentifyOptions(methods=("hopfield",), hopfield=HopfieldSettings(settle=True))
    both = identify([run], GUARD, settle)
    np.testing.assert_array_equal(both.results["hopfield"].theta, hop.theta)
    (fitted,), _, _ = prepared_runs([run], GUARD)  # the currents identify fits
    _, A, y = identification_rows(
        run.t, run.q, fitted.current, GUARD, highest_harmonic_hz=_hh(logs["a"])
    )
    p = A.shape[-1]
    lstsq = np.linalg.lstsq(A.reshape(-1, p), y.reshape(-1), rcond=None)[0]
    assert np.max(np.abs(both.results["hopfield-eq"].theta - lstsq) / ls.std) < 0.01
