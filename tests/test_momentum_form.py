"""The filtered momentum form (guardid.conditioning.momentum, DESIGN.md section 5b).

Independent truths: pinocchio's mass matrix M(q) and Coriolis matrix C(q, qd) (the momentum
M v and the rest -C^T v + g, with the identity dM/dt = C + C^T), the friction torque written
from docs/ROBOT_YAML.md (tests/test_pinocchio.py), the simulated plant's own state and
exact period-mean current, and the robot YAML's parameters.
"""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest
from test_pinocchio import CHAINS, friction_torque, perturbed, pin_model, rotor_mass_matrix

from guardid.conditioning import momentum as mom
from guardid.conditioning.electrical_lag import electrical_time_constants, lag_correction
from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import build_model
from guardid.errors import ConfigError
from guardid.identify.equation import drive_gain, free_columns, position_limits
from guardid.identify.rows import stacked_rows
from guardid.plant.plant import Plant
from guardid.robot import load_robot

PRISMATIC = """
name: pr
gravity: [0.0, 0.0, -9.81]
joints:
  - {type: prismatic, dh: {a: 0.0, alpha: 1.5707963267948966, d: 0.3, theta: 0.2},
     limits: {position: [-0.4, 0.4], velocity: 1, acceleration: 1}, drive: null,
     friction: {viscous: 0.3, coulomb: 0.1, model: tanh, velocity_scale: 0.05}}
  - {type: revolute, dh: {a: 0.25, alpha: -0.4, d: 0.05, theta: 0.0},
     limits: {position: null, velocity: 2, acceleration: 5}, drive: null,
     friction: {viscous: 0.05, coulomb: 0.2}}
links:
  - {mass: 3.0, com: [0.02, -0.1, 0.05], inertia: {xx: 0.05, yy: 0.06, zz: 0.04, xz: 0.003}}
  - {mass: 1.2, com: [-0.1, 0.01, 0.03], inertia: {xx: 0.01, yy: 0.02, zz: 0.025, xy: 0.001}}
"""


def _descriptions(tmp_path):
    path = tmp_path / "pr.yaml"
    path.write_text(PRISMATIC)
    out = {name: load_robot(name) for name in CHAINS}
    out["guard perturbed"] = perturbed(load_robot("guard"), 3)
    out["pr"] = load_robot(path)
    return out


def test_momentum_and_rest_match_pinocchio(tmp_path):
    """Y_p theta = M(q) v and Y_r theta = -C(q, v)^T v + g(q) + friction(v) (pinocchio), on
    random states of every shipped chain, a perturbed guard and a prismatic-revolute chain;
    and both are linear in the base parameters (the base regressor gives the same); the
    two at once (``momentum_and_rest_regressors``, one complex step) give the same."""
    rng = np.random.default_rng(7)
    for name, desc in _descriptions(tmp_path).items():
        model = build_model(desc)
        pm = pin_model(desc)
        data = pm.createData()
        n = desc.n_dof
        q = rng.uniform(-np.pi, np.pi, (6, n))
        for j, joint in enumerate(desc.joints):
            if joint.type == "prismatic":
                q[:, j] = rng.uniform(-0.4, 0.4, 6)
        v = rng.normal(0.0, 2.0, (6, n))
        p = model.momentum_regressor(q, v) @ model.params
        rest = model.rest_regressor(q, v) @ model.params
        base = model.base.values(model.params)
        p_base = model.momentum_regressor(q, v) @ model.base.B @ base
        p_both, rest_both = (y @ model.params for y in model.momentum_and_rest_regressors(q, v))
        for k in range(len(q)):
            m = pin.crba(pm, data, q[k])
            m = np.triu(m) + np.triu(m, 1).T + rotor_mass_matrix(desc)
            c = pin.computeCoriolisMatrix(pm, data, q[k], v[k])
            g = pin.computeGeneralizedGravity(pm, data, q[k])
            want_p = m @ v[k]
            want_r = -c.T @ v[k] + g + friction_torque(desc, v[k : k + 1])[0]
            scale_p, scale_r = np.abs(want_p).max(), np.abs(want_r).max()
            assert np.abs(p[k] - want_p).max() <= 1e-10 * scale_p, name
            assert np.abs(p_base[k] - want_p).max() <= 1e-9 * scale_p, name
            assert np.abs(rest[k] - want_r).max() <= 1e-10 * scale_r, name
            assert np.abs(p_both[k] - want_p).max() <= 1e-10 * scale_p, name
            assert np.abs(rest_both[k] - want_r).max() <= 1e-10 * scale_r, name


