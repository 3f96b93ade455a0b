"""Conditioning chosen from the data, one options object, recorded and reused (issue 16)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from synthetic import V_SCALE, log, truth

from guardid.cli import main
from guardid.conditioning.options import ConditioningOptions
from guardid.errors import ConfigError
from guardid.identify import identify
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


# (sample rate [Hz], excitation band [Hz]): every parameter with relative std < 5 % within
# 2 % of the truth, the truth within 3 std (no option set)
ACCURATE = [(100, 0.2, 2.0), (500, 0.5, 5.0), (500, 1.0, 10.0), (1000, 0.2, 2.0),
            (1000, 1.0, 10.0)]  # fmt: skip
# bands reaching 20 Hz: friction's relative std is 2-4 %, so only the 3-std part holds
CONSISTENT = [(500, 2.0, 20.0), (1000, 2.0, 20.0)]


def _fit(robot, fs, lo, hi, seed=1):
    t, q, tau = log(fs, lo, hi, seed)
    r = identify(t, q, tau, robot, methods=("ls",), effort_is_torque=True)
    ls = r.results["ls"]
    tr = np.array([truth()[n] for n in r.names])
    return r, ls, tr


@pytest.mark.parametrize("fs,lo,hi", ACCURATE)
def test_default_conditioning_recovers_the_truth(robot, fs, lo, hi):
    r, ls, tr = _fit(robot, fs, lo, hi)
    well = ls.rel_std_pct < 5.0
    rel = np.abs(ls.theta - tr) / np.abs(tr)
    errors = (ls.theta - tr) / tr
    report = {
        n: f"{100 * e:+.2f} % (std {s:.2f} %)"
        for n, e, s in zip(r.names, errors, ls.rel_std_pct, strict=True)
    }
    assert well.sum() >= 5, report
    assert np.all(rel[well] < 0.02), (r.cutoff_hz, report)
    assert np.all(np.abs(ls.theta - tr)[well] < 3 * ls.std[well]), (r.cutoff_hz, report)
    assert "held-out error" not in r.cutoff_reason or r.conditioning.cutoff_hz == r.cutoff_hz


@pytest.mark.parametrize("fs,lo,hi", CONSISTENT)
def test_wide_band_truth_within_three_std(robot, fs, lo, hi):
    r, ls, tr = _fit(robot, fs, lo, hi)
    well = ls.rel_std_pct < 5.0
    assert np.all(np.abs(ls.theta - tr)[well] < 3 * ls.std[well])


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
    r = identify(t, q, tau, sign, methods=("ls",), effort_is_torque=True,
                 conditioning=ConditioningOptions(stiction_threshold=2.0))  # fmt: skip
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
