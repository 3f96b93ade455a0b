"""Physically consistent identification (guardid.physical), against hand-made truth.

Consistency is checked here by hand (mass > 0, inertia about the COM positive definite,
triangle inequality on its principal moments), and the least-squares references are numpy
lstsq, not guardid's estimators.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner
from realdata import DFKI as REALDATA_DFKI

from guardid.dynamics import build_model
from guardid.identify.pipeline import identified_names
from guardid.physical import (
    description_with,
    fit_consistent,
    link_violations,
    log_cholesky_from_standard,
    pseudo_inertia,
    standard_from_log_cholesky,
)
from guardid.robot import load_robot


def physical(phi) -> bool:
    """Hand check of one link's standard parameters (10,)."""
    m = phi[9]
    if m <= 0:
        return False
    c = phi[6:9] / m
    xx, xy, xz, yy, yz, zz = phi[:6]
    i_c = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) - m * (
        c @ c * np.eye(3) - np.outer(c, c)
    )
    ev = np.linalg.eigvalsh(i_c)
    return ev[0] > 0 and ev[2] < ev[0] + ev[1]


def test_every_log_cholesky_point_is_a_physical_link():
    rng = np.random.default_rng(0)
    for x in rng.normal(0.0, 1.5, (500, 10)):
        phi = standard_from_log_cholesky(x)
        assert physical(phi) and link_violations(phi) == []


def test_round_trip_and_an_unphysical_link_is_caught():
    for robot in ("guard", "planar2"):
        for link in load_robot(robot).links:
            phi = link.standard_parameters()
            back = standard_from_log_cholesky(log_cholesky_from_standard(phi))
            assert np.allclose(back, phi, rtol=0, atol=1e-8 * np.abs(phi).max())
    # a rod-like link whose moments break the triangle inequality (1 + 1 < 3)
    phi = np.array([1.0, 0, 0, 1.0, 0, 3.0, 0, 0, 0, 1.0])
    assert not physical(phi)
    assert np.linalg.eigvalsh(pseudo_inertia(phi))[0] < 0
    assert "triangle" in " ".join(link_violations(phi))


def rows(desc, truth_params, seed, noise=0.01, num=600):
    """Base-regressor rows of random states and torques of ``truth_params`` + noise."""
    model = build_model(desc)
    rng = np.random.default_rng(seed)
    n = desc.n_dof
    q = rng.uniform(-np.pi, np.pi, (num, n))
    qd, qdd = rng.normal(0, 1.0, (num, n)), rng.normal(0, 3.0, (num, n))
    keep = [model.base.names.index(nm) for nm in identified_names(desc)]
    A = model.base_regressor(q, qd, qdd)[:, :, keep]
    tau = model.inverse_dynamics(q, qd, qdd, params=truth_params)
    return A, tau + noise * tau.std(axis=0) * rng.standard_normal(tau.shape)


def test_consistent_truth_gives_ls_and_keeps_unseen_parameters_at_the_yaml():
    desc = load_robot("guard")
    model = build_model(desc)
    truth = model.params.copy()
    truth[model.param_names.index("M2")] *= 1.1  # a heavier payload (still physical)
    truth[model.param_names.index("MX2")] *= 1.1
    A, y = rows(desc, truth, 1)
    A2, y1 = A.reshape(-1, A.shape[2]), y.reshape(-1)
    theta, *_ = np.linalg.lstsq(A2, y1, rcond=None)
    r = y1 - A2 @ theta
    std = np.sqrt(np.diag(np.linalg.inv(A2.T @ A2)) * (r @ r) / (len(y1) - len(theta)))
    fit = fit_consistent(A, y, desc)
    assert np.abs(fit.base - theta).max() <= 0.02 * std.min()
    # parameters in no base combination: the YAML decides them
    k = model.base.K[[model.base.names.index(n) for n in identified_names(desc)]]
    unseen = [i for i in range(len(truth)) if not k[:, i].any()]
    assert {model.param_names[i] for i in unseen} >= {"M1", "MX1", "MZ1"}
    assert np.allclose(fit.standard[unseen], model.params[unseen], rtol=1e-6, atol=1e-9)
    assert all(physical(fit.standard[10 * j : 10 * j + 10]) for j in range(2))