def test_rest_is_the_torque_minus_the_momentum_derivative(tmp_path):
    """Along a smooth path q(t) = a + b sin(w t): tau(q, qd, qdd) (pinocchio's rnea plus the
    friction) = d/dt (M(q) qd) (central difference of pinocchio's M qd, step 1e-5 s) +
    Y_r theta, to the difference's accuracy."""
    desc = _descriptions(tmp_path)["pr"]
    model = build_model(desc)
    pm = pin_model(desc)
    data = pm.createData()
    a, b, w = np.array([0.1, -0.4]), np.array([0.2, 1.1]), np.array([2.1, 0.7])
    rotor = rotor_mass_matrix(desc)

    def state(t):
        return a + b * np.sin(w * t), b * w * np.cos(w * t), -b * w * w * np.sin(w * t)

    def momentum(t):
        q, qd, _ = state(t)
        m = pin.crba(pm, data, q)
        return (np.triu(m) + np.triu(m, 1).T + rotor) @ qd

    h = 1e-5
    for t in (0.1, 0.9, 2.3):
        q, qd, qdd = state(t)
        tau = pin.rnea(pm, data, q, qd, qdd) + rotor @ qdd + friction_torque(desc, qd[None])[0]
        dp = (momentum(t + h) - momentum(t - h)) / (2 * h)
        rest = model.rest_regressor(q[None], qd[None])[0] @ model.params
        np.testing.assert_allclose(dp + rest, tau, rtol=0, atol=1e-7 * np.abs(tau).max())


def _plant_run(seconds=30.0, noise=False, seed=0):
    """The guard's plant under a position loop on its true state tracking sums of sines:
    tick times [s], true q [rad], true qd [rad/s], exact period-mean current [A] (the mean
    over the period ending at each tick), measured counts [rad] and current [A]."""
    desc = load_robot("guard")
    plant = Plant(desc, noise=noise, seed=seed)
    period = plant.dt
    t = np.arange(int(seconds / period)) * period
    ref = np.column_stack(
        [
            0.6 * np.sin(2 * np.pi * 0.23 * t) + 0.3 * np.sin(2 * np.pi * 0.61 * t),
            0.2 + 0.2 * np.sin(2 * np.pi * 0.31 * t) + 0.1 * np.sin(2 * np.pi * 0.83 * t),
        ]
    )
    rows = []
    q = qd = np.zeros(2)
    for k in range(len(t)):
        s = plant.step(list(np.clip(40.0 * (ref[k] - q) - qd, -12.0, 12.0)))
        q, qd = np.array(s.q), np.array(s.qd)
        rows.append((*s.q, *s.qd, *s.current_true, *s.q_sensed, *s.current))
    x = np.array(rows)
    return t + period, x[:, 0:2], x[:, 2:4], x[:, 4:6], x[:, 6:8], x[:, 8:10]


@pytest.fixture(scope="module")
def plant_run():
    return _plant_run()


def test_period_identity_holds_on_the_plant(plant_run):
    """impulse_k = N eta Kt i_mean T (the plant's exact period mean) equals the momentum
    change plus the integral of the rest with the true parameters, on every period where
    the joint moves (no stick, no stop nearby), to the quadrature's accuracy: 1e-4 of the
    impulses' peak (the plant's own state at the ticks)."""
    t, q, qd, i_mean, _, _ = plant_run
    desc = load_robot("guard")
    model = build_model(desc)
    period = desc.sample_period
    phi = mom.period_regressor(model, q, qd, period)
    imp = mom.period_impulse(i_mean, period, drive_gain(desc), False)
    bad = mom.flagged_ticks(q, qd, period, threshold=np.full(2, 0.02), flat_is_stuck=False,
                            position_limits=position_limits(desc))  # fmt: skip
    valid = mom.period_validity(len(t), np.zeros(len(t), bool), 0, bad)
    assert valid.mean(0).min() > 0.7
    r = imp - phi @ model.base.values(model.params)
    for j in range(2):
        peak = np.abs(imp[valid[:, j], j]).max()
        assert np.abs(r[valid[:, j], j]).max() <= 1e-4 * peak
        # the equation is not empty: a 5 % wrong rotor inertia leaves 10 x that residual
        wrong = model.params.copy()
        wrong[model.param_names.index(f"Ia{j + 1}")] *= 1.05
        r_wrong = imp - phi @ model.base.values(wrong)
        assert np.abs(r_wrong[valid[:, j], j]).max() > 1e-3 * peak


