"""Momentum rows at every tick (identify's default, and ``--every-tick``), their shared noise
counted in the std (each joint's residual autocovariance over 2 / cut-off), recorded and
reused; a short log falls back to rows one every 1 / (2 fc) (``--spaced-rows``), a long one
keeps a row every m-th tick."""

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
from guardid.identify.pipeline import identified_names
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
    spaced = stacked_rows([run_signals(run, [run])], desc, ConditioningOptions(decimate=0), **kw)
    auto = stacked_rows([run_signals(run, [run])], desc, ConditioningOptions(), **kw)
    fs = 1.0 / run.sample_period_s
    fc = tick.options.cutoff_hz
    k = int(fs / (2.0 * fc))  # the default spacing, worked out here
    assert tick.lag_ticks == 4 * k == mom.correlation_ticks(fs, fc)
    assert spaced.lag_ticks == 0 and spaced.row_ticks is None
    assert (tick.options.decimate, spaced.options.decimate) == (1, k)  # recorded as used
    # the default on 60 s: every tick, the same rows
    assert auto.options.decimate == 1 and auto.lag_ticks == tick.lag_ticks
    np.testing.assert_array_equal(auto.row_ticks, tick.row_ticks)
    np.testing.assert_array_equal(auto.A, tick.A)
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
    # the default falls back to rows 1 / (2 fc) apart, says why, and records the spacing;
    # validate scores the 12 s with every-tick params
    res = invoke("identify", log, "--method", "wls", "-o", out)
    assert res.exit_code == 0, res.stderr
    said = [x for x in res.stdout.splitlines() if x.startswith("rows every 16 ticks")]
    assert len(said) == 1 and "too few for closer rows' std" in said[0] and "1560" in said[0]
    k = int(1.0 / 0.015 / (2.0 * 2.0))  # 66.7 Hz ticks, cut-off 2 Hz
    assert yaml.safe_load(out.read_text())["conditioning"]["decimate"] == k == 16
    assert invoke("validate", log, "--params", every_tick_params[1]).exit_code == 0


def test_the_default_is_every_tick_on_a_60_s_log(gap_guard_captures, every_tick_params, tmp_path):
    out = tmp_path / "p.yaml"
    res = invoke("identify", gap_guard_captures[1], "--method", "wls", "-o", out)
    assert res.exit_code == 0, res.stderr
    got, want = (yaml.safe_load(p.read_text()) for p in (out, every_tick_params[1]))
    assert got["conditioning"]["decimate"] == 1
    assert got["methods"]["wls"]["values"] == want["methods"]["wls"]["values"]
    assert got["methods"]["wls"]["std"] == want["methods"]["wls"]["std"]


def test_spaced_rows_are_one_every_half_cutoff_period_with_the_white_std(
    gap_guard_captures, every_tick_params, tmp_path
):
    out = tmp_path / "p.yaml"
    res = invoke("identify", gap_guard_captures[1], "--method", "wls", "--spaced-rows", "-o", out)
    assert res.exit_code == 0, res.stderr
    assert "after decimation by 16" in res.stdout
    data = yaml.safe_load(out.read_text())
    assert data["conditioning"]["decimate"] == 16
    tick = yaml.safe_load(every_tick_params[1].read_text())["methods"]["wls"]
    assert data["methods"]["wls"]["values"] != tick["values"]
    out = tmp_path / "both.yaml"
    both = invoke("identify", gap_guard_captures[1], "--every-tick", "--spaced-rows", "-o", out)
    assert both.exit_code == 2 and "not both" in both.stderr and not out.exists()
    assert len(both.stderr.strip().splitlines()) == 1


