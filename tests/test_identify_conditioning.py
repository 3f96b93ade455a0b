"""Conditioning chosen from the data, one options object, recorded and reused (issue 16)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from synthetic import NAMES, V_SCALE, log, motion, regressor, torque, truth

from guardid.cli import main
from guardid.conditioning.options import ConditioningOptions
from guardid.errors import ConfigError
from guardid.identify import IdentifyOptions, identify, run_from_arrays
from guardid.identify.cutoff import choose_parallel_filter, parallel_candidates
from guardid.identify.cutoff_scores import covariance_log_volume
from guardid.robot import load_robot
from guardid.robot.loader import parse_robot


@pytest.fixture(scope="module")
def robot():
    """The shipped pendulum with the synthetic model's Coulomb velocity scale."""
    path = load_robot("dfki_double_pendulum").source
    data = yaml.safe_load(open(path, encoding="utf-8"))
    for j in data["joints"]:
        j["friction"]["velocity_scale"] = V_SCALE
    return parse_robot(data, "synthetic.yaml")


# The bar: synthetic logs at 100 Hz, 500 Hz and 1 kHz, excitation bands 0.2-20 Hz,
# a 15-bit encoder's quantisation and torque noise (tests/synthetic.py), default conditioning,
# no option set: every parameter whose relative std is under 5 % lies within 2 % of the
# truth, and the truth within 3 std. (sample rate [Hz], band's low and high edge [Hz]).
CASES = [(100, 0.2, 2.0), (500, 0.5, 5.0), (500, 1.0, 10.0), (1000, 0.2, 2.0),
         (1000, 1.0, 10.0), (500, 2.0, 20.0), (1000, 2.0, 20.0)]  # fmt: skip
# Asserted here on seeds 1 and 2 of each case. Over seeds 1-15 (bench/bench_synthetic.py, an
# evaluator in plain numpy) it holds on 103 of these 105 logs, not all: 100 Hz 0.2-2 Hz seed 8
# (Fv2 -2.40 %, 2.3 std; its rel. std 1.0 %) and 500 Hz 1-10 Hz seed 10 (MX2R +0.08 % at
# 3.0 std) miss.
SEEDS = (1, 2)
LS = IdentifyOptions(methods=("ls",))


_FITS: dict = {}


def _fit(robot, fs, lo, hi, seed=1):
    """(identification, its LS result, the truth (b,)) of one synthetic log (cached)."""
    key = (id(robot), fs, lo, hi, seed)
    if key not in _FITS:
        t, q, tau = log(fs, lo, hi, seed)
        r = identify([run_from_arrays(t, q, tau, torque=True)], robot, LS)
        _FITS[key] = (r, r.results["ls"], np.array([truth()[n] for n in r.names]))
    return _FITS[key]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("fs,lo,hi", CASES)
def test_default_conditioning_recovers_the_truth(robot, fs, lo, hi, seed):
    r, ls, tr = _fit(robot, fs, lo, hi, seed)
    assert r.names == NAMES
    well = ls.std / np.abs(ls.theta) < 0.05
    rel = np.abs(ls.theta - tr) / np.abs(tr)
    report = {
        n: f"{100 * e:+.2f} % ({e * t / s:+.1f} std, rel. std {100 * s / abs(t):.2f} %)"
        for n, e, s, t in zip(r.names, (ls.theta - tr) / tr, ls.std, tr, strict=True)
    }
    where = (r.cutoff_hz, r.conditioning.parallel_filter_hz, report)
    assert well.sum() >= 5, where
    assert np.all(rel[well] < 0.02), where
    assert np.all(np.abs(ls.theta - tr)[well] < 3 * ls.std[well]), where


def test_synthetic_regressor_is_the_closed_form_model():
    """The hand-derived regressor (the bench's oracle) reproduces the closed-form torque."""
    t = np.arange(0.0, 5.0, 0.002)
    q, qd, qdd = motion(t, 0.5, 5.0, 3)
    theta = np.array([truth()[n] for n in NAMES])
    np.testing.assert_allclose(regressor(q, qd, qdd) @ theta, torque(q, qd, qdd), atol=1e-12)


def test_cutoff_follows_the_data_not_a_constant(robot):
    """A slow and a fast excitation of the same robot get different cut-offs, each above its
    band, and the report says how it was chosen and which rows were used."""
    slow, _, _ = _fit(robot, 500, 0.2, 2.0)
    fast, _, _ = _fit(robot, 500, 2.0, 20.0)
    assert 2.0 <= slow.cutoff_hz < fast.cutoff_hz
    assert fast.cutoff_hz >= 20.0
    for r in (slow, fast):
        assert "cross-validation" in r.cutoff_reason
        assert r.rows_summary.startswith("rows: ")


def test_parallel_filter_chosen_where_every_row_obeys_the_model(robot):
    """Smooth friction, every row kept: a parallel filter below the positions' cut-off (the
    20 Hz band's differentiated encoder noise removed); sign friction, rows near zero
    velocity dropped: no parallel filter (it would mix those rows back in)."""
    r, _, _ = _fit(robot, 500, 2.0, 20.0)
    pf = r.conditioning.parallel_filter_hz
    assert pf is not None and pf < r.cutoff_hz, r.notes
    assert any(n.startswith(f"parallel filter {pf:g} Hz on the regressor") for n in r.notes)
    data = yaml.safe_load(open(load_robot("dfki_double_pendulum").source, encoding="utf-8"))
    for j in data["joints"]:
        j["friction"]["model"] = "sign"
        del j["friction"]["velocity_scale"]
    sign = parse_robot(data, "sign.yaml")
    r, _, _ = _fit(sign, 500, 0.5, 5.0)
    assert r.conditioning.parallel_filter_hz is None
    assert any("parallel filter off: rows near zero velocity" in n for n in r.notes), r.notes