@pytest.mark.parametrize("every", [16, 1, 4], ids=["spaced", "every-tick", "every-4th-mean"])
def test_identification_recovers_the_truth_on_true_signals(plant_run, every):
    """The plant's true positions and exact period-mean currents in the momentum form,
    scored in units of the std that WLS reports on the same run as measured (quantised
    counts and current, no sensor noise: a small std). With the plant's true tick
    velocities every base parameter comes within 0.05 std (the form is exact up to the
    quadrature); with velocities from the difference stencil of the true positions (and its
    corrections for the torque steps, their slopes and the current's lag behind each step)
    within 0.1 std (the largest 0.053, ZZ2R at every tick, 2026-11-29). Without the lag's
    term the largest was Fv2 at -0.31, without any correction 1.5 std: this test's stiff
    position loop changes the voltage a lot every tick.
    ``every``: the rows' spacing in ticks, 16 = 1 / (2 fc) (what the default gives this
    short run), 1 every tick, 4 every 4th tick, each the mean of its 4 ticks (a long log's
    rows): the same bounds, in units of the std WLS reports on those rows (their shared
    noise counted)."""
    from guardid.estimators import WeightedLeastSquares

    t, q, qd, i_mean, q_meas, i_meas = plant_run
    desc = load_robot("guard")
    model = build_model(desc)
    opts = ConditioningOptions(equation="momentum", cutoff_hz=2.0, decimate=every)
    measured = stacked_rows([(t, q_meas, i_meas)], desc, opts)
    std = WeightedLeastSquares(**measured.error_model()).fit(measured.A, measured.y).std_
    free = free_columns(model, desc)
    truth = model.base.values(model.params)[free]
    for velocity, bound in ((qd, 0.05), (None, 0.1)):
        run = (t, q, i_mean) if velocity is None else (t, q, i_mean, velocity)
        true = stacked_rows([run], desc, opts.with_(flat_is_stuck=False))
        assert true.options.equation == "momentum" and true.options.order == mom.DEFAULT_ORDER
        assert true.options.decimate == measured.options.decimate == every
        theta = WeightedLeastSquares().fit(true.A, true.y).theta_
        z = (theta - truth) / std
        assert np.abs(z).max() < bound, dict(zip([model.base.names[i] for i in free], z,
                                                 strict=True))  # fmt: skip


def test_measured_run_within_a_few_std(plant_run):
    """The same run as the encoder and the ADC report it (quantised, no noise), identified
    with identify's defaults: the momentum form is chosen, and WLS's truth lies within 3 of
    its std for every parameter."""
    from guardid.identify.pipeline import IdentifyOptions, identify
    from guardid.identify.runs import run_from_arrays

    t, _, _, _, q_meas, i_meas = plant_run
    desc = load_robot("guard")
    model = build_model(desc)
    run = run_from_arrays(t, q_meas, i_meas, highest_harmonic_hz=0.83)
    res = identify([run], desc, IdentifyOptions(methods=("wls",)))
    assert res.conditioning.equation == "momentum"
    w = res.results["wls"]
    truth = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    z = (w.theta - np.array([truth[n] for n in res.names])) / w.std
    assert np.abs(z).max() < 3.0, dict(zip(res.names, z, strict=True))


