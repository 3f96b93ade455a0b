"""An identified mass matrix that is not positive definite beyond its own std makes the result
untrusted (guardid.identify.untrusted.indefinite_mass_matrix).

Truth: the guard's Newton-Euler M(q) (``model.mass_matrix`` of the physical parameters, not
the identified base columns the check builds M from) and numpy's eigh; the eigenvalue's std
worked out by hand: with a covariance on ZZ1R alone (variance s^2), whose change moves M by
dM/dZZ1R (taken here as a finite difference of the Newton-Euler M in YY1, ZZ1R's only
physical term of coefficient 1), the smallest eigenvalue's std is s |v^T (dM/dZZ1R) v|.
On the command line: one joint's current under the other's name on a simulated log of the
variant robot.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from badinput_tools import ERROR_PREFIX, invoke
from capturetools import VARIANT
from logedit import swapped

from guardid.dynamics import build_model
from guardid.identify.untrusted import IMPOSSIBLE_STD, indefinite_mass_matrix
from guardid.robot import load_robot

K = 200


@pytest.fixture(scope="module")
def lowered():
    """(model, physical params with YY1 lowered by 0.75 kg m^2, q (K, 2), the base values,
    the index of ZZ1R, numpy's smallest eigenvalue (K,) and the hand std per unit s (K,))."""
    m = build_model(load_robot("guard"))
    names = m.base.names
    k = names.index("ZZ1R")
    yy1 = m.param_names.index("YY1")
    assert m.base.K[k, yy1] == 1.0 and np.count_nonzero(m.base.K[:, yy1]) == 1
    params = np.array(m.params, dtype=float)
    params[yy1] -= 0.75
    q = np.c_[np.linspace(-3, 3, K), np.linspace(-np.pi, np.pi, K)]
    M = m.mass_matrix(q, params)
    lam, vec = np.linalg.eigh(M)
    bumped = params.copy()
    bumped[yy1] += 1e-3
    dM = (m.mass_matrix(q, bumped) - M) / 1e-3  # d M / d ZZ1R (M is linear in it)
    v = vec[:, :, 0]
    per_s = np.abs(np.einsum("ki,kij,kj->k", v, dM, v))
    assert np.sum(lam[:, 0] < 0) > 10 and np.sum(lam[:, 0] > 0) > 10  # indefinite at some rows
    return m, params, q, m.base.values(params), k, lam[:, 0], per_s


def _cov(n: int, k: int, s: float) -> np.ndarray:
    cov = np.zeros((n, n))
    cov[k, k] = s**2
    return cov


def test_flagged_rows_are_those_more_than_3_std_below_zero(lowered):
    """s splits the rows with a negative eigenvalue: the count in the problem is the hand
    count of lambda < -3 s |v^T dM v|, strictly between 0 and all negative rows."""
    m, _, q, theta, k, lam, per_s = lowered
    neg = lam < 0
    ratio = -lam[neg] / (IMPOSSIBLE_STD * per_s[neg])  # flagged when s < ratio
    s = float(np.median(ratio))
    expect = int(np.sum(neg & (lam < -IMPOSSIBLE_STD * s * per_s)))
    assert 0 < expect < int(neg.sum())
    free = list(range(len(theta)))
    (problem,) = indefinite_mass_matrix(m, free, theta, _cov(len(theta), k, s), q)
    assert f"more than 3 std below zero at {expect} of {K} sampled rows" in problem
    z = np.where(neg, lam / (s * per_s), np.inf)
    worst = int(np.argmin(z))
    assert f"smallest eigenvalue is {lam[worst]:.3g} +- {s * per_s[worst]:.2g}" in problem
    assert f"q = ({q[worst, 0]:.3g}, {q[worst, 1]:.3g})" in problem


def test_a_negative_eigenvalue_within_3_std_is_not_a_problem(lowered):
    """s larger than every negative row's |lambda| / (3 |v^T dM v|): nothing flagged."""
    m, _, q, theta, k, lam, per_s = lowered
    neg = lam < 0
    s = 1.01 * float(np.max(-lam[neg] / (IMPOSSIBLE_STD * per_s[neg])))
    free = list(range(len(theta)))
    assert indefinite_mass_matrix(m, free, theta, _cov(len(theta), k, s), q) == []


def test_a_positive_definite_mass_matrix_or_no_covariance_is_not_a_problem(lowered):
    m, _, q, theta, k, _, _ = lowered
    free = list(range(len(theta)))
    nominal = m.base.values(np.array(m.params, dtype=float))
    assert np.linalg.eigvalsh(m.mass_matrix(q, np.array(m.params, float)))[:, 0].min() > 0
    assert indefinite_mass_matrix(m, free, nominal, _cov(len(theta), k, 1e-9), q) == []
    assert indefinite_mass_matrix(m, free, theta, None, q) == []


def test_currents_under_each_others_names_are_refused_by_the_mass_matrix(variant_schroeder_300s,
                                                                         tmp_path):  # fmt: skip
    """The pan's current logged as the tilt's and back: the check of R and Ke against zero
    does not catch it on this robot (R comes out near zero, not below it); the mass matrix
    does (and the motors' disagreement with the description): one line, exit 4, no file;
    with --force the file lists it under ``untrusted``. The intact log passes."""
    out = tmp_path / "p.yaml"
    intact = invoke(
        "identify", variant_schroeder_300s, "--robot", VARIANT, "--method", "wls", "-o", out
    )
    assert intact.exit_code == 0, intact.stderr
    log = tmp_path / "swapped.csv"
    log.write_text(
        swapped(variant_schroeder_300s.read_text(), "i_pan_A", "i_tilt_A", names_too=False)
    )
    bad = tmp_path / "bad.yaml"
    res = invoke("identify", log, "--robot", VARIANT, "--method", "wls", "-o", bad)
    assert res.exit_code == 4, res.stderr
    (line,) = res.stderr.splitlines()
    assert line.startswith(ERROR_PREFIX) and "swapped.csv" in line
    assert "mass matrix M(q) is not positive definite" in line and "std below zero at" in line
    assert "ohm, below zero" not in line and "V s/rad, below zero" not in line  # R, Ke not < 0
    assert not bad.exists()
    res = invoke("identify", log, "--robot", VARIANT, "--method", "wls", "--force", "-o", bad)
    assert res.exit_code == 0, res.stderr
    untrusted = yaml.safe_load(bad.read_text())["untrusted"]
    assert any("mass matrix M(q) is not positive definite" in u for u in untrusted)


def test_real_torques_under_each_others_names_are_refused_without_motor_data(tmp_path):
    """Real data with no motor to check (the DFKI double pendulum's measured torques): run 00
    with tau1 and tau2 mapped to each other's columns is refused by the mass matrix alone
    (exit 4, one line naming it); the intact mapping passes."""
    from realdata import DFKI

    log = DFKI / "trajectory_00.csv"
    base = ("--robot", "dfki_double_pendulum", "--cutoff", "5", "--parallel-filter", "3",
            "--method", "wls")  # fmt: skip
    intact = "time=time,q1=pos_meas1,q2=pos_meas2,tau1=tau_meas1,tau2=tau_meas2"
    swapped_taus = "time=time,q1=pos_meas1,q2=pos_meas2,tau1=tau_meas2,tau2=tau_meas1"
    ok = invoke("identify", log, *base, "--columns", intact, "-o", tmp_path / "ok.yaml")
    assert ok.exit_code == 0, ok.stderr
    out = tmp_path / "bad.yaml"
    res = invoke("identify", log, *base, "--columns", swapped_taus, "-o", out)
    assert res.exit_code == 4, res.stderr
    (line,) = res.stderr.splitlines()
    assert line.startswith(ERROR_PREFIX) and "trajectory_00.csv" in line
    assert "mass matrix M(q) is not positive definite" in line and "motor" not in line
    assert not out.exists()


def test_a_forced_result_carries_its_reasons_to_the_api_and_the_report():
    """identify_logs(force=True) on the swapped real torques: ``untrusted`` holds the mass
    matrix's reason, ``warnings`` leads with it, and the HTML report's verdict says the result
    is not to be trusted (it used to read as an ordinary fit)."""
    from realdata import DFKI

    from guardid.api import identify_logs
    from guardid.report.html import verdict

    res = identify_logs(
        [DFKI / "trajectory_00.csv"], "dfki_double_pendulum", "wls", force=True,
        columns="time=time,q1=pos_meas1,q2=pos_meas2,tau1=tau_meas2,tau2=tau_meas1",
        cutoff_hz=5.0, parallel_filter_hz=3.0,
    )  # fmt: skip
    (why,) = res.untrusted
    assert "mass matrix M(q) is not positive definite" in why
    assert res.warnings[0] == f"cannot be trusted (force=True): {why}"
    sentence, trusted = verdict(res.identification)
    assert not trusted and sentence.startswith("Not to be trusted") and why in sentence