def test_row_spacing_of_a_long_log():
    """Every tick up to MAX_ROWS ticks, then ceil(ticks / MAX_ROWS), at most 1 / (2 fc)."""
    fs, fc = 1.0 / 0.015, 2.0  # the default spacing int(66.7 / 4) = 16
    assert mom.MAX_ROWS == 65536
    from guardid.commands.identify import _EVERY_TICK_HELP

    assert "longer than 65536 ticks (at most 65536 rows," in _EVERY_TICK_HELP  # says the same
    assert mom.row_spacing(16 * 65536, fs, fc) == 16 < mom.row_spacing(16 * 65536 + 1, fs, fc) + 1
    assert 16 * 65536 * 0.015 / 3600 == pytest.approx(4.4, abs=0.05)  # "about 4.4 h"
    assert mom.row_spacing(4000, fs, fc) == 1
    assert mom.row_spacing(65536, fs, fc) == 1
    assert mom.row_spacing(65537, fs, fc) == 2
    assert mom.row_spacing(240000, fs, fc) == 4  # 1 h: 240000 / 65536 = 3.66
    assert mom.row_spacing(960000, fs, fc) == 15  # 4 h: 14.6
    assert mom.row_spacing(1920000, fs, fc) == 16  # 8 h: 29.3, capped


def test_a_long_log_keeps_a_row_every_few_ticks_and_its_std_covers(gap_guard_captures, monkeypatch):
    """With the budget at 1000 rows a 60 s log (4000 ticks) keeps every 4th tick, each the
    mean of its 4 ticks; the window is 2 / fc in ticks and the mean's 3, and WLS's std
    covers the robot YAML's values within 4 std on the three runs; the white std is smaller
    on every parameter."""
    monkeypatch.setattr(mom, "MAX_ROWS", 1000)
    desc, truth = load_robot("guard"), _truth()
    worst, ratio = [], []
    for log in gap_guard_captures.values():
        run = load_run(log)
        kw = dict(highest_harmonic_hz=run.highest_harmonic_hz, periods_s=[None])
        rows = stacked_rows([run_signals(run, [run])], desc, ConditioningOptions(), **kw)
        assert rows.options.decimate == 4 and rows.lag_ticks == 64 + 3  # the mean's 3 more
        assert rows.cond.momentum.mean_ticks == 4  # the Butterworth, then the 4-tick mean
        steps = np.diff(rows.row_ticks)
        assert np.all(steps % 4 == 0) and np.mean(steps == 4) > 0.9
        said = "rows every 4 ticks, each the mean of its 4 ticks: at most 1000 rows"
        assert any(x.startswith(said) for x in rows.cond.notes)
        want = np.array([truth[n] for n in identified_names(desc)])
        lagged = WeightedLeastSquares(**rows.error_model()).fit(rows.A, rows.y)
        white = WeightedLeastSquares(column_noise=rows.column_noise).fit(rows.A, rows.y)
        worst.append(np.max(np.abs(lagged.theta_ - want) / lagged.std_))
        ratio.append(np.min(lagged.std_ / white.std_))
    assert max(worst) < 4.0, worst
    assert min(ratio) > 1.3, ratio  # rows 4 ticks apart still share their noise


def test_rows_every_few_ticks_stay_on_the_tick_count_across_lost_ticks(
    gap_guard_captures, tmp_path, monkeypatch
):
    """Two ticks lost at row 1001 and two runs: the rows every 3rd tick stay on the ticks
    whose count is a multiple of 3 (not every 3rd sample, which the loss would shift), in
    both runs, and the second run's rows on the same grid (the window, 64 + 2 ticks, is not
    a multiple of 3), so that their pairs lie on one grid 3 ticks apart."""
    monkeypatch.setattr(mom, "MAX_ROWS", 2700)  # two logs of about 4000 ticks: every 3rd
    log = tmp_path / "lost.csv"
    log.write_text(without_footer(without_rows(gap_guard_captures[1].read_text(), 1001, 2)))
    runs = [load_run(log), load_run(gap_guard_captures[2])]
    rows = stacked_rows([run_signals(r, runs) for r in runs], load_robot("guard"),
                        ConditioningOptions(), highest_harmonic_hz=runs[0].highest_harmonic_hz,
                        periods_s=[None, None])  # fmt: skip
    assert rows.options.decimate == 3 and rows.lag_ticks == 66
    for cond in rows.runs:  # the ticks counted from each run's first, by its time stamps
        tick = np.rint((cond.t - cond.t[0]) / 0.015).astype(int)
        assert np.all(tick % 3 == 0)
    assert rows.runs[0].t[-1] > 1004 * 0.015  # rows after the lost ticks
    assert np.all(rows.row_ticks % 3 == 0)  # the second run's rows on the same grid
    assert len(np.unique(rows.row_ticks)) == len(rows.row_ticks) == len(rows.A)


