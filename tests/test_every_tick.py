"""``identify --every-tick``: momentum rows at every tick, their shared noise counted in the
std (each joint's residual autocovariance over 2 / cut-off), recorded and reused."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from badinput_tools import invoke
from logedit import data_rows, without_footer, without_rows

from guardid.conditioning import momentum as mom
from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import build_model
from guardid.estimators import WeightedLeastSquares
from guardid.identify.prepare import run_signals
from guardid.identify.rows import stacked_rows
from guardid.identify.runs import load_run
from guardid.robot import load_robot


@pytest.fixture(scope="module")
def every_tick_params(gap_guard_captures, tmp_path_factory):
    """{seed: params of ``identify --every-tick --method wls``} on the 60 s captures."""
    d = tmp_path_factory.mktemp("every_tick")
    out = {}
    for seed, log in gap_guard_captures.items():
        out[seed] = d / f"p{seed}.yaml"
        res = invoke("identify", log, "--every-tick", "--method", "wls", "-o", out[seed])
        assert res.exit_code == 0, res.stderr
    return out


def _truth():
    model = build_model(load_robot("guard"))
    return dict(zip(model.base.names, model.base.values(model.params), strict=True))


def test_the_std_covers_the_truth(every_tick_params):
    """Every parameter of three runs within 4 std of the robot YAML's value. The rows'
    white-residual std is about 3.5x too small on these rows (neighbours share noise):
    with it, errors of 4 std and more are the rule (checked by dropping the lag)."""
    truth = _truth()
    worst = []
    for path in every_tick_params.values():
        data = yaml.safe_load(path.read_text())
        names = [b["name"] for b in data["base_parameters"]]
        wls = data["methods"]["wls"]
        err = [abs(v - truth[n]) / s for n, v, s in zip(names, wls["values"], wls["std"],
                                                         strict=True)]  # fmt: skip
        worst.append(max(err))
    assert max(worst) < 4.0, worst


def test_the_choice_is_recorded_and_validate_reuses_it(every_tick_params, gap_guard_captures):
    path = every_tick_params[1]
    data = yaml.safe_load(path.read_text())
    assert data["conditioning"]["decimate"] == 1
    res = invoke("validate", gap_guard_captures[2], "--params", path)
    assert res.exit_code == 0, res.stderr


def test_rows_every_tick_and_the_window_from_the_filter(gap_guard_captures):
    """Every usable tick is a row; the window is 2 / fc in ticks (4 default row spacings),
    and the default rows (one every 1 / (2 fc)) are taken as independent."""
    desc = load_robot("guard")
    run = load_run(gap_guard_captures[1])
    kw = dict(highest_harmonic_hz=run.highest_harmonic_hz, periods_s=[run.excitation_period_s])
    tick = stacked_rows([run_signals(run, [run])], desc, ConditioningOptions(decimate=1), **kw)
    spaced = stacked_rows([run_signals(run, [run])], desc, ConditioningOptions(), **kw)
    fs = 1.0 / run.sample_period_s
    fc = tick.options.cutoff_hz
    k = int(fs / (2.0 * fc))  # the default spacing, worked out here
    assert tick.lag_ticks == 4 * k == mom.correlation_ticks(fs, fc)
    assert spaced.lag_ticks == 0 and spaced.row_ticks is None
    steps = np.diff(tick.row_ticks)
    assert np.mean(steps == 1) > 0.9  # consecutive ticks but at the cuts
    assert 0.8 * k < len(tick.A) / len(spaced.A) < 1.2 * k
    # the same rows fitted without the window: a std several times smaller (not honest)
    white = WeightedLeastSquares(column_noise=tick.column_noise).fit(tick.A, tick.y)
    lagged = WeightedLeastSquares(column_noise=tick.column_noise, row_ticks=tick.row_ticks,
                                  lag_ticks=tick.lag_ticks).fit(tick.A, tick.y)  # fmt: skip
    assert np.all(lagged.std_ > 1.5 * white.std_)


def test_rows_of_two_runs_are_never_neighbours():
    from types import SimpleNamespace

    from guardid.identify.rows import row_ticks

    dt = 0.015
    a = SimpleNamespace(t=5.0 + dt * np.arange(10), mask=np.arange(10) % 4 != 1, momentum=None)
    b = SimpleNamespace(t=dt * np.arange(6), mask=np.ones(6, bool), momentum=None)
    got = row_ticks([a, b], lag_ticks=3)
    # run a: its usable ticks 0, 2, 3, 4, 6, 7, 8; run b after a's last tick (9) + 3 + 1
    np.testing.assert_array_equal(got, [0, 2, 3, 4, 6, 7, 8, 13, 14, 15, 16, 17, 18])


def test_a_run_too_short_for_the_window_is_refused_in_one_line(
    gap_guard_captures, every_tick_params, tmp_path
):
    """12 s of a capture: fewer usable rows than 2 x parameters x window (2 x 12 x 65 =
    1560 ticks, 23 s): one line naming the rows and what they need, exit 2, no params."""
    text = gap_guard_captures[1].read_text()
    rows = len(data_rows(text)[1])
    log = tmp_path / "short.csv"
    log.write_text(without_footer(without_rows(text, 800, rows - 800)))  # the first 12 s
    out = tmp_path / "p.yaml"
    res = invoke("identify", log, "--every-tick", "--method", "wls", "-o", out)
    assert res.exit_code == 2 and not out.exists()
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "too few for their std" in lines[0] and "Traceback" not in res.stderr
    # the default rows identify the same 12 s, and validate scores it with every-tick params
    assert invoke("identify", log, "--method", "wls", "-o", out).exit_code == 0
    assert invoke("validate", log, "--params", every_tick_params[1]).exit_code == 0


@pytest.mark.parametrize("option", [("--equation", "acceleration"), ("--parallel-filter", "1")])
def test_rows_of_another_form_are_refused(gap_guard_captures, tmp_path, option):
    """The acceleration form's rows at every tick would get the white std: refused."""
    out = tmp_path / "p.yaml"
    res = invoke("identify", gap_guard_captures[1], "--every-tick", *option, "-o", out)
    assert res.exit_code == 2 and not out.exists()
    assert len(res.stderr.strip().splitlines()) == 1 and "momentum form only" in res.stderr
