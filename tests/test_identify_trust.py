"""Friction models, physically impossible values, bounded fits, not-converged marking,
measured velocities and prismatic units (issue 16, items 4-6)."""

from __future__ import annotations

import numpy as np
import pytest
import synthetic
import yaml
from click.testing import CliRunner
from test_foreign_logs import AXIS_YAML, jittered_time, sines, write_csv

from guardid.cli import main
from guardid.dynamics import build_model
from guardid.errors import ConfigError
from guardid.identify import IdentifyOptions, identify, run_from_arrays
from guardid.identify.pipeline import MethodResult
from guardid.identify.trust import impossible_values, mark_not_converged, mass_matrix_along
from guardid.robot import load_robot
from guardid.robot.loader import parse_robot


def _axis(friction: dict):
    data = yaml.safe_load(AXIS_YAML)
    data["joints"][0]["friction"] = friction
    return parse_robot(data, "axis.yaml")


def test_friction_model_keys_are_validated():
    with pytest.raises(ConfigError, match=r"axis.yaml: joints\[0\].friction.velocity_scale: req"):
        _axis({"viscous": 1, "coulomb": 1, "model": "tanh"})
    with pytest.raises(ConfigError, match=r"friction.model: expected one of"):
        _axis({"viscous": 1, "coulomb": 1, "model": "cubic"})
    with pytest.raises(ConfigError, match=r"friction.velocity_scale: only with"):
        _axis({"viscous": 1, "coulomb": 1, "velocity_scale": 0.1})


@pytest.mark.parametrize(
    "model,shape",
    [("tanh", lambda v: np.tanh(v / 0.2)), ("atan", lambda v: np.arctan(v / 0.2)),
     ("sign", np.sign)],
)  # fmt: skip
def test_coulomb_column_is_the_models_shape(model, shape):
    f = {"viscous": 3.0, "coulomb": 1.5, "model": model}
    if model != "sign":
        f["velocity_scale"] = 0.2
    m = build_model(_axis(f))
    v = np.linspace(-1, 1, 41)[:, None]
    y = m.regressor(np.zeros_like(v), v, np.zeros_like(v))
    k = m.param_names.index("Fc1")
    np.testing.assert_allclose(y[:, 0, k], shape(v[:, 0]), atol=1e-15)


def test_stribeck_adds_its_column():
    f = {"viscous": 3.0, "coulomb": 1.5, "model": "stribeck", "velocity_scale": 0.01,
         "stribeck": 0.5, "stribeck_velocity": 0.1}  # fmt: skip
    m = build_model(_axis(f))
    v = np.array([[-0.2], [0.05], [0.3]])
    y = m.regressor(np.zeros_like(v), v, np.zeros_like(v))
    k = m.param_names.index("Fs1")
    np.testing.assert_allclose(
        y[:, 0, k], np.exp(-((v[:, 0] / 0.1) ** 2)) * np.tanh(v[:, 0] / 0.01)
    )
    tau = m.inverse_dynamics(np.zeros_like(v), v, np.zeros_like(v))
    at_rest = m.inverse_dynamics([[0.0]], [[0.0]], [[0.0]])[0, 0]  # m g on the lift
    by_hand = 3.0 * 0.05 + 1.5 * np.tanh(5.0) + 0.5 * np.exp(-0.25) * np.tanh(5.0)
    assert tau[1, 0] - at_rest == pytest.approx(by_hand, rel=1e-12)


def test_smooth_model_keeps_rows_near_zero_velocity_and_sign_drops_them():
    t, q, tau = synthetic.log(500, 0.2, 2.0, 4, duration_s=20.0)
    run, ls = [run_from_arrays(t, q, tau, torque=True)], IdentifyOptions(methods=("ls",))
    smooth = identify(run, load_robot("dfki_double_pendulum"), ls)
    path = load_robot("dfki_double_pendulum").source
    data = yaml.safe_load(open(path, encoding="utf-8"))
    for j in data["joints"]:
        j["friction"] = {"viscous": 0.001, "coulomb": 0.09, "offset": None}
    sign = identify(run, parse_robot(data, "sign.yaml"), ls)
    assert "near zero velocity" not in smooth.rows_summary
    assert "near zero velocity" in sign.rows_summary