@pytest.mark.parametrize("option", [("--equation", "acceleration"), ("--parallel-filter", "1")])
def test_rows_of_another_form_are_refused(gap_guard_captures, tmp_path, option):
    """The acceleration form's rows at every tick would get the white std: refused."""
    out = tmp_path / "p.yaml"
    res = invoke("identify", gap_guard_captures[1], "--every-tick", *option, "-o", out)
    assert res.exit_code == 2 and not out.exists()
    assert len(res.stderr.strip().splitlines()) == 1 and "momentum form only" in res.stderr


def test_iv_and_didim_rows_keep_the_acceleration_forms_spacing(gap_guard_captures):
    """--every-tick (decimate 1) is the momentum form's: IV and DIDIM condition the runs again
    in the acceleration form, whose std is white, at that form's own spacing (about
    1 / (2 fc)), not at every tick."""
    from types import SimpleNamespace

    from guardid.identify.rows import closed_loop_rows

    run = load_run(gap_guard_captures[1])
    desc = load_robot("guard")
    kw = dict(highest_harmonic_hz=run.highest_harmonic_hz, periods_s=[None])
    tick = stacked_rows([run_signals(run, [run])], desc, ConditioningOptions(decimate=1), **kw)
    fit = SimpleNamespace(rows=tick, runs=[run], description=desc, effort_is_torque=False,
                          options=SimpleNamespace(conditioning=ConditioningOptions(decimate=1),
                                                  in_current_units=False))  # fmt: skip
    own = closed_loop_rows(fit)
    assert own.options.equation == "acceleration"
    assert own.cond.decimation > 4 and len(own.A) < len(tick.A) / 4
    assert own.row_ticks is None and own.lag_ticks == 0


def test_tick_count_rounds_half_ticks_up():
    """Stamps half a tick off the grid (a step of 1.5 ticks, in binary-exact 1/64 s): each
    its own tick, counted by hand, where numpy's round-half-to-even would give two the
    same."""
    dt = 1.0 / 64.0
    t = dt * np.array([0.0, 1.0, 2.5, 3.5, 4.5, 5.5])
    np.testing.assert_array_equal(mom.tick_count(t, dt), [0, 1, 3, 4, 5, 6])
    assert len(np.unique(np.rint(t / dt))) < len(t)  # what rint would have done


def test_a_long_logs_fallback_counts_the_means_ticks_in_its_window(
    gap_guard_captures, tmp_path, monkeypatch
):
    """Rows every 5th tick (a budget of 400 rows on about 2000 ticks) need 2 x 12 x (64 +
    5) = 1656 usable ticks, the window with the mean's 4 more; a log with fewer falls back
    to the spaced rows and identifies (it was refused by the fit's own check)."""
    monkeypatch.setattr(mom, "MAX_ROWS", 400)
    text = gap_guard_captures[1].read_text()
    rows = len(data_rows(text)[1])
    log = tmp_path / "short.csv"
    log.write_text(without_footer(without_rows(text, 2000, rows - 2000)))
    run = load_run(log)
    got = stacked_rows([run_signals(run, [run])], load_robot("guard"), ConditioningOptions(),
                       highest_harmonic_hz=run.highest_harmonic_hz, periods_s=[None])  # fmt: skip
    five = stacked_rows([run_signals(run, [run])], load_robot("guard"),
                        ConditioningOptions(decimate=5),
                        highest_harmonic_hz=run.highest_harmonic_hz, periods_s=[None])  # fmt: skip
    usable = 5 * len(five.A)
    assert 2 * 12 * (64 + 1) <= usable < 2 * 12 * (64 + 5)  # between the two windows' needs
    assert got.options.decimate == 16 and got.lag_ticks == 0
    out = tmp_path / "p.yaml"
    res = invoke("identify", log, "--method", "wls", "-o", out)
    assert res.exit_code == 0, res.stderr
