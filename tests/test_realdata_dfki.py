"""Real data: the DFKI double pendulum (design A.0), conditioning + least squares.

The model check and the identification (real runs in tests/data/dfki-double-pendulum).
Published values: tests/data/dfki-double-pendulum/published_parameters_design_A.0_model_2.0.yml
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from realdata import DFKI as REALDATA_DFKI

from guardid.conditioning import condition, parallel_filter
from guardid.dynamics import build_model
from guardid.robot import load_robot

DATA = REALDATA_DFKI
PUB = dict(
    m1=0.5593806151425046, m2=0.6043459469186889, r1=0.3, r2=0.18377686083653508,
    I1=0.053470810264216295, I2=0.02392374528789766, Ir=7.659297952841183e-05,
    b1=0.001, b2=0.001, cf1=0.093, cf2=0.078, g=9.81, gr=6.0, l1=0.3,
)  # fmt: skip
# The README's four base parameters: I1 + m2 l1^2, m1 r1 + m2 l1, m2 r2, I2.
PUB4 = np.array([0.1079, 0.3491, 0.1111, 0.02392])
NAMES4 = ("I1 + m2 l1^2", "m1 r1 + m2 l1", "m2 r2", "I2")
Q_CUTOFF_HZ = 5.0  # position filter (README: 5 Hz matters)
PARALLEL_CUTOFF_HZ = 3.0  # regressor/torque filter: ~ the positions' 99.5 % energy band


def lab_torque(q, qd, qdd, p=PUB, friction="atan"):
    """The lab's closed-form model (README), implemented independently of guardid.dynamics."""
    m1, m2, r1, r2, i1, i2, ir, g, gr, l1 = (p[k] for k in "m1 m2 r1 r2 I1 I2 Ir g gr l1".split())
    c2, s2 = np.cos(q[:, 1]), np.sin(q[:, 1])
    m11 = i1 + i2 + m2 * l1**2 + 2 * m2 * l1 * r2 * c2 + (gr**2 + 1) * ir
    m12 = i2 + m2 * l1 * r2 * c2 - gr * ir
    m22 = i2 + gr**2 * ir
    h1 = -m2 * l1 * r2 * s2 * (2 * qd[:, 0] * qd[:, 1] + qd[:, 1] ** 2)
    h2 = m2 * l1 * r2 * s2 * qd[:, 0] ** 2
    g12 = m2 * r2 * g * np.sin(q[:, 0] + q[:, 1])
    g1 = (m1 * r1 + m2 * l1) * g * np.sin(q[:, 0]) + g12
    fr = {
        "atan": lambda v: np.arctan(100 * v),
        "tanh": lambda v: np.tanh(v / 0.01),  # the shipped YAML's smooth Coulomb shape
        "sign": np.sign,
    }[friction]
    t1 = m11 * qdd[:, 0] + m12 * qdd[:, 1] + h1 + g1 + p["b1"] * qd[:, 0] + p["cf1"] * fr(qd[:, 0])
    t2 = m12 * qdd[:, 0] + m22 * qdd[:, 1] + h2 + g12 + p["b2"] * qd[:, 1] + p["cf2"] * fr(qd[:, 1])
    return np.column_stack([t1, t2])


@pytest.fixture(scope="module")
def model():
    return build_model(
        load_robot(Path(__file__).parents[1] / "guardid/robots/dfki_double_pendulum.yaml")
    )


def regressor_with_rotor(model, q, qd, qdd):
    """Base regressor (N, 2, b): the YAML's mechanical-only rotors (``rotor``, the elbow's
    coupled: -1) give the lab's 37 Ir, -6 Ir, 36 Ir in M11, M12, M22 exactly; base
    parameters ZZ1R = I1 + m2 l1^2 + Ia1, ZZ2R = I2, Ia2 = 36 Ir (Ia1 = 36 Ir grouped)."""
    return model.base_regressor(q, qd, qdd)