def test_cuts_at_missing_ticks_and_per_joint(plant_run):
    """A lost tick cuts every joint's stretch (its period has no impulse); a joint flagged
    as stuck cuts only its own equation; rows where a joint is cut are zero for it."""
    t, q, _, i_mean, _, _ = plant_run
    desc = load_robot("guard")
    model = build_model(desc)
    keep = np.ones(len(t), bool)
    keep[1000] = False
    kw = {"gain": drive_gain(desc), "cutoff_hz": 2.0, "stiction_threshold": 0.03}
    cond, A, y = mom.condition_momentum(t[keep], q[keep], i_mean[keep], model, **kw)
    whole = mom.condition_momentum(t, q, i_mean, model, **kw)[0].momentum.valid
    valid = cond.momentum.valid
    # period 1000 (the new index) spans the lost tick; period k's terms use ticks k-4 ..
    # k+3 (velocity stencil, quadrature, and the stencil corrections one period further)
    assert not valid[997:1004].any()
    np.testing.assert_array_equal(valid[:997], whole[:997])
    np.testing.assert_array_equal(valid[1004:], whole[1005:])
    jm = cond.joint_mask
    assert np.all(A[~jm] == 0.0) and np.all(y[~jm] == 0.0)
    assert (jm[:, 0] != jm[:, 1]).any()  # some rows hold one joint's equation only


def test_options_record_and_read_back_the_equation():
    """params.yaml's conditioning carries the equation; a file written before the field
    existed is read as the acceleration form; a wrong value is a one-line ConfigError."""
    used = ConditioningOptions(equation="momentum", cutoff_hz=2.0, order=2)
    back = ConditioningOptions.from_dict(used.to_dict())
    assert back == used
    old = {k: v for k, v in used.to_dict().items() if k != "equation"}
    assert ConditioningOptions.from_dict(old).equation == "acceleration"
    with pytest.raises(ConfigError, match="conditioning.equation"):
        ConditioningOptions.from_dict({"equation": "energy"})


def test_torque_samples_explicit_momentum_and_automatic_acceleration():
    """A foreign log of instantaneous torque samples (the DFKI pendulum's closed-form model,
    tests/synthetic.py: tanh Coulomb friction, a coupled rotor, 15-bit encoder, torque noise):
    the automatic form is the acceleration one (said so); asked for, the momentum form (the
    impulse by the four-point rule, the five-point stencil) puts the closed-form truth within
    3 of WLS's std for every parameter."""
    import synthetic

    from guardid.estimators import WeightedLeastSquares

    desc = load_robot("dfki_double_pendulum")
    t, q, tau = synthetic.log(100.0, 0.2, 2.0, seed=0)
    auto = stacked_rows([(t, q, tau)], desc, effort_is_torque=True, options=None)
    assert auto.options.equation == "acceleration"
    assert any("measured torque samples" in n for n in auto.cond.notes)
    rows = stacked_rows([(t, q, tau)], desc, ConditioningOptions(equation="momentum"),
                        effort_is_torque=True)  # fmt: skip
    w = WeightedLeastSquares().fit(rows.A, rows.y)
    truth = synthetic.truth()
    z = (w.theta_ - np.array([truth[n] for n in synthetic.NAMES])) / w.std_
    assert np.abs(z).max() < 3.0, dict(zip(synthetic.NAMES, z, strict=True))


def test_old_params_files_validate_in_the_acceleration_form():
    """``guardid validate`` reads a params file's conditioning: without ``equation`` (written
    before the field) or without ``conditioning`` at all, the acceleration form."""
    from guardid.identify.validation import stored_conditioning

    old = {"conditioning": {"cutoff_hz": 4.0, "order": 4, "decimate": None}}
    assert stored_conditioning("p.yaml", old).equation == "acceleration"
    older = {"cutoff_hz": 4.0, "parallel_filter_hz": None}
    assert stored_conditioning("p.yaml", older).equation == "acceleration"
    new = {"conditioning": {"cutoff_hz": 2.0, "order": 2, "equation": "momentum"}}
    assert stored_conditioning("p.yaml", new).equation == "momentum"


