"""Promises that no other test defended (issue 15, "What was seen", last bullet), each
checked against numbers worked out by hand or by an independent computation:

* the reflected rotor inertia is N^2 J_rotor in the dynamics the identification uses (mass
  matrix, torques, the base parameters it estimates) and in the simulated plant;
* a FAULT the firmware emulator sends during a capture reaches the log's footer;
* LS standard deviations are sqrt(diag(sigma^2 (A^T A)^-1)), sigma^2 = ||r||^2 / (M - p).
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from guardid.capture import capture
from guardid.dynamics import build_model
from guardid.estimators import LeastSquares
from guardid.excitation.presets import seeded_fourier
from guardid.link import Session, open_port
from guardid.log import read_log
from guardid.plant import Plant
from guardid.protocol import ENUMS
from guardid.robot import load_robot, parse_robot, shipped_path

GUARD_YAML = yaml.safe_load(shipped_path("guard").read_text())


# ---------------------------------------------------------------- reflected rotor inertia
def _guard_without_rotors():
    raw = yaml.safe_load(shipped_path("guard").read_text())
    for joint in raw["joints"]:
        joint["drive"]["rotor_inertia"] = 0.0
    return parse_robot(raw, "guard-without-rotors.yaml")


def test_reflected_rotor_inertia_is_n_squared_j_rotor():
    """By hand from the guard YAML: pan N = 500, J = 2e-6 kg m^2 -> 500^2 * 2e-6 = 0.5 kg m^2;
    tilt N = 1000 -> 1000^2 * 2e-6 = 2.0 kg m^2. Removing the rotors from the YAML must
    take exactly these off M(q)'s diagonal, off the inverse-dynamics torques (0.5 qdd1,
    2.0 qdd2), off the base parameters identify estimates (ZZ1R, ZZ2R) and off the plant's
    mass matrix."""
    drives = [j["drive"] for j in GUARD_YAML["joints"]]
    assert [d["gear_ratio"] for d in drives] == [500, 1000]
    assert [d["rotor_inertia"] for d in drives] == [2.0e-6, 2.0e-6]
    reflected = np.array([0.5, 2.0])  # [kg m^2], worked out above

    guard, bare = load_robot("guard"), _guard_without_rotors()
    with_rotor, without = build_model(guard), build_model(bare)
    rng = np.random.default_rng(0)
    q = rng.uniform([-3.0, -0.17], [3.0, 0.6], (5, 2))
    qd, qdd = rng.normal(size=(5, 2)), rng.normal(size=(5, 2))
    dm = with_rotor.mass_matrix(q) - without.mass_matrix(q)
    np.testing.assert_allclose(dm, np.broadcast_to(np.diag(reflected), dm.shape), atol=1e-12)
    dtau = with_rotor.inverse_dynamics(q, qd, qdd) - without.inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(dtau, qdd * reflected, atol=1e-12)
    y = with_rotor.regressor(q, qd, qdd) @ with_rotor.params
    np.testing.assert_allclose(y, with_rotor.inverse_dynamics(q, qd, qdd), atol=1e-12)

    base = dict(zip(with_rotor.base.names, with_rotor.base.values(with_rotor.params), strict=True))
    bare_base = dict(zip(without.base.names, without.base.values(without.params), strict=True))
    moved = {k: base[k] - bare_base[k] for k in base if abs(base[k] - bare_base[k]) > 1e-12}
    assert moved == pytest.approx({"ZZ1R": 0.5, "ZZ2R": 2.0}, abs=1e-12)

    # the simulated robot integrates the same mass matrix (m11, m12, m22 of its evaluator)
    opts = {"noise": False, "friction": False, "limits": False, "open_circuit": True}
    plant, bare_plant = Plant(guard, **opts), Plant(bare, **opts)
    for q1, q2 in q:
        m = np.subtract(plant._dyn(q1, q2, 0.0, 0.0)[:3], bare_plant._dyn(q1, q2, 0.0, 0.0)[:3])
        np.testing.assert_allclose(m, [reflected[0], 0.0, reflected[1]], atol=1e-9)


# ---------------------------------------------------------------- firmware faults -> footer
def test_a_firmware_fault_during_a_capture_reaches_the_footer(tmp_path):
    """The host goes silent for 0.4 s of robot time at row 100 (the lock-step robot runs on
    while the host works on that row): the firmware's 0.25 s watchdog trips, it sends
    FAULT(watchdog) with the silence it measured, and the log's footer lists that fault."""
    guard = load_robot("guard")
    traj = seeded_fourier(build_model(guard), guard, 3, 0.5, np.zeros(2), 0, 0.05)
    port = open_port("sim://guard?seed=3")
    ticks = []

    def on_row(t, q, v, i):
        ticks.append(port.engine.ticks)
        if len(ticks) == 100:
            port.engine.advance_to(port.engine.now_ns + 400_000_000)

    log = tmp_path / "fault.csv"
    try:
        session = Session(port)
        session.handshake()
        capture(session, guard, traj, 3.0, log, {"robot": "guard"}, on_row=on_row)
    finally:
        port.close()
    footer = read_log(log).footer
    assert footer is not None and len(footer["faults"]) == 1, footer
    tick, code, joint, detail = footer["faults"][0]
    assert code == ENUMS["fault"]["watchdog"] and joint == 0xFF
    # silent since the host's last write (before row 100's callback): 250 ms = 16.7 ticks
    assert ticks[99] + 16 <= tick <= ticks[99] + 17 and 250 <= detail < 270