def _negative_friction_log():
    """Pendulum data whose first joint has *negative* viscous friction (impossible)."""
    saved = dict(synthetic.P)
    synthetic.P["b1"] = -0.05
    try:
        return synthetic.log(500, 0.5, 5.0, 5, duration_s=20.0)
    finally:
        synthetic.P.update(saved)


def test_negative_friction_is_flagged_and_bls_keeps_it_feasible():
    t, q, tau = _negative_friction_log()
    r = identify([run_from_arrays(t, q, tau, torque=True)], load_robot("dfki_double_pendulum"),
                 IdentifyOptions(methods=("ls", "bls")))  # fmt: skip
    k = r.names.index("Fv1")
    assert r.results["ls"].theta[k] < 0
    assert any(w.startswith("Fv1 = ") and "physically impossible" in w for w in r.warnings)
    bls = r.results["bls"].theta
    lower = [i for i, n in enumerate(r.names) if n.startswith(("Fv", "Fc", "Ia"))]
    assert np.all(bls[lower] >= 0) and bls[k] == 0.0


def _bounded_ls_by_active_sets(A, y, bounded):
    """min ||A x - y|| subject to x[bounded] >= 0, by trying every set of bounds held at 0
    (numpy lstsq on the other columns; the feasible solution of least residual)."""
    best, best_rss = None, np.inf
    for mask in range(2 ** len(bounded)):
        held = [b for i, b in enumerate(bounded) if mask >> i & 1]
        free = [k for k in range(A.shape[1]) if k not in held]
        x = np.zeros(A.shape[1])
        x[free] = np.linalg.lstsq(A[:, free], y, rcond=None)[0]
        rss = float(np.sum((A @ x - y) ** 2))
        if np.all(x[bounded] >= -1e-12) and rss < best_rss:
            best, best_rss = x, rss
    return best


def test_bls_is_the_bounded_least_squares_with_wls_std():
    """One output with white noise: WLS's covariance is s^2 (A^T A)^-1, so the nearest
    point inside the bounds in its metric is the bounded least-squares solution, found here
    by enumerating the active sets. The std is WLS's (the old BLS's formula at the bounded
    solution gave a std 2-5x too small on the guard's momentum rows)."""
    from guardid.estimators import WeightedLeastSquares
    from guardid.identify.trust import BoundedLeastSquares

    rng = np.random.default_rng(8)
    A = rng.normal(size=(400, 4)) + 0.6 * rng.normal(size=(400, 1))  # correlated columns
    truth = np.array([1.0, 0.0, 0.02, -0.5])  # 1, 2 bounded at 0 (friction-like)
    y = A @ truth + 0.3 * rng.normal(size=400)
    lower = np.array([-np.inf, 0.0, 0.0, -np.inf])
    wls = WeightedLeastSquares().fit(A, y)
    assert np.all(wls.theta_[1:3] < 0)  # the case: the unbounded fit breaks both bounds
    bls = BoundedLeastSquares(lower).fit(A, y)
    want = _bounded_ls_by_active_sets(A, y, [1, 2])
    np.testing.assert_allclose(bls.theta_, want, atol=1e-9)
    assert bls.active_.tolist() == [False, *(want[1:3] == 0.0), False] and bls.active_[1]
    np.testing.assert_allclose(bls.std_, np.sqrt(np.diag(wls.cov_)), rtol=1e-12)


def test_bls_without_a_metric_clips_at_the_bounds():
    """A covariance that is not finite (an error model the rows are too few for), a zero
    covariance (an exact fit) or an estimate with a NaN gives no metric: the estimate is
    clipped at the bounds, the other parameters kept, no exception."""
    from guardid.identify.trust import _nearest_inside

    theta, lower = np.array([1.0, -0.2, 0.3]), np.array([-np.inf, 0.0, 0.0])
    for cov in (np.full((3, 3), np.nan), np.zeros((3, 3))):
        np.testing.assert_array_equal(_nearest_inside(theta, cov, lower), [1.0, 0.0, 0.3])
    got = _nearest_inside(np.array([np.nan, -0.2, 0.3]), np.eye(3), lower)
    np.testing.assert_array_equal(got[1:], [0.0, 0.3])