def test_rows_of_other_positions_line_up_with_the_measured_ones(plant_run):
    """``momentum_rows_of`` (instruments from a simulated run) on the measured positions
    themselves gives the measured rows' regressor; on the true positions rows close to them
    (the same cuts and filter; the difference is the quantisation)."""
    from guardid.identify.momentum_rows import momentum_rows_of

    t, q, _, _, q_meas, i_meas = plant_run
    desc = load_robot("guard")
    model = build_model(desc)
    free = free_columns(model, desc)
    rows = stacked_rows([(t, q_meas, i_meas)], desc, ConditioningOptions(equation="momentum"))
    again = momentum_rows_of(rows, 0, q_meas, model, free)
    np.testing.assert_allclose(again, rows.A, rtol=0, atol=1e-12 * np.abs(rows.A).max())
    true = momentum_rows_of(rows, 0, q, model, free)
    assert true.shape == rows.A.shape
    rel = np.linalg.norm(true - rows.A) / np.linalg.norm(rows.A)
    assert 0 < rel < 0.05


def _whole_stretches(Phi, imp, valid, sos, skip, taper):
    """Reference for the chunked filter: the whole log's period regressor in one array, each
    joint's valid stretches filtered in one ``sosfilt`` call from rest (the form before
    issue 30's chunks), the stretch's k-th period (k = 1, 2, ..) weighted min(k / taper, 1)
    on both sides: (A (N, n, b), y (N, n), good (N, n)) on every tick."""
    from scipy.signal import sosfilt

    A, y = np.zeros_like(Phi), np.zeros(Phi.shape[:2])
    good = np.zeros(Phi.shape[:2], dtype=bool)
    for j in range(Phi.shape[1]):
        for s in range(len(Phi)):
            if valid[s, j] and (s == 0 or not valid[s - 1, j]):
                e = s + int(np.argmin(np.append(valid[s:, j], False)))
                ramp = np.minimum(np.arange(1, e - s + 1) / taper, 1.0)[:, None]
                both = np.column_stack([imp[s:e, j], Phi[s:e, j, :]]) * ramp
                out = sosfilt(sos, both, axis=0)
                y[s + skip : e, j], A[s + skip : e, j] = out[skip:, 0], out[skip:, 1:]
                good[s + skip : e, j] = True
    return A, y, good


@pytest.mark.parametrize(("mean", "chunk"), [(1, 29), (4, 29), (4, 89)])
def test_chunked_rows_equal_the_whole_log_filtered_at_once(plant_run, monkeypatch, mean, chunk):
    """Issue 30: the period regressor formed by chunks of ``chunk`` ticks (with their
    neighbours) and the filter's state carried across chunk boundaries give the rows of the
    whole log's regressor filtered in one pass per stretch (an independent loop,
    ``_whole_stretches``), with stretches cut mid-chunk (a lost tick, a stuck joint) and
    chunks where a joint is cut throughout, between two where it is not (a filter state
    carried over them was caught here; not with 61-tick chunks). Tolerance 1e-12 of each
    column's peak: the arithmetic is the same element by element; only the BLAS product
    with the base matrix sees other row counts (bit-equal on the 2-core EPYC)."""
    t, q, _, i_mean, q_meas, _ = plant_run
    desc = load_robot("guard")
    model = build_model(desc)
    keep = np.ones(len(t), bool)
    keep[1000] = False
    t, q, i_mean = t[keep], q_meas[keep], i_mean[keep]
    kw = {"gain": drive_gain(desc), "cutoff_hz": 2.0, "stiction_threshold": 0.03}
    if mean > 1:  # rows every 4th tick, each the mean of its 4: one more filter section
        kw.update(decimate=mean, mean_ticks=mean)
    monkeypatch.setattr(mom, "TICKS_CHUNK", chunk)
    cond, A, y = mom.condition_momentum(t, q, i_mean, model, **kw)
    st = cond.momentum
    assert len(t) // chunk > 20 and (st.valid[:, 0] != st.valid[:, 1]).any()  # per-joint cuts

    dt = st.dt
    Phi = mom.period_regressor(model, st.q, st.v, dt, st.kink)
    imp = mom.period_impulse(i_mean, dt, drive_gain(desc), False)
    drive, damping = imp / dt, mom.electrical_damping(desc, drive_gain(desc))
    broken = np.zeros(len(t), dtype=bool)
    broken[1:] = np.abs(np.diff(t) - dt) > 1e-6 * dt  # the lost tick
    imp += mom.kink_correction(drive, dt, 3)
    imp -= damping * mom.slope_term(st.v, dt, 3)
    imp += lag_correction(drive, st.q, dt, *mom.STENCILS[3], electrical_time_constants(desc),
                          damping, broken)  # fmt: skip
    # the whole filter as second-order sections (the Butterworth, then the mean's FIR):
    # independent of the mean formed at the kept rows and carried across chunks
    full = mom.row_filter(2.0, 1.0 / dt, mom.DEFAULT_ORDER, mean)
    assert st.taper == 5  # round(fs / (2 pi fc)) = round(66.7 / 12.57): a ramp in the rows
    A_ref, y_ref, good = _whole_stretches(Phi, imp, st.valid, full, st.skip, st.taper)
    np.testing.assert_array_equal(st.row_mask, good[st.rows])
    scale = np.abs(A_ref).max(axis=(0, 1))
    np.testing.assert_allclose(A * dt, A_ref[st.rows], rtol=0, atol=1e-12 * scale.max())
    np.testing.assert_allclose(y * dt, y_ref[st.rows], rtol=0, atol=1e-12 * np.abs(y_ref).max())
    assert cond.dropped["in the filter's start after a cut"] == round(
        (st.valid & ~good).sum() / st.rows[1]
    )
    # another model's rows on the same cuts (validation, instruments)
    again = mom.regressor_rows(st, model)
    np.testing.assert_allclose(again, A, rtol=0, atol=1e-12 * scale.max() / dt)


