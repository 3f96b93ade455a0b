"""Gaps are honest (issue 26): a long stretch of lost ticks splits a run into segments that
are conditioned as separate runs, and every command says so; a single lost tick is bridged
as before.

Truth: the robot YAML's values of the base parameters (the simulator runs guard.yaml), the
intact capture's result computed separately, gap times worked out from the tick column, the
bridge limit worked out by hand from its formula, and a spline bridge measured on a sine.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
import yaml
from badinput_tools import invoke
from logedit import column, without_footer, without_rows
from scipy.interpolate import CubicSpline

from guardid.identify.runs import Run
from guardid.identify.segments import (
    BRIDGE_ERROR,
    bridge_limit_ticks,
    split_run,
    split_runs,
)

PERIOD = 0.015  # guard's tick [s]
GAPS = {"gap200": (2000, 200), "gap95": (1000, 95)}  # first lost data row, lost rows


# --- the limit ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("cutoff_hz", "ticks"),
    # h_max = (384e-3 / 5)^(1/4) x 8 / (2 pi fc) = 0.67027 / fc [s]; floor(h_max / T) - 1
    [(8.0, 4), (4.0, 10), (13.333, 2), (200.0, 1)],  # 5.59 -> 4; 11.17 -> 10; 3.35 -> 2; floor 1
)
def test_bridge_limit_worked_out_by_hand(cutoff_hz, ticks):
    assert bridge_limit_ticks(cutoff_hz, PERIOD) == ticks


@pytest.mark.parametrize("cutoff_hz", [8.0, 4.0])
def test_a_bridge_at_the_limit_is_within_its_error_and_three_times_longer_is_not(cutoff_hz):
    """The conditioning's bridge (a cubic spline through the rows kept) over the motion's
    highest frequency, fc / 8: within BRIDGE_ERROR of the sine at the limit, beyond it at
    three times the limit."""
    t = np.arange(4000) * PERIOD
    x = np.sin(2 * np.pi * cutoff_hz / 8 * t + 0.3)

    def bridge_error(lost):
        keep = np.ones(len(t), bool)
        keep[2000 : 2000 + lost] = False
        return np.abs(CubicSpline(t[keep], x[keep])(t[~keep]) - x[~keep]).max()

    limit = bridge_limit_ticks(cutoff_hz, PERIOD)
    assert bridge_error(limit) <= BRIDGE_ERROR
    assert bridge_error(3 * limit) > BRIDGE_ERROR


def _run(ticks, path="r.csv"):
    ticks = np.asarray(ticks, dtype=np.int64)
    n = len(ticks)
    q = np.column_stack([np.arange(n), -np.arange(n)]).astype(float)
    return Run(path, "guard", ticks, (ticks - ticks[0]) * PERIOD, q, q * 2, None,
               setpoint=q * 3, sample_period_s=PERIOD)  # fmt: skip


def test_split_run_cuts_after_long_gaps_only_and_drops_short_segments():
    # rows 0-29, then 1 lost (bridged), 31-59, 5 lost (split), 65-99, 7 lost (split), 107-110
    ticks = [*range(30), *range(31, 60), *range(65, 100), *range(107, 111)]
    segments, gaps, dropped, jumps = split_run(_run(ticks), limit_ticks=4, min_rows=10)
    assert [s.path for s in segments] == ["r.csv[1]", "r.csv[2]"]
    assert [(g.lost, g.at_s) for g in gaps] == [(5, pytest.approx(59 * PERIOD)),
                                               (7, pytest.approx(99 * PERIOD))]  # fmt: skip
    assert dropped == [("r.csv[3]", 4)] and jumps == []  # no reach given: no jump looked for
    assert list(segments[0].ticks) == [*range(30), *range(31, 60)]
    assert list(segments[1].ticks) == list(range(65, 100))
    # every per-row array cut alike: the second segment's rows are rows 59..93 of the run
    assert np.array_equal(segments[1].q[:, 0], np.arange(59, 94))
    assert np.array_equal(segments[1].setpoint, 3 * segments[1].q)
    assert segments[1].source == "r.csv"


def test_split_runs_takes_the_limit_from_the_given_cutoff():
    ticks = [*range(200), *range(206, 400)]  # 6 lost ticks
    assert len(split_runs([_run(ticks)], cutoff_hz=4.0).runs) == 1  # limit 10: bridged
    split = split_runs([_run(ticks)], cutoff_hz=8.0)  # limit 4: split
    assert [r.path for r in split.runs] == ["r.csv[1]", "r.csv[2]"]
    line = split.lines(4.0)[0]
    # cost: 6 lost + a cut-off period (1 / 4 Hz = 16.7 -> 17 rows) at each new end
    assert "gap at 2.985 s: 6 ticks (0.09 s) lost" in line and "cost 40 rows" in line


# --- the commands on captures with rows removed -----------------------------------------------


def _params(path):
    data = yaml.safe_load(path.read_text())
    truth = np.array([p["yaml_value"] for p in data["base_parameters"]])
    wls = data["methods"]["wls"]
    return np.array(wls["values"]), np.array(wls["std"]), truth, int(data["rows"])


@pytest.fixture(scope="module")
def intact_params(gap_guard_wls_params):
    """{seed: (values, std, truth, rows)} of each intact capture, identified on its own."""
    return {seed: _params(path) for seed, path in gap_guard_wls_params.items()}


@pytest.mark.parametrize("gap", sorted(GAPS))
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_long_gap_splits_the_run_names_the_gap_and_keeps_the_estimate(
    gap_guard_captures, intact_params, tmp_path, seed, gap
):
    first, lost = GAPS[gap]
    text = gap_guard_captures[seed].read_text()
    log = tmp_path / f"{gap}.csv"
    log.write_text(without_rows(text, first, lost))
    gap_at_s = column(text, "time_s")[first - 1]  # the row before the gap
    out = tmp_path / "p.yaml"
    res = invoke("identify", log, "--method", "wls", "-o", out)
    assert res.exit_code == 0, res.stderr
    found = re.findall(r"gap at ([0-9.]+) s: (\d+) ticks \(([0-9.]+) s\) lost.*cost (\d+) rows",
                       res.stderr)  # fmt: skip
    assert len(found) == 1, res.stderr
    at, ticks, seconds, cost = found[0]
    assert float(at) == pytest.approx(gap_at_s, abs=1e-3)
    assert int(ticks) == lost and float(seconds) == pytest.approx(lost * PERIOD, rel=1e-2)
    assert int(cost) > lost  # the lost rows and the new ends' rows
    values, std, truth, rows = _params(out)
    assert rows < intact_params[seed][3]
    off = np.abs(values - truth) / std
    names = [p["name"] for p in yaml.safe_load(out.read_text())["base_parameters"]]
    assert off.max() < 3.0, dict(zip(names, off.round(2), strict=True))


@pytest.mark.parametrize("seed", [1, 2])
def test_a_single_lost_row_is_bridged_as_before(gap_guard_captures, intact_params, tmp_path, seed):
    log = tmp_path / "one.csv"
    log.write_text(without_rows(gap_guard_captures[seed].read_text(), 2000, 1))
    res = invoke("identify", log, "--method", "wls", "-o", tmp_path / "p.yaml")
    assert res.exit_code == 0, res.stderr
    assert "gap at" not in res.stderr and "[2]" not in res.stdout
    values, std, truth, _ = _params(tmp_path / "p.yaml")
    intact = intact_params[seed]
    assert np.all(np.abs(values - intact[0]) < intact[1])  # one row of 4000 moved it a little
    assert np.all(np.abs(values - truth) < 3 * std)


@pytest.fixture(scope="module")
def gap200_log(gap_guard_captures, tmp_path_factory):
    d = tmp_path_factory.mktemp("gap200")
    log = d / "gap200.csv"
    log.write_text(without_rows(gap_guard_captures[1].read_text(), *GAPS["gap200"]))
    return log


def test_validate_scores_each_segment_and_names_the_gap(gap200_log, gap_guard_captures, tmp_path):
    params = tmp_path / "p.yaml"
    assert invoke("identify", gap_guard_captures[2], "--method", "ls", "-o", params).exit_code == 0
    res = invoke("validate", gap200_log, "--params", params)
    assert res.exit_code == 0, res.stderr
    assert f"run {gap200_log}[1] (" in res.stdout and f"run {gap200_log}[2] (" in res.stdout
    assert re.search(r"gap at [0-9.]+ s: 200 ticks \(3 s\) lost", res.stdout), res.stdout
    assert "all runs, stacked relative rms error" in res.stdout


def test_cv_keeps_one_fold_per_file(gap200_log, gap_guard_captures):
    res = invoke("identify", gap200_log, gap_guard_captures[2], "--method", "ls", "--cv",
                 "--cutoff", "4")  # fmt: skip
    assert res.exit_code == 0, res.stderr
    rows = [line.split()[0] for line in res.stdout.splitlines() if line.endswith("%")]
    assert rows == [str(gap200_log), str(gap_guard_captures[2]), "mean"], res.stdout
    assert re.search(r"gap at [0-9.]+ s: 200 ticks", res.stdout), res.stdout


def test_closed_loop_iv_simulates_each_segment(gap200_log):
    """IV on a run split at a gap: each segment's simulation starts from its own first
    state (a single simulation across the gap would leave the rows misaligned: the
    command would stop, or the estimate drift); the estimate stays within 3 std."""
    res = invoke("identify", gap200_log, "--method", "wls,iv", "--cutoff", "4", "-o",
                 gap200_log.with_suffix(".yaml"))  # fmt: skip
    assert res.exit_code == 0, res.stderr
    data = yaml.safe_load(gap200_log.with_suffix(".yaml").read_text())
    truth = np.array([p["yaml_value"] for p in data["base_parameters"]])
    iv = data["methods"]["iv"]
    assert np.all(np.abs(np.array(iv["values"]) - truth) < 3 * np.array(iv["std"]))
    assert "gap at" in res.stderr


def test_the_online_replay_says_it_restarts_at_the_gap(gap200_log):
    res = invoke("identify", gap200_log, "--method", "ls,rls", "--cutoff", "4")
    assert res.exit_code == 0, res.stderr
    assert "causal filter restarted after each of 1 gaps" in res.stdout, res.stdout


def test_a_run_with_no_stretch_long_enough_names_the_file(gap_guard_captures, tmp_path):
    text = gap_guard_captures[1].read_text()
    log = tmp_path / "short.csv"
    log.write_text(without_footer(without_rows(text, 20, 4000)))  # 20 rows left
    res = invoke("identify", log, "--method", "ls", "-o", tmp_path / "p.yaml")
    assert res.exit_code == 2
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("guardid: error: ") and "short.csv" in lines[0]
    assert not (tmp_path / "p.yaml").exists()


def test_the_python_api_splits_a_long_gap_as_the_command_does(gap200_log):
    """identify(runs, ...) is the command's pipeline: in the acceleration form (which bridges
    what it is given) the 200-tick gap must split the run, be named, and leave the truth
    within 3 std (bridged with no word: ZZ2R and MX2R 4.2 std off, Fc1 3.6)."""
    from guardid.conditioning.options import ConditioningOptions
    from guardid.dynamics import build_model
    from guardid.identify import IdentifyOptions, identify, load_run
    from guardid.robot import load_robot

    acceleration = ConditioningOptions(equation="acceleration")
    options = IdentifyOptions(methods=("wls",), conditioning=acceleration)
    with pytest.warns(Warning, match="footer"):
        result = identify([load_run(str(gap200_log))], load_robot("guard"), options)
    gap = [w for w in result.warnings if re.search(r"gap at [0-9.]+ s: 200 ticks", w)]
    assert len(gap) == 1, result.warnings
    model = build_model(load_robot("guard"))  # the simulator's robot: the truth
    truth = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    wls = result.results["wls"]
    off = {n: abs(v - truth[n]) / s for n, v, s in zip(result.names, wls.theta, wls.std,
                                                         strict=True)}  # fmt: skip
    assert max(off.values()) < 3.0, off