def to_lab(model, theta):
    """The README's four base parameters (and Ir) from our base parameters; the two motors
    are alike (the lab's one Ir), so Ia1 = Ia2."""
    b = dict(zip(model.base.names, theta, strict=True))
    ir = b["Ia2"] / 36.0
    return np.array([b["ZZ1R"] - b["Ia2"], b["MX1R"], b["MX2R"], b["ZZ2R"]]), ir


def d_tau(tau, pred):
    """DESIGN.md section 5 (as guardid.estimators.metrics.d_tau): mean over joints of
    ||tau_j - pred_j|| / ||tau_j||, norms over the samples."""
    return float(np.mean(np.linalg.norm(tau - pred, axis=0) / np.linalg.norm(tau, axis=0)))


def test_yaml_reproduces_closed_form_model(model):
    rng = np.random.default_rng(7)
    q = rng.uniform(-np.pi, np.pi, (200, 2))
    qd, qdd = rng.normal(0, 3, (200, 2)), rng.normal(0, 20, (200, 2))
    ours = model.inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(ours, lab_torque(q, qd, qdd, PUB, "tanh"), atol=1e-12)
    # the base regressor reproduces the full closed form (Ir included) exactly
    ir = PUB["Ir"]
    theta = model.base.values(model.params)
    pred = regressor_with_rotor(model, q, qd, qdd) @ theta
    np.testing.assert_allclose(pred, lab_torque(q, qd, qdd, PUB, "tanh"), atol=1e-12)
    lab4, ir_back = to_lab(model, theta)
    np.testing.assert_allclose(lab4, PUB4, rtol=1e-3)
    assert ir_back == pytest.approx(ir)


def _runs():
    pub = yaml.safe_load((DATA / "published_parameters_design_A.0_model_2.0.yml").read_text())
    for k, v in PUB.items():
        assert pub[k] == pytest.approx(v)
    out = []
    for i in range(3):
        data = np.genfromtxt(DATA / f"trajectory_0{i}.csv", delimiter=",", names=True)
        q = np.column_stack([data["pos_meas1"], data["pos_meas2"]])
        tau = np.column_stack([data["tau_meas1"], data["tau_meas2"]])
        out.append((data["time"], q, tau))
    return out


def _prepare(model, t, q, tau):
    """Condition (5 Hz), regressor, then parallel filter (3 Hz) + decimation, stiction rows out."""
    c = condition(t, q, tau, cutoff_hz=Q_CUTOFF_HZ, decimate=1, align_period_mean=False, gain=1.0)
    fs = 1.0 / (c.t[1] - c.t[0])
    y = regressor_with_rotor(model, c.q, c.qd, c.qdd)
    lab = lab_torque(c.q, c.qd, c.qdd)
    _, (y, tau_f, lab, keep) = parallel_filter(fs, PARALLEL_CUTOFF_HZ, y, c.tau, lab, c.mask)
    return y[keep], tau_f[keep], lab[keep]


def _lstsq(prepared):
    a = np.concatenate([p[0] for p in prepared])
    y = np.concatenate([p[1] for p in prepared])
    theta, *_ = np.linalg.lstsq(a.reshape(-1, a.shape[2]), y.reshape(-1), rcond=None)
    return theta


def test_dfki_least_squares(model):
    prepared = [_prepare(model, *run) for run in _runs()]
    report = []
    for label, train in (("runs 00+01+02", (0, 1, 2)), ("runs 00+01", (0, 1))):
        lab4, ir = to_lab(model, _lstsq([prepared[i] for i in train]))
        err = 100 * (lab4 - PUB4) / PUB4
        report.append(f"LS on {label}: " + ", ".join(
            f"{n} = {v:.4f} ({e:+.1f} %)" for n, v, e in zip(NAMES4, lab4, err, strict=True)
        ) + f", Ir = {ir:.3g}")  # fmt: skip
        assert np.all(np.abs(err) < 10.0), report[-1]
    # fit on 00 + 01, predict the held-out run 02
    theta = _lstsq(prepared[:2])
    y, tau, lab = prepared[2]
    ours, published = d_tau(tau, y @ theta), d_tau(tau, lab)
    report.append(f"held-out run 02: d_tau ours {ours:.3f}, published {published:.3f}")
    print("\n".join(report))
    assert ours <= published