def test_chunked_identification_equals_the_unchunked_one(plant_run, monkeypatch):
    """identify's estimates and their std with chunks of 61 ticks equal those with the whole
    log in one chunk (to 1e-9 relative: the same rows to 1e-12, through one solve)."""
    from guardid.identify.pipeline import IdentifyOptions, identify
    from guardid.identify.runs import run_from_arrays

    t, _, _, _, q_meas, i_meas = plant_run
    desc = load_robot("guard")
    run = run_from_arrays(t, q_meas, i_meas, highest_harmonic_hz=0.83)
    fits = []
    for chunk in (10**9, 61):
        monkeypatch.setattr(mom, "TICKS_CHUNK", chunk)
        res = identify([run], desc, IdentifyOptions(methods=("ls", "wls")))
        fits.append([(r.theta, r.std) for r in res.results.values()])
    for (th0, sd0), (th1, sd1) in zip(*fits, strict=True):
        np.testing.assert_allclose(th1, th0, rtol=1e-9, atol=1e-9 * np.abs(th0).max())
        np.testing.assert_allclose(sd1, sd0, rtol=1e-9)


def test_a_ramped_start_leaves_the_mean_of_the_first_momenta():
    """With a running sum as the filter, the period equations' momentum differences summed
    from a stretch's start leave p_t minus the start's momentum: p_(s-1) alone without a
    ramp, the mean of the m momenta p_(s-1) .. p_(s+m-2) with the ramp of m (worked by
    hand: the weights' steps are 1/m each), on both sides of the equation (the impulses
    given as the same momentum changes). Random momenta, two stretches, both paths of
    :func:`filtered_rows` (a stretch carried across chunks, stretches from rest); the
    caller's arrays are left as they were."""
    rng = np.random.default_rng(3)
    n_t, m = 60, 4
    p = rng.normal(size=n_t)
    d_p = np.zeros(n_t)
    d_p[1:] = p[1:] - p[:-1]  # period k's momentum change, ending at tick k
    kept = d_p.copy()
    valid = np.zeros((n_t, 1), dtype=bool)
    valid[5:25, 0] = valid[30:58, 0] = True  # stretches from periods 5 and 30
    running_sum = np.array([[1.0, 0.0, 0.0, 1.0, -1.0, 0.0]])
    rows = np.arange(n_t)
    for chunk in (n_t, 7):
        chunks = [(a, min(a + chunk, n_t), d_p[a : a + chunk, None, None])
                  for a in range(0, n_t, chunk)]  # fmt: skip
        for taper, with_imp in itertools.product((1, m), (False, True)):
            imp = d_p[:, None].copy() if with_imp else None
            A, y, good, _ = mom.filtered_rows(chunks, imp, valid, running_sum, 0, rows, 1,
                                              taper=taper)  # fmt: skip
            for a, _, phi in chunks:  # not scaled in place
                np.testing.assert_array_equal(phi[:, 0, 0], kept[a : a + len(phi)])
            for s, e in ((5, 25), (30, 58)):
                start = p[s - 1] if taper == 1 else p[s - 1 : s - 1 + m].mean()
                t = np.arange(s + m, e)
                np.testing.assert_allclose(A[t, 0, 0], p[t] - start, rtol=0, atol=1e-12)
                if with_imp:
                    np.testing.assert_array_equal(imp[:, 0], kept)
                    np.testing.assert_allclose(y[t, 0], p[t] - start, rtol=0, atol=1e-12)
                assert good[s:e, 0].all()