def test_bls_projection_with_scales_decades_apart():
    """Parameters whose std differ by 8 decades, two of them correlated (0.9): the bounded
    point is found by hand. Holding x3 at its bound 0 from -0.5 moves x2 by the regression
    of x2 on x3, 0.9 x (1e-4 / 1) x 0.5 = +4.5e-5, and x1 (uncorrelated) not at all."""
    from guardid.identify.trust import _nearest_inside

    s = np.array([1e4, 1e-4, 1.0])
    corr = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.9], [0.0, 0.9, 1.0]])
    cov = corr * np.outer(s, s)
    theta = np.array([3.0, 5.0, -0.5])
    got = _nearest_inside(theta, cov, np.array([-np.inf, -np.inf, 0.0]))
    want = np.array([3.0, 5.0 + 0.9 * 1e-4 * 0.5, 0.0])
    assert np.all(np.abs(got - want) / s < 1e-9), (got - want) / s  # in each one's std


def test_bls_projection_holds_a_direction_with_no_variance():
    """x1 - x2 known exactly (a singular covariance: the variance of x1 - x2 is 0): moving
    x2 up to its bound 0 takes x1 along, by the same amount (an earlier version, which
    dropped the direction without variance, gave [0.75, 0.75]: x2 not even at its bound)."""
    from guardid.identify.trust import _nearest_inside

    cov = np.array([[1.0, 1.0], [1.0, 1.0]])  # x1 and x2 move together
    got = _nearest_inside(np.array([2.0, -0.5]), cov, np.array([-np.inf, 0.0]))
    np.testing.assert_allclose(got, [2.5, 0.0], atol=1e-5)


def test_bls_inside_its_bounds_is_wls_with_its_error_model(gap_guard_captures):
    """On a guard capture every friction parameter is well above 0: BLS is the verdict's
    WLS, estimate and std (the rows' correlated errors and the encoder's rounding counted)."""
    from guardid.identify.runs import load_run

    run = load_run(gap_guard_captures[1])
    r = identify([run], load_robot("guard"), IdentifyOptions(methods=("wls", "bls")))
    wls, bls = r.results["wls"], r.results["bls"]
    np.testing.assert_allclose(bls.theta, wls.theta, rtol=1e-12)
    np.testing.assert_allclose(bls.std, wls.std, rtol=1e-12)


def test_mass_matrix_from_base_parameters_matches_newton_euler_and_is_checked():
    d = load_robot("dfki_double_pendulum")
    m = build_model(d)
    free = list(range(len(m.base.names)))
    q = np.random.default_rng(1).uniform(-3, 3, (50, 2))
    theta = m.base.values(m.params)
    np.testing.assert_allclose(mass_matrix_along(m, free, theta, q), m.mass_matrix(q), atol=1e-12)
    bad = theta.copy()
    bad[m.base.names.index("ZZ2R")] = -0.05
    eig = np.linalg.eigvalsh(mass_matrix_along(m, free, bad, q))
    assert np.all(eig[:, 0] < 0)


def test_an_estimator_far_worse_than_ls_is_not_converged():
    ls = MethodResult("ls", np.zeros(2), d_stacked=0.09)
    hop = MethodResult("hopfield", np.zeros(2), d_stacked=0.34)
    rls = MethodResult("rls", np.zeros(2), d_stacked=0.0905)
    warnings = mark_not_converged({"ls": ls, "hopfield": hop, "rls": rls}, ls)
    assert not hop.converged and rls.converged and ls.converged
    assert warnings and warnings[0].startswith("HOPFIELD: not converged")


