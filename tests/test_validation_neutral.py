"""Acceptance on measured data (issue 16): leave-one-run-out over the DFKI runs 00-02.

guardid identifies from two runs with its default conditioning (only the robot and the
columns given); a neutral evaluator written here in plain numpy (independent of guardid:
its own resampling, filter, differences and the lab's closed-form regressor) scores the
held-out run for three parameter sets under one and the same conditioning: guardid's, a
plain least-squares fit's (2 ms grid, order-4 zero-phase Butterworth at 5 Hz on positions
and torques, central differences, every sample but one cut-off period at each end, the
lab's model with sign friction) and the lab's published parameters (entered as a
reference values file, docs/examples/dfki_published.reference.yaml). The score is the
stacked relative rms error over both joints, rms(tau - Y theta) / rms(tau).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from realdata import DFKI as REALDATA_DFKI
from scipy.interpolate import interp1d
from scipy.signal import butter, sosfiltfilt

from guardid.cli import main

DATA = REALDATA_DFKI
REFERENCE = (
    Path(__file__).resolve().parents[1] / "docs" / "examples" / "dfki_published.reference.yaml"
)
COLUMNS = "time=time,q1=pos_meas1,q2=pos_meas2,tau1=tau_meas1,tau2=tau_meas2"
G, L1, GR = 9.81, 0.3, 6.0
DT, FC = 0.002, 5.0  # s, Hz: the evaluator's (and the plain fit's) conditioning


def _load(k):
    a = np.genfromtxt(DATA / f"trajectory_{k:02d}.csv", delimiter=",", names=True)
    return a["time"], np.c_[a["pos_meas1"], a["pos_meas2"]], np.c_[a["tau_meas1"], a["tau_meas2"]]


def _condition(k):
    """2 ms grid (linear interpolation), Butterworth 4 at 5 Hz forward-backward on q and tau,
    central differences, one cut-off period dropped at each end."""
    t, q, tau = _load(k)
    grid = np.arange(t[0], t[-1], DT)
    q, tau = interp1d(t, q, axis=0)(grid), interp1d(t, tau, axis=0)(grid)
    sos = butter(4, FC, fs=1 / DT, output="sos")
    q, tau = sosfiltfilt(sos, q, axis=0), sosfiltfilt(sos, tau, axis=0)
    qd = np.gradient(q, DT, axis=0)
    qdd = np.gradient(qd, DT, axis=0)
    n = int(round(1 / FC / DT))
    return q[n:-n], qd[n:-n], qdd[n:-n], tau[n:-n]


def _shape(v, friction):
    model, scale = friction
    return {"sign": np.sign, "tanh": lambda x: np.tanh(x / scale),
            "atan": lambda x: np.arctan(x / scale)}[model](v)  # fmt: skip


def _regressor(q, qd, qdd, friction=("sign", None)):
    """The lab's model (README of the data), columns [I1 + m2 l1^2, m1 r1 + m2 l1, m2 r2, I2,
    Ir, b1, cf1, b2, cf2, offset1, offset2] (N, 2, 11)."""
    y = np.zeros((len(q), 2, 11))
    c2, s2 = np.cos(q[:, 1]), np.sin(q[:, 1])
    s12 = np.sin(q[:, 0] + q[:, 1])
    y[:, 0, 0] = qdd[:, 0]
    y[:, 0, 1] = G * np.sin(q[:, 0])
    coriolis = s2 * (2 * qd[:, 0] * qd[:, 1] + qd[:, 1] ** 2)
    y[:, 0, 2] = L1 * (c2 * (2 * qdd[:, 0] + qdd[:, 1]) - coriolis) + G * s12
    y[:, 1, 2] = L1 * (c2 * qdd[:, 0] + s2 * qd[:, 0] ** 2) + G * s12
    y[:, :, 3] = (qdd[:, 0] + qdd[:, 1])[:, None]
    y[:, 0, 4] = (GR**2 + 1) * qdd[:, 0] - GR * qdd[:, 1]
    y[:, 1, 4] = -GR * qdd[:, 0] + GR**2 * qdd[:, 1]
    y[:, 0, 5], y[:, 0, 6] = qd[:, 0], _shape(qd[:, 0], friction)
    y[:, 1, 7], y[:, 1, 8] = qd[:, 1], _shape(qd[:, 1], friction)
    y[:, 0, 9] = y[:, 1, 10] = 1.0
    return y


def _error(k, theta, friction):
    q, qd, qdd, tau = _condition(k)
    r = tau - _regressor(q, qd, qdd, friction) @ theta
    return float(np.sqrt(np.mean(r**2) / np.mean(tau**2)))


def _lab_theta(b: dict) -> np.ndarray:
    """guardid base parameters -> the lab's (ZZ1R = I1 + m2 l1^2 + gr^2 Ir, Ia2 = gr^2 Ir)."""
    g = lambda n: float(b.get(n, 0.0))  # noqa: E731
    return np.array([g("ZZ1R") - g("Ia2"), g("MX1R"), g("MX2R"), g("ZZ2R"), g("Ia2") / GR**2,
                     g("Fv1"), g("Fc1"), g("Fv2"), g("Fc2"), g("Fo1"), g("Fo2")])  # fmt: skip


