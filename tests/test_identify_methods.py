"""Estimators registered by name: a new method is one registered class, no list to edit.

The registered test estimator is numpy's least squares with its covariance written out
(s^2 (A^T A)^-1, an implementation independent of guardid's QR), fitted on a prismatic
axis whose force is worked out by hand (m qdd + m g + Fv qd + Fc sign(qd), noise added).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml
from test_foreign_logs import AXIS_YAML, cli, jittered_time, sines, write_csv

from guardid.conditioning.options import ConditioningOptions
from guardid.identify import (
    HopfieldSettings,
    IdentifyOptions,
    Method,
    MethodFit,
    identify,
    method_names,
    methods,
    register,
    run_from_arrays,
)
from guardid.robot.loader import parse_robot

MASS, G, FV, FC = 2.5, 9.81, 3.0, 1.5  # kg, m/s^2, N s/m, N (AXIS_YAML's values)
COLUMNS = "time=seconds,q1=z_m,tau1=force_N"


@pytest.fixture
def registry(monkeypatch):
    """The registry as it is; what a test registers is gone after it."""
    monkeypatch.setattr(methods, "_REGISTRY", dict(methods._REGISTRY))


@pytest.fixture(scope="module")
def lift(tmp_path_factory):
    """(robot YAML path, log path, (t, q, force)): 17 s of the axis at 500 Hz, force noise
    0.05 N (1 sigma)."""
    d = tmp_path_factory.mktemp("lift")
    robot = d / "lift.yaml"
    robot.write_text(AXIS_YAML)
    t = jittered_time(8700, 0.002, seed=3)
    q, qd, qdd = sines(t, [0.15, 0.06, 0.02], [0.4, 1.1, 2.3], [0.0, 1.0, 2.0])  # m
    force = MASS * qdd + MASS * G + FV * qd + FC * np.sign(qd)
    force += np.random.default_rng(5).normal(0.0, 0.05, len(t))
    log = d / "lift.csv"
    write_csv(log, ["seconds", "z_m", "force_N"], [t, q, force])
    return robot, log, (t, q[:, None], force[:, None])


def _numpy_lstsq():
    class NumpyLstsq(Method):
        summary = "numpy's least squares, for the test"

        def fit(self, rows):
            A = rows.A.reshape(-1, rows.A.shape[-1])
            y = rows.y.reshape(-1)
            theta, rss, *_ = np.linalg.lstsq(A, y, rcond=None)
            s2 = float(rss[0]) / (len(y) - len(theta))
            return MethodFit(theta, cov=s2 * np.linalg.inv(A.T @ A))

    return NumpyLstsq


def test_a_registered_estimator_is_in_the_help_and_in_params_yaml(registry, lift, tmp_path):
    robot, log, _ = lift
    register("numpy-lstsq")(_numpy_lstsq())
    assert "numpy-lstsq" in method_names()
    shown = " ".join(cli("identify", "--help").output.split())
    assert "numpy-lstsq (numpy's least squares, for the test)" in shown
    assert "bls (bounded: WLS with friction and rotor inertia kept >= 0)" in shown
    out = tmp_path / "p.yaml"
    res = cli("identify", log, "--robot", robot, "--columns", COLUMNS, "--cutoff", "60",
              "--method", "ls,numpy-lstsq", "-o", out)  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "NUMPY-LSTSQ" in res.output  # in the table
    p = yaml.safe_load(out.read_text())
    names = [b["name"] for b in p["base_parameters"]]
    mine, ls = p["methods"]["numpy-lstsq"], p["methods"]["ls"]
    np.testing.assert_allclose(mine["values"], ls["values"], rtol=1e-9)
    np.testing.assert_allclose(mine["std"], ls["std"], rtol=1e-6)  # sqrt(diag(cov))
    got = dict(zip(names, mine["values"], strict=True))
    assert got["M1"] == pytest.approx(MASS, rel=0.01)
    assert got["Fv1"] == pytest.approx(FV, rel=0.02)


def test_an_unknown_method_is_one_line_naming_the_registered_ones(registry, lift):
    robot, log, _ = lift
    register("numpy-lstsq")(_numpy_lstsq())
    res = cli("identify", log, "--robot", robot, "--columns", COLUMNS, "--method", "ls,nope")
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("guardid: error: --method: unknown nope")
    assert "numpy-lstsq" in lines[0] and "didim" in lines[0]


def test_extra_results_notes_and_settings_reach_the_identification(registry, lift):
    _, _, (t, q, force) = lift

    @register("halves")
    class Halves(Method):
        def fit(self, rows):
            full = rows.ls.theta_
            return MethodFit(full / 2, settings={"factor": 0.5}, notes=["halves: a test"],
                             extra={"quarters": MethodFit(full / 4)})  # fmt: skip

    desc = parse_robot(yaml.safe_load(AXIS_YAML), "lift.yaml")
    at_60 = ConditioningOptions(cutoff_hz=60.0)
    options = IdentifyOptions(methods=("halves", "ls"), conditioning=at_60)
    r = identify([run_from_arrays(t, q, force, torque=True)], desc, options)
    assert list(r.results) == ["halves", "quarters", "ls"]
    ls = r.results["ls"].theta
    np.testing.assert_array_equal(r.results["halves"].theta, ls / 2)
    np.testing.assert_array_equal(r.results["quarters"].theta, ls / 4)
    assert r.results["halves"].std is None and r.results["halves"].settings == {"factor": 0.5}
    assert "halves: a test" in r.warnings
    # the fit's error: rms(y - A theta) / rms(y) with half the estimate is about 1/2
    assert r.results["halves"].d_stacked == pytest.approx(0.5, abs=0.01)


def test_method_fit_derives_std_and_relative_std_from_the_covariance():
    fit = MethodFit([2.0, -6.0], cov=np.array([[4.0, 1.0], [1.0, 9.0]]))
    np.testing.assert_allclose(fit.std, [2.0, 3.0])
    np.testing.assert_allclose(fit.rel_std_pct, [100.0, 50.0])
    assert MethodFit([1.0]).std is None


def test_a_taken_name_is_refused(registry):
    with pytest.raises(ValueError, match="'ls' is already registered"):
        register("ls")(_numpy_lstsq())


def test_options_are_immutable_values():
    o = IdentifyOptions(methods=["ls"], hopfield=HopfieldSettings(nominal=np.array([1.0, 2.0])))
    assert o.methods == ("ls",) and o.hopfield.nominal == (1.0, 2.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.rls_lambda = 0.5
    assert IdentifyOptions() == IdentifyOptions()
    assert IdentifyOptions(methods="ls, wls").methods == ("ls", "wls")  # not ('l', 's', ...)


def test_the_rows_are_made_in_the_form_every_method_asks_for(registry, gap_guard_captures):
    """A guardid log's default form is the momentum form; a method that fits only in the
    acceleration form (as iv and didim do), asked for alone, gets rows in that form (and the
    params file says so); beside a method without a form of its own, the momentum form
    stays."""
    from guardid.identify import load_run
    from guardid.robot import load_robot

    class AccelerationOnly(Method):
        summary = "least squares in the acceleration form, for the test"
        equation = "acceleration"

        def fit(self, rows):
            return MethodFit.of(rows.ls)

    register("accel-only")(AccelerationOnly)
    runs, guard = [load_run(gap_guard_captures[1])], load_robot("guard")

    def form(*names):
        return identify(runs, guard, IdentifyOptions(methods=names)).conditioning.equation

    assert form("ls") == "momentum"
    assert form("accel-only") == "acceleration"
    assert form("ls", "accel-only") == "momentum"