# ---------------------------------------------------------------- LS standard deviation
def test_ls_std_by_hand_on_a_line_fit():
    """y = a + b x at x = 0..3, y = 1, 2, 2, 4. By hand: A^T A = [[4, 6], [6, 14]],
    det 20, A^T y = (9, 18) -> a = b = 0.9; r = (0.1, 0.2, -0.7, 0.4), ||r||^2 = 0.70,
    sigma^2 = 0.70 / (4 - 2) = 0.35; var a = 0.35 * 14 / 20 = 0.245, var b = 0.35 * 4 / 20 =
    0.07."""
    A = np.array([[1.0, 0.0], [1.0, 1.0], [1.0, 2.0], [1.0, 3.0]])
    y = np.array([1.0, 2.0, 2.0, 4.0])
    est = LeastSquares().fit(A, y)
    np.testing.assert_allclose(est.theta_, [0.9, 0.9], rtol=1e-12)
    assert est.sigma2_ == pytest.approx(0.35, rel=1e-12)
    np.testing.assert_allclose(est.std_, np.sqrt([0.245, 0.07]), rtol=1e-12)
    np.testing.assert_allclose(est.cov_, 0.35 / 20 * np.array([[14, -6], [-6, 4]]), rtol=1e-12)
    np.testing.assert_allclose(est.rel_std_, 100 * np.sqrt([0.245, 0.07]) / 0.9, rtol=1e-12)


def test_ls_std_counts_every_row_of_a_multi_output_regressor():
    """(N, n_out, p) blocks: the degrees of freedom are N * n_out - p (rows, not samples);
    reference: normal equations and an explicit inverse in numpy (the estimator uses QR)."""
    rng = np.random.default_rng(7)
    A = rng.normal(size=(9, 2, 3))
    y = A @ np.array([1.0, -2.0, 0.5]) + 0.1 * rng.normal(size=(9, 2))
    est = LeastSquares().fit(A, y)
    M = A.reshape(18, 3)
    ata_inv = np.linalg.inv(M.T @ M)
    theta = ata_inv @ M.T @ y.reshape(18)
    r = y.reshape(18) - M @ theta
    sigma2 = r @ r / (18 - 3)
    np.testing.assert_allclose(est.theta_, theta, rtol=1e-10)
    np.testing.assert_allclose(est.std_, np.sqrt(sigma2 * np.diag(ata_inv)), rtol=1e-10)
    # the same rows fed one sample at a time give the same statistics
    online = LeastSquares()
    for k in range(9):
        online.update(A[k], y[k])
    np.testing.assert_allclose(online.std_, est.std_, rtol=1e-9)