def _plain(train):
    ys, ts = [], []
    for k in train:
        q, qd, qdd, tau = _condition(k)
        ys.append(_regressor(q, qd, qdd)[:, :, :9].reshape(-1, 9))
        ts.append(tau.reshape(-1))
    theta = np.linalg.lstsq(np.concatenate(ys), np.concatenate(ts), rcond=None)[0]
    return np.r_[theta, 0.0, 0.0]


def _guardid(train, tmp_path):
    out = tmp_path / f"params_{''.join(map(str, train))}.yaml"
    logs = [str(DATA / f"trajectory_{k:02d}.csv") for k in train]
    args = ["identify", *logs, "--robot", "dfki_double_pendulum", "--columns", COLUMNS,
            "--method", "ls", "-o", str(out)]  # fmt: skip
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    p = yaml.safe_load(out.read_text())
    values = dict(zip([b["name"] for b in p["base_parameters"]], p["methods"]["ls"]["values"],
                      strict=True))  # fmt: skip
    fr = p["robot_description"]["joints"][0]["friction"]  # the model guardid fitted
    return _lab_theta(values), (fr.get("model", "sign"), fr.get("velocity_scale")), out


@pytest.fixture(scope="module")
def folds(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("loo")
    ref = yaml.safe_load(REFERENCE.read_text())
    published = _lab_theta(ref["values"])
    pub_friction = (ref["friction"]["model"], ref["friction"]["velocity_scale"])
    out = []
    for k in range(3):
        train = [j for j in range(3) if j != k]
        ours, friction, params = _guardid(train, tmp)
        out.append({
            "guardid": _error(k, ours, friction),
            "plain": _error(k, _plain(train), ("sign", None)),
            "published": _error(k, published, pub_friction),
            "params": params,
        })  # fmt: skip
    print("\nheld-out run: guardid / plain LS / published (stacked relative rms error)")
    for k, f in enumerate(out):
        print(f"  {k:02d}: {f['guardid']:.4f} / {f['plain']:.4f} / {f['published']:.4f}")
    return out


def test_guardid_no_worse_than_plain_least_squares_on_every_fold(folds):
    for k, f in enumerate(folds):
        assert f["guardid"] <= f["plain"], (k, f)


def test_guardid_within_5_percent_of_the_published_parameters_on_average(folds):
    ours = np.mean([f["guardid"] for f in folds])
    published = np.mean([f["published"] for f in folds])
    assert ours <= 1.05 * published, (ours, published)


def test_validate_scores_params_and_reference_side_by_side(folds):
    """guardid validate ranks the held-out run 02 like the neutral evaluator does."""
    held = str(DATA / "trajectory_02.csv")
    res = CliRunner().invoke(main, ["validate", held, "--params", str(folds[2]["params"]),
                                    "--params", str(REFERENCE), "--columns", COLUMNS])  # fmt: skip
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    ours = next(x for x in lines if ":LS " in x)
    pub = next(x for x in lines if x.strip().startswith("DFKI published") and "%" in x)
    stacked = [float(x.split("%")[0].split()[-1]) for x in (ours, pub)]
    neutral = (folds[2]["guardid"], folds[2]["published"])
    assert (stacked[0] < stacked[1]) == (neutral[0] < neutral[1]), (res.output, neutral)
    assert "the same rows for every parameter set" in res.output


def test_identify_cv_prints_the_leave_one_run_out_table(folds):
    """``identify --cv`` over the three runs: one line per held-out run and the mean; its LS
    figures (guardid's own conditioning) agree with the independent evaluator's to 0.02."""
    logs = [str(DATA / f"trajectory_{k:02d}.csv") for k in range(3)]
    res = CliRunner().invoke(main, ["identify", *logs, "--robot", "dfki_double_pendulum",
                                    "--columns", COLUMNS, "--method", "ls", "--cv"])  # fmt: skip
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    rows = [x for x in lines if "trajectory_0" in x]
    assert len(rows) == 3 and lines[-1].startswith("mean")
    for k, row in enumerate(rows):
        cv = float(row.split()[-1].rstrip("%")) / 100
        assert abs(cv - folds[k]["guardid"]) < 0.02, (row, folds[k])