def test_the_ramp_is_one_time_constant_of_the_filter():
    """m = round(fs / (2 pi fc)), by hand: the guard's 66.7 Hz at 2 Hz: 5.3 -> 5; 100 Hz at
    2 Hz: 7.96 -> 8; 50 Hz at 4 Hz: 1.99 -> 2; a cut-off near Nyquist: 1 (no ramp)."""
    assert mom.taper_ticks(2.0, 1.0 / 0.015) == 5
    assert mom.taper_ticks(2.0, 100.0) == 8
    assert mom.taper_ticks(4.0, 50.0) == 2
    assert mom.taper_ticks(20.0, 50.0) == 1
    np.testing.assert_allclose(mom.start_ramp(4), [0.25, 0.5, 0.75])


@pytest.mark.parametrize("m", [1, 4, 15])
def test_the_rows_filter_is_the_butterworth_then_the_mean_of_m_ticks(m):
    """Its impulse response is the causal Butterworth's convolved with m taps of 1 / m
    (numpy's convolve of scipy's butter, independent of the second-order sections)."""
    from scipy.signal import butter, lfilter, sosfilt

    fs, fc = 1.0 / 0.015, 2.0
    x = np.zeros(600)
    x[0] = 1.0
    b, a = butter(mom.DEFAULT_ORDER, fc, fs=fs)
    want = np.convolve(lfilter(b, a, x), np.full(m, 1.0 / m))[: x.size]
    got = sosfilt(mom.row_filter(fc, fs, mom.DEFAULT_ORDER, m), x)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    assert got.sum() == pytest.approx(1.0, rel=1e-6)  # unit gain at DC: the equation's scale


def test_offset_column_is_the_period_length():
    """A friction offset Fo is a constant torque: its integral over a period is Fo T, so
    the Fo column of joint j's period equation is T on every period whose terms lie in the
    log (with the stencil's kink and slope corrections too: a constant torque does not
    step at the ticks), and 0 in the other joint's equation. The guard with its offsets
    declared (``offset: 0.05``, modelled), on a motion that never stops."""
    from dataclasses import replace

    guard = load_robot("guard")
    joints = tuple(
        replace(j, friction=replace(j.friction, offset=0.05, offset_modelled=True))
        for j in guard.joints
    )
    model = build_model(replace(guard, joints=joints))
    names = list(model.base.names)
    period = guard.sample_period
    t = np.arange(400) * period
    q = np.column_stack([0.5 * t + 0.1 * np.sin(2 * np.pi * 0.4 * t),
                         0.3 * t + 0.05 * np.sin(2 * np.pi * 0.7 * t)])  # fmt: skip
    v = np.column_stack([0.5 + 0.1 * 2 * np.pi * 0.4 * np.cos(2 * np.pi * 0.4 * t),
                         0.3 + 0.05 * 2 * np.pi * 0.7 * np.cos(2 * np.pi * 0.7 * t)])  # fmt: skip
    for kink, inside in ((None, slice(2, -1)), (3, slice(3, -2))):
        phi = mom.period_regressor(model, q, v, period, kink)
        for j in range(2):
            col = names.index(f"Fo{j + 1}")
            np.testing.assert_allclose(phi[inside, j, col], period, rtol=1e-12, atol=0)
            assert np.all(phi[:, 1 - j, col] == 0.0)