def test_parallel_filter_is_exact_on_noise_free_data(robot):
    """Without noise the parallel-filtered rows obey the model exactly (the filter's reach
    past the first stage's ends is dropped): every parameter within 0.05 % of the truth."""
    t = np.arange(0.0, 20.0, 0.001)
    q, qd, qdd = motion(t, 1.0, 10.0, 2)
    o = ConditioningOptions(cutoff_hz=25.0, parallel_filter_hz=8.0)
    r = identify([run_from_arrays(t, q, torque(q, qd, qdd), torque=True)], robot,
                 IdentifyOptions(methods=("ls",), conditioning=o))  # fmt: skip
    tr = np.array([truth()[n] for n in r.names])
    err = np.abs(r.results["ls"].theta - tr) / tr
    assert np.all(err < 5e-4), dict(zip(r.names, err, strict=True))


def test_parallel_filter_rule():
    """choose_parallel_filter on scores worked out by hand (log variance per parameter,
    held-out error): the most precise candidate whose held-out error is within 2 % of
    off's, and only when it divides the variances by at least 2."""
    cands = parallel_candidates(10.0)
    assert cands[0] == 0.63 and cands[-1] == 10.0  # R10 from 10 / 16 = 0.625 Hz up
    gains = {None: (1.0, 0.300), 4.0: (3.0, 0.309), 2.0: (2.5, 0.305), 1.0: (2.2, 0.30)}

    def score(hz):
        g, held = gains.get(hz, (1.1, 0.3))
        return -np.log(g), held

    assert choose_parallel_filter(10.0, score).hz == 2.0  # 4 Hz: held-out 3 % worse
    gains[2.0] = gains[1.0] = (1.5, 0.3)
    choice = choose_parallel_filter(10.0, score)
    assert choice.hz is None and "1.50 x only" in choice.reason


def test_covariance_log_volume_is_the_least_squares_covariance():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(200, 2, 3)) * np.array([1.0, 10.0, 0.01])
    y = A @ np.array([1.0, -2.0, 30.0]) + rng.normal(0.0, 0.1, (200, 2))
    a, b = A.reshape(-1, 3), y.reshape(-1)
    res = b - a @ np.linalg.solve(a.T @ a, a.T @ b)
    cov = res @ res / (len(b) - 3) * np.linalg.inv(a.T @ a)
    assert covariance_log_volume(A, y) == pytest.approx(np.log(np.linalg.det(cov)) / 3, abs=1e-9)


def test_options_round_trip_and_errors():
    o = ConditioningOptions(cutoff_hz=5.0, parallel_filter_hz=3.0, friction_filter=True)
    assert ConditioningOptions.from_dict(o.to_dict()) == o
    with pytest.raises(ConfigError, match="p.yaml: conditioning.cutof: unknown"):
        ConditioningOptions.from_dict({"cutof": 5}, "p.yaml: conditioning")
    with pytest.raises(ConfigError, match="conditioning.cutoff_hz: expected a number"):
        ConditioningOptions.from_dict({"cutoff_hz": "five"})


def test_most_rows_dropped_is_warned(robot):
    t, q, tau = log(500, 0.2, 2.0, 1)
    sign = load_robot("dfki_double_pendulum")  # tanh model: keeps the rows near zero speed
    o = ConditioningOptions(stiction_threshold=2.0)
    r = identify([run_from_arrays(t, q, tau, torque=True)], sign,
                 IdentifyOptions(methods=("ls",), conditioning=o))  # fmt: skip
    assert any("conditioned samples usable" in w for w in r.warnings), r.warnings
    assert "near zero velocity" in r.rows_summary


def test_params_store_conditioning_and_robot_and_validate_reuses_them(tmp_path, robot):
    """identify -o writes the options used and the robot description itself; validate with
    no --robot and no --cutoff scores under exactly that conditioning."""
    t, q, tau = log(500, 0.5, 5.0, 3, duration_s=20.0)
    csv = tmp_path / "run.csv"
    np.savetxt(csv, np.column_stack([t, q, tau]), delimiter=",")  # headerless
    yml = tmp_path / "mine.yaml"
    data = yaml.safe_load(open(load_robot("dfki_double_pendulum").source, encoding="utf-8"))
    for j in data["joints"]:
        j["friction"]["velocity_scale"] = V_SCALE
    yml.write_text(yaml.safe_dump(data))
    params = tmp_path / "p.yaml"
    cols = "time=1,q1=2,q2=3,tau1=4,tau2=5"
    res = CliRunner().invoke(main, ["identify", str(csv), "--robot", str(yml), "--columns", cols,
                                    "--method", "ls", "-o", str(params)])  # fmt: skip
    assert res.exit_code == 0, res.output
    p = yaml.safe_load(params.read_text())
    assert p["conditioning"]["cutoff_hz"] == pytest.approx(p["cutoff_hz"])
    assert p["robot_description"]["joints"][0]["friction"]["velocity_scale"] == V_SCALE
    yml.unlink()  # validate must not need the robot's file any more
    res = CliRunner().invoke(main, ["validate", str(csv), "--params", str(params), "--columns",
                                    cols])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert f"cut-off {p['cutoff_hz']:g} Hz" in res.output