@pytest.mark.parametrize(
    "ref,converged,not_converged",
    [(0.01, 0.018, 0.021),  # bar max(1.5 x 0.01, 0.01 + 0.01) = max(0.015, 0.02) = 0.02
     (0.1, 0.14, 0.16)],  # bar max(1.5 x 0.1, 0.1 + 0.01) = max(0.15, 0.11) = 0.15
)  # fmt: skip
def test_the_not_converged_bar_is_the_larger_of_one_and_a_half_ls_and_ls_plus_a_point(
    ref, converged, not_converged
):
    """An estimator is not converged when its in-sample stacked error exceeds the larger of
    1.5 x LS's and LS's + 0.01 (1 percentage point): below the bar it stays converged."""
    ls = MethodResult("ls", np.zeros(2), d_stacked=ref)
    near = MethodResult("hopfield", np.zeros(2), d_stacked=converged)
    far = MethodResult("rls", np.zeros(2), d_stacked=not_converged)
    warnings = mark_not_converged({"ls": ls, "hopfield": near, "rls": far}, ls)
    assert near.converged and not far.converged and ls.converged
    assert len(warnings) == 1 and warnings[0].startswith("RLS: not converged")


def test_a_mass_matrix_indefinite_at_some_samples_is_counted():
    """impossible_values warns that M(q) is not positive definite at k of the K sampled rows,
    k counted on the smallest eigenvalue: here the pan's inertia ZZ1R lowered by 0.75 kg m^2
    (M11(q2) then changes sign with the tilt angle) while the tilt's M22 stays positive, so
    the largest eigenvalue is positive at every row and only the smallest tells. Truth: k
    from numpy's eigvalsh on the Newton-Euler M(q) of the physical parameters with YY1
    (one of ZZ1R's terms, coefficient 1) lowered by 0.75."""
    from types import SimpleNamespace

    m = build_model(load_robot("guard"))
    names = m.base.names
    params = np.array(m.params, dtype=float)
    assert m.base.K[names.index("ZZ1R"), m.param_names.index("YY1")] == 1.0
    params[m.param_names.index("YY1")] -= 0.75
    theta = m.base.values(params)
    K = 200
    q = np.c_[np.linspace(-3, 3, K), np.linspace(-np.pi, np.pi, K)]
    eig = np.linalg.eigvalsh(m.mass_matrix(q, params))
    k = int(np.sum(eig[:, 0] <= 0))
    assert 0 < k < K and np.all(eig[:, -1] > 0)  # indefinite at some rows only
    ls = SimpleNamespace(theta_=theta, std_=np.full(len(theta), 0.01))
    out = impossible_values(m, list(range(len(names))), names, ls, SimpleNamespace(q=q))
    (line,) = out  # no friction or rotor inertia below 0
    assert f"not positive definite at {k} of {K} sampled rows" in line
    assert f"smallest eigenvalue {eig[:, 0].min():.3g})" in line


def test_measured_velocity_columns_are_used(tmp_path):
    t, q, tau = synthetic.log(500, 0.5, 5.0, 6, duration_s=20.0)
    _, qd, _ = synthetic.motion(t, 0.5, 5.0, 6)
    csv = tmp_path / "v.csv"
    write_csv(csv, ["t", "a", "b", "va", "vb", "ta", "tb"],
              [t, q[:, 0], q[:, 1], qd[:, 0], qd[:, 1], tau[:, 0], tau[:, 1]])  # fmt: skip
    cols = "time=t,q1=a,q2=b,qd1=va,qd2=vb,tau1=ta,tau2=tb"
    res = CliRunner().invoke(main, ["identify", str(csv), "--robot", "dfki_double_pendulum",
                                    "--columns", cols, "--method", "ls"])  # fmt: skip
    assert res.exit_code == 0, res.output
    partial = cols.replace("qd2=vb,", "")
    res = CliRunner().invoke(main, ["identify", str(csv), "--robot", "dfki_double_pendulum",
                                    "--columns", partial, "--method", "ls"])  # fmt: skip
    assert res.exit_code != 0 and "map qd<j> for every joint or for none" in res.output