def test_inconsistent_data_give_a_physical_model_no_worse_than_needed():
    """DFKI pendulum whose torques imply a negative rotor inertia and negative viscous
    friction: LS follows them, the consistent fit stays physical (Ia2 and Fv >= 0)."""
    desc = load_robot("dfki_double_pendulum")
    model = build_model(desc)
    truth = model.params.copy()
    truth[model.param_names.index("Ia2")] = -0.004
    truth[model.param_names.index("Fv1")] = -0.05
    A, y = rows(desc, truth, 2, noise=0.001)
    names = list(identified_names(desc))
    theta, *_ = np.linalg.lstsq(A.reshape(-1, A.shape[2]), y.reshape(-1), rcond=None)
    assert theta[names.index("Ia2")] < 0 and theta[names.index("Fv1")] < 0
    fit = fit_consistent(A, y, desc)
    assert fit.violations == ()
    assert fit.value("Ia2") >= 0 and fit.value("Fv1") >= 0 and fit.value("Fv2") >= 0
    assert all(physical(fit.standard[10 * j : 10 * j + 10]) for j in range(2))
    # known-zero parameters are exactly zero (held by the parameterisation)
    for j in (1, 2):
        for s in ("XY", "XZ", "YZ", "MY", "MZ"):
            assert fit.value(f"{s}{j}") == 0.0
    full = description_with(desc, fit.names, fit.standard)
    assert [link.mass > 0 for link in full.links] == [True, True]


def test_description_with_round_trips_the_yaml_parameters():
    for robot in ("guard", "dfki_double_pendulum"):
        desc = load_robot(robot)
        model = build_model(desc)
        again = build_model(description_with(desc, model.param_names, model.params))
        assert np.allclose(again.params, model.params, rtol=1e-12, atol=1e-15)


DATA = REALDATA_DFKI
COLUMNS = "time=time,q1=pos_meas1,q2=pos_meas2,tau1=tau_meas1,tau2=tau_meas2"


def test_cli_identify_consistent_then_export(tmp_path):
    """Real data (DFKI run 00, tests/data/dfki-double-pendulum): identify --consistent
    prints and writes the standard set, export turns it into a URDF."""
    import yaml

    from guardid.cli import main

    log = DATA / "trajectory_00.csv"
    params = tmp_path / "p.yaml"
    args = ["identify", str(log), "--robot", "dfki_double_pendulum", "--columns", COLUMNS]
    args += ["--cutoff", "5", "--parallel-filter", "3", "--method", "ls", "--consistent"]
    res = CliRunner().invoke(main, [*args, "-o", str(params)])
    assert res.exit_code == 0, res.output
    assert "CONSISTENT" in res.output and "every link physically consistent" in res.output
    # the summary line gives each figure a method has, no "nan" for the consistent fit's
    (summary,) = [x for x in res.output.splitlines() if x.startswith("rows ")]
    assert "nan" not in summary.lower() and "stacked error LS " in summary
    data = yaml.safe_load(params.read_text())
    model = build_model(load_robot("dfki_double_pendulum"))
    std = data["consistent"]["standard_parameters"]
    assert [e["name"] for e in std] == model.param_names
    values = dict((e["name"], e["value"]) for e in std)
    phi = np.array(list(values.values()))
    assert all(physical(phi[10 * j : 10 * j + 10]) for j in range(2))
    assert min(values[k] for k in ("Ia1", "Ia2", "Fv1", "Fc1", "Fv2", "Fc2")) >= 0
    assert len(data["methods"]["consistent"]["values"]) == len(data["base_parameters"])
    out = tmp_path / "id.urdf"
    res = CliRunner().invoke(main, ["export", str(params), "--urdf", str(out)])
    assert res.exit_code == 0 and out.is_file()
    back = load_robot(out)
    assert back.links[1].mass == pytest.approx(values["M2"], rel=1e-12)


def test_replace_keeps_frozen_descriptions_intact():
    desc = load_robot("guard")
    model = build_model(desc)
    p = model.params.copy()
    p[model.param_names.index("Ia1")] = 0.25
    new = description_with(desc, model.param_names, p)
    assert new.joints[0].drive.rotor_inertia == pytest.approx(0.25 / 500**2)
    assert desc.joints[0].drive.rotor_inertia == 2.0e-6
    assert replace(new) == new


def test_consistent_fit_refuses_current_units():
    from types import SimpleNamespace

    from guardid.errors import GuardidError
    from guardid.physical.report import add_consistent

    result = SimpleNamespace(torque_unit="A", cutoff_hz=4.0, results={})
    with pytest.raises(GuardidError, match="current units"):
        add_consistent(result, [], load_robot("guard"))