def test_viscous_column_carries_the_viscous_torques_stencil_error():
    """The Fv column of a period is the integral of qdot over it, q_k - q_(k-1), plus (with
    the stencil's corrections) the change of the three-point stencil's momentum error that
    the viscous torque Fv qdot(t) makes: that error is the stencil's error on X(t) =
    integral of q (X'' = qdot), g_k = (X_(k+1) - X_(k-1)) / (2 T) - q_k, and enters the
    regressor as + Fv (g_k - g_(k-1)) (imp = change of M v_hat - change of M (v_hat - v) +
    rest, the viscous torque's share of M (v - v_hat) being Fv g). Closed form on a motion
    whose acceleration is constant over each period (a voltage held per period, the back-EMF
    neglected): q and the period integrals of q exact from the accelerations. The code takes
    the slope of qdot over a period from the stencil's velocities (T a_i ~ v_hat_i -
    v_hat_(i-1)), off by O(T^5 a'''), about 1 % of the slope's share here: within 5 % of
    that share; exactly (1e-12) the hand-derived three-point formula on v_hat (weights
    W = [-1/4, 1/4] on the period means, U = [-1/24, -1/24] on the slopes, of the periods
    ending at ticks k and k+1, worked out from the Taylor expansion)."""
    desc = load_robot("guard")
    model = build_model(desc)
    names = list(model.base.names)
    period = desc.sample_period
    n = 400
    mid = (np.arange(n) - 0.5) * period  # period i ends at tick i
    w = 2 * np.pi * mid
    acc = np.column_stack([4.0 * np.sin(1.3 * w) + 2.0 * np.sin(2.9 * w + 1),
                           3.0 * np.cos(1.7 * w) - 1.5 * np.sin(3.3 * w)])  # fmt: skip
    q, v, integral_q = np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2))
    q[0], v[0] = [0.1, -0.2], [1.0, 0.8]
    for i in range(1, n):
        q[i] = q[i - 1] + period * v[i - 1] + period**2 * acc[i] / 2
        integral_q[i] = period * q[i - 1] + period**2 * v[i - 1] / 2 + period**3 * acc[i] / 6
        v[i] = v[i - 1] + period * acc[i]
    assert v.min() > 0.3  # moving one way: the Coulomb column's direction is plain
    v_hat = np.zeros_like(q)
    v_hat[1:-1] = (q[2:] - q[:-2]) / (2 * period)
    dq = np.zeros_like(q)
    dq[1:] = q[1:] - q[:-1]
    g = np.zeros_like(q)
    g[1:-1] = (integral_q[1:-1] + integral_q[2:]) / (2 * period) - q[1:-1]
    truth = dq.copy()
    truth[1:] += g[1:] - g[:-1]
    # the slope's share by hand on the true velocities, and the formula on v_hat
    slope = np.zeros_like(q)
    slope[1:-1] = -period / 24 * (v[2:] - v[:-2])
    slope_hat = np.zeros_like(q)
    slope_hat[1:-1] = -period / 24 * (v_hat[2:] - v_hat[:-2])
    kink = np.zeros_like(q)
    kink[1:-1] = (dq[2:] - dq[1:-1]) / 4
    formula = dq.copy()
    formula[1:] += kink[1:] - kink[:-1] + slope_hat[1:] - slope_hat[:-1]
    share = np.abs(np.diff(slope, axis=0)[3:-2]).max()
    assert share > 1e-5
    inside = slice(3, -2)  # the corrections' reach inside the log
    plain = mom.period_regressor(model, q, v_hat, period, None)
    corrected = mom.period_regressor(model, q, v_hat, period, 3)
    for j in range(2):
        col = names.index(f"Fv{j + 1}")
        np.testing.assert_allclose(plain[2:-1, j, col], dq[2:-1, j], rtol=1e-12, atol=0)
        np.testing.assert_allclose(corrected[inside, j, col], truth[inside, j], rtol=0,
                                   atol=0.05 * share)  # fmt: skip
        np.testing.assert_allclose(corrected[inside, j, col], formula[inside, j], rtol=0,
                                   atol=1e-12 * np.abs(formula[inside, j]).max())  # fmt: skip