def test_prismatic_units_in_the_report(tmp_path):
    robot = tmp_path / "lift.yaml"
    robot.write_text(AXIS_YAML)
    t = jittered_time(3000, 0.002, seed=3)
    q, qd, qdd = sines(t, [0.15, 0.06, 0.02], [0.4, 1.1, 2.3], [0.0, 1.0, 2.0])
    force = 2.5 * qdd + 2.5 * 9.81 + 3.0 * qd + 1.5 * np.sign(qd)
    log = tmp_path / "lift.csv"
    write_csv(log, ["s", "z", "f"], [t, q, force])
    out = tmp_path / "p.yaml"
    args = ["--robot", str(robot), "--columns", "time=s,q1=z,tau1=f"]
    res = CliRunner().invoke(main, ["identify", str(log), *args, "--method", "ls", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "effort in N;" in res.output and "N m" not in res.output
    assert "sign(qd)" in res.output
    res = CliRunner().invoke(main, ["validate", str(log), "--params", str(out), "--columns",
                                    "time=s,q1=z,tau1=f"])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "rms [N]" in res.output and "N m" not in res.output


def test_validation_metric_stacks_joints_and_names_a_passive_joint():
    """Stacked error and per-joint figures worked out by hand on a two-joint axis pair."""
    from types import SimpleNamespace

    from guardid.identify.validation import ParameterSet, score_sets

    d = load_robot("dfki_double_pendulum")
    m = build_model(d)
    rng = np.random.default_rng(3)
    q, qd, qdd = rng.normal(0, 1, (3, 200, 2))
    theta = m.base.values(m.params)
    tau = m.base_regressor(q, qd, qdd) @ theta
    tau[:, 1] = 0.01 * rng.normal(size=200)  # a passive elbow: only sensor noise
    cond = SimpleNamespace(q=q, qd=qd, qdd=qdd, tau=tau, mask=np.ones(200, bool))
    values = dict(zip(m.base.names, theta, strict=True))
    (s,) = score_sets([cond], [ParameterSet("truth", values, d)], ["run"])
    model_tau = m.base_regressor(q, qd, qdd) @ theta
    r = tau - model_tau  # joint 1: 0; joint 2: the noise minus the elbow's model torque
    assert s.stacked == pytest.approx(np.sqrt(np.sum(r**2) / np.sum(tau**2)), rel=1e-12)
    assert s.rms[0] == pytest.approx(0.0, abs=1e-12)
    assert s.rms[1] == pytest.approx(np.sqrt(np.mean(r[:, 1] ** 2)), rel=1e-12)
    assert list(s.passive) == [False, True] and np.isnan(s.relative[1])


def test_measured_velocities_enter_the_fit():
    """Exact measured velocities (qd<j>) replace the differentiated positions: the estimates
    still land on the truth, and the notes say so."""
    t, q, tau = synthetic.log(500, 0.5, 5.0, 6, duration_s=20.0)
    _, qd, _ = synthetic.motion(t, 0.5, 5.0, 6)
    path = load_robot("dfki_double_pendulum").source
    data = yaml.safe_load(open(path, encoding="utf-8"))
    for j in data["joints"]:
        j["friction"]["velocity_scale"] = synthetic.V_SCALE
    r = identify([run_from_arrays(t, q, tau, torque=True, qd=qd)], parse_robot(data, "s.yaml"),
                 IdentifyOptions(methods=("ls",)))  # fmt: skip
    assert any("measured velocities used" in n for n in r.notes)
    ls, tr = r.results["ls"], np.array([synthetic.truth()[n] for n in r.names])
    well = ls.rel_std_pct < 5
    assert np.all(np.abs(ls.theta - tr)[well] < 0.02 * np.abs(tr)[well])


def test_headerless_csv_reads_every_line(tmp_path):
    from guardid.identify.foreign import parse_mapping, read_foreign

    rows = np.column_stack([np.arange(12) * 0.01, np.arange(12) * 0.1, np.arange(12) * 2.0])
    path = tmp_path / "h.csv"
    np.savetxt(path, rows, delimiter=",")
    data = read_foreign(path, parse_mapping(["time=1,q1=2,tau1=3"]), 1, "axis")
    assert len(data.t) == 12 and data.q[0, 0] == 0.0 and data.effort[-1, 0] == 22.0
    with pytest.raises(Exception, match="column 4 not found"):
        read_foreign(path, parse_mapping(["time=1,q1=4,tau1=3"]), 1, "axis")
