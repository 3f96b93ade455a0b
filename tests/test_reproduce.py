"""``guardid reproduce``: the seed papers' experiments (issue 10 acceptance)."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from guardid.cli import main
from guardid.reproduce import (
    EXPERIMENTS,
    flexsim,
    seed000_fast,
    seed000_slow,
    seed000_step,
    seed001_table1,
)


@pytest.fixture(scope="module")
def table1(seed001_table1_report):
    return seed001_table1_report  # the default: 15 noise seeds


@pytest.fixture(scope="module")
def step(reproduced):
    return reproduced("seed000_step", lambda: seed000_step.run(0, seeds=3))


@pytest.fixture(scope="module")
def fast(reproduced):
    return reproduced("seed000_fast", lambda: seed000_fast.run(0, seeds=3))


def test_registry_and_cli_registration():
    assert set(EXPERIMENTS) == {"seed000-step", "seed000-slow", "seed000-fast", "seed001-table1"}
    assert "reproduce" in main.list_commands(None)
    assert main.get_command(None, "reproduce").name == "reproduce"


def test_seed001_table1_within_one_percent(table1):
    """Default: noisy quantised q and noisy tau through guardid's conditioning.

    Truth: the simulated model's parameters (DESIGN.md section 4). LS must be within 1 %;
    the online estimators, which see every filtered row once with a fixed gain, are only
    required to stay within 10 % (on this data they are not within 1 %: see the report).
    """
    s = table1.summary
    assert not s["exact_acceleration"]
    assert np.all(s["pct_error"]["LS"] < 1.0), s["pct_error"]["LS"]
    assert np.all(s["pct_error"]["RLS"] < 1.0), s["pct_error"]["RLS"]  # RLS(lam=1) = LS
    for name in ("Hopfield", "gradient"):
        assert np.all(s["pct_error"][name] < 10.0), (name, s["pct_error"][name])
    # the filter is the conditioning's choice for a known excitation: 8 x 1.7 Hz (the
    # factor of identify, guardid.conditioning.bandwidth.HARMONIC_FACTOR)
    assert s["cutoff_hz"] == pytest.approx(13.6)
    assert s["noise"] == {"q": seed001_table1.NOISE_Q_RAD, "tau": seed001_table1.NOISE_TAU}
    # the paper's worst errors, as printed in its Table 1 (actual minus estimate)
    assert s["paper_pct_error"]["LS"].max() == pytest.approx(18.24, abs=0.01)
    assert s["paper_pct_error"]["RLS"].max() == pytest.approx(26.68, abs=0.01)
    assert s["lam_max_factor"] < 2.0  # gradient gain inside the explicit-Euler limit
    text = table1.text()
    for needle in (
        "paper LS",
        "Hopfield",
        "quantised",
        "Butterworth at 13.6 Hz",
        "central differences",
        "PID",
        "wall time",
        "misprint",
    ):
        assert needle in text


def test_seed001_exact_acceleration_variant():
    rep = seed001_table1.run(0, exact_acceleration=True, seeds=2)
    s = rep.summary
    assert s["exact_acceleration"] and s["noise"] == seed001_table1.NOISE
    for name in ("LS", "RLS", "Hopfield"):
        assert np.all(s["pct_error"][name] < 1.0), (name, s["pct_error"][name])
    assert "no filter" in rep.text()
    res = CliRunner().invoke(main, ["reproduce", "seed000-slow", "--exact-acceleration"])
    assert res.exit_code == 2 and "seed001-table1 only" in res.output


def test_seed001_deterministic(table1):
    again = seed001_table1.run(0, seeds=2)
    for k, v in table1.summary["estimates_per_seed"].items():
        np.testing.assert_array_equal(v[:2], again.summary["estimates_per_seed"][k])
    other = seed001_table1.run(2, seeds=1)  # seed 2 is the first one's third draw
    np.testing.assert_array_equal(
        other.summary["estimates_per_seed"]["LS"][0], table1.summary["estimates_per_seed"]["LS"][2]
    )
    assert not np.array_equal(other.summary["estimates"]["LS"], table1.summary["estimates"]["LS"])


def test_seed000_step_hopfield_settles(step):
    limit = 0.7 * math.pi
    for data in ("exact", "noisy"):
        r = step.summary["hopfield"][(data, flexsim.BETA)]
        assert r["start"][0] is not None and r["start"][0] <= limit, (data, r)
        assert r["step"][0] is not None and r["step"][0] <= limit, (data, r)
        assert r["step"][1] is not None and r["step"][1] <= limit, (data, r)
    exact = step.summary["hopfield"][("exact", flexsim.BETA)]
    assert exact["final_err"] < 1e-4
    # DESIGN.md's reference figure at beta = 0.003: ~0.5 pi after the start, ~0.7 pi after
    ref = step.summary["hopfield"][("exact", flexsim.BETA_DESIGN)]
    assert ref["start"][0] == pytest.approx(0.5 * math.pi, abs=0.1 * math.pi)
    assert ref["step"][0] == pytest.approx(0.7 * math.pi, abs=0.1 * math.pi)


def test_seed000_step_gain_robustness_is_the_integrators(step):
    """Same integrator, same settling range: the gain robustness belongs to the integrator.

    Truth: explicit Euler's stability bound, worked out by hand (the per-sample factor
    1 - k dt mu must stay above -1: k dt lambda_max(A_k^T A_k) < 2), and the implicit step's
    unconditional stability (factor 1 / (1 + k dt mu) in (0, 1]).
    """
    gains = step.summary["gains"]
    A, _ = flexsim.measurements(flexsim.simulate(seed000_step.mass, lambda t: 1.0), noisy=False)
    lam_max = np.linalg.eigvalsh(np.einsum("nji,njk->nik", A, A))[:, -1].max()
    dt = 0.5e-3
    for est in ("hopfield", "gradient"):
        imp, eul = gains[(est, "implicit")], gains[(est, "euler")]
        assert set(imp) == set(eul) == set(seed000_step.GAINS)
        for k in seed000_step.GAINS:
            assert imp[k]["verdict"] != "diverges", (est, k)
            if k * dt * lam_max > 2.0:
                assert eul[k]["verdict"] == "diverges", (est, k)
            elif k >= 100:  # fast enough to settle within the 4 pi s windows
                assert eul[k]["verdict"] == "settles", (est, k)
        settled = [k for k in seed000_step.GAINS if imp[k]["verdict"] == "settles"]
        assert min(settled) == 100 and max(settled) == 1e5, (est, settled)  # three decades
    text = step.text()
    assert "hub inertia" in text and "spring sign" in text and "wall time" in text
    assert "same linearly implicit step" in text and "explicit Euler per sample" in text


def test_seed000_slow_tracks_gamma():
    rep = seed000_slow.run(0, seeds=1)
    r = rep.summary[("exact", flexsim.BETA)]
    assert r["rms"] < 0.01
    assert r["stays"] is not None


def test_seed000_fast_lag_shrinks_with_beta(fast):
    s = fast.summary
    betas = (flexsim.BETA_DESIGN, flexsim.BETA, seed000_fast.BETA_SMALL)
    lags = [s[("exact", b)]["lag"] for b in betas]
    rms = [s[("exact", b)]["rms"] for b in betas]
    assert lags[0] > 0.05  # the estimate visibly lags the 1 rad/s variation
    assert lags[0] > lags[1] > lags[2] > 0
    assert rms[0] > rms[1] > rms[2]
    assert s[("exact", flexsim.BETA_DESIGN)]["amp_ratio"] < s[("exact", flexsim.BETA)]["amp_ratio"]


def test_settle_time_helper():
    from guardid.reproduce.common import settle_time

    t = np.arange(10.0)
    err = np.array([5, 0.5, 2, 0.5, 0.5, 0.5, 3, 0.1, 0.1, 0.1])
    assert settle_time(t, err, 1.0, 0.0) == (1.0, 7.0)
    assert settle_time(t, err, 1.0, 0.0, 6.0) == (1.0, 3.0)
    assert settle_time(t, err, 0.01, 0.0) == (None, None)


def test_cli_prints_and_plots(tmp_path):
    pytest.importorskip("matplotlib")
    res = CliRunner().invoke(
        main, ["reproduce", "seed001-table1", "--seeds", "1", "--plot", str(tmp_path)]
    )
    assert res.exit_code == 0, res.output
    assert "Actual minus estimate" in res.output and "wall time" in res.output
    assert (tmp_path / "seed001_fig6_rls.png").stat().st_size > 1000


def test_cli_plot_without_matplotlib(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    res = CliRunner().invoke(main, ["reproduce", "seed001-table1", "--plot", str(tmp_path)])
    assert res.exit_code == 2
    assert res.output.strip().count("\n") == 0
    assert "matplotlib" in res.output


def test_cli_rejects_unknown_experiment():
    """Bad input: one line naming the value and the choices, exit 2, no traceback."""
    res = CliRunner().invoke(main, ["reproduce", "seed002"])
    assert res.exit_code == 2, res.output
    assert isinstance(res.exception, SystemExit)  # not an exception escaping the command
    line = res.output.strip()
    assert line.count("\n") == 0 and line.startswith("guardid: error: "), res.output
    assert "'seed002'" in line and "seed001-table1" in line and "Traceback" not in line


# --- stochastic rows over seeds, and a std that covers the error (issue 27 item 4) ---------


def test_seed001_rows_are_median_and_worst_over_15_seeds(table1):
    """Every estimate is a noise draw: the tables give the median and the worst over the
    seeds, recomputed here with numpy from the per-seed estimates against the paper's values
    (TABLE1, Table 1's 'actual' column)."""
    from guardid.dynamics.planar import TABLE1

    s = table1.summary
    assert s["seeds"] == list(range(15))
    for name, est in s["estimates_per_seed"].items():
        assert est.shape == (15, 5), name
        err = TABLE1 - est
        np.testing.assert_allclose(s["error_median"][name], np.median(err, axis=0))
        worst = err[np.argmax(np.abs(err), axis=0), np.arange(5)]
        np.testing.assert_allclose(s["error_worst"][name], worst)
        np.testing.assert_allclose(s["pct_error"][name], 100 * np.abs(err).max(0) / TABLE1)
    text = table1.text()
    assert "median over 15 seeds" in text and "worst (largest |value|) over 15 seeds" in text
    assert "median / worst over 15 seeds" in text


def test_seed001_ls_std_covers_its_error_against_the_papers_truth(table1):
    """LS's formula std alone is 20x smaller than its error on th1 (the conditioning's bias:
    the same in every seed, not noise); the printed 'std with that bias' covers the error of
    every seed against the paper's truth within 3 of it. Truth: TABLE1 (the paper's values)."""
    from guardid.dynamics.planar import TABLE1

    s = table1.summary
    err = TABLE1 - s["estimates_per_seed"]["LS"]  # (15, 5)
    std = np.median(s["ls_std_per_seed"], axis=0)
    assert np.abs(err[:, 0]).max() / std[0] > 10  # the formula std does not cover th1
    with_bias = s["ls_cover"]["std_with_bias"]
    np.testing.assert_allclose(with_bias**2, std**2 + s["ls_cover"]["bias_noise_free"] ** 2)
    assert np.all(np.abs(err) <= 3 * with_bias[None, :]), np.abs(err).max(0) / with_bias
    # the bias is systematic: the mean error over seeds is close to the noise-free one
    spread = err.std(axis=0, ddof=1)
    bias_nf = s["ls_cover"]["bias_noise_free"]
    assert np.all(np.abs(err.mean(0) - bias_nf) < 4 * spread / np.sqrt(15) + 3e-4)
    assert "std with the no-noise error" in table1.text()


def test_seed000_fast_noisy_rows_are_median_and_worst(fast):
    """One noise draw can look perfect (seed 0: amplitude ratio 1.000 at beta = 1e-4; seed 1:
    0.969, lag 0.128 rad): the noisy rows are the median and the worst over the seeds,
    recomputed here from the per-seed figures."""
    s = fast.summary
    assert s["seeds"] == [0, 1, 2]
    r = s[("noisy", seed000_fast.BETA_SMALL)]
    ratios = np.array([x["amp_ratio"] for x in r["per_seed"]])
    lags = np.array([x["lag"] for x in r["per_seed"]])
    assert r["median"]["amp_ratio"] == pytest.approx(np.median(ratios))
    assert r["worst"]["amp_ratio"] == ratios[np.argmax(np.abs(ratios - 1))]
    assert r["worst"]["lag"] == lags[np.argmax(np.abs(lags))]
    assert abs(r["worst"]["amp_ratio"] - 1) > 0.02  # seed 1's draw shows in the worst row
    assert r["worst"]["rms"] == max(x["rms"] for x in r["per_seed"])
    text = fast.text()
    assert "noisy median (3)" in text and "noisy worst (3)" in text


def test_cli_seeds_option():
    from guardid.reproduce.common import DEFAULT_SEEDS

    cmd = main.get_command(None, "reproduce")
    seeds = next(p for p in cmd.params if p.name == "n_seeds")
    assert seeds.default == DEFAULT_SEEDS >= 15
    res = CliRunner().invoke(main, ["reproduce", "seed001-table1", "--seeds", "0"])
    assert res.exit_code == 2 and "--seeds" in res.output
    res = CliRunner().invoke(main, ["reproduce", "--help"])
    assert "--seeds" in res.output and "median" in res.output


def test_seed001_momentum_form_std_covers_its_error_without_a_bias_term(table1):
    """LS-mom (nothing differentiated twice, one filter on both sides): over 15 seeds its
    own std covers its error against the paper's truth (every seed within 3 std) and its mean
    error is a fraction of its std (the acceleration form's is 20x its std on th1), with a
    spread over seeds of the size of the std (neither too small nor 3x too large).
    Truth: TABLE1."""
    from guardid.dynamics.planar import TABLE1

    s = table1.summary
    est, std = s["estimates_per_seed"]["LS-mom"], s["std_per_seed"]["LS-mom"]
    err = TABLE1 - est
    assert np.all(np.abs(err) <= 3 * std), (np.abs(err) / std).max(0)
    assert np.all(np.abs(err.mean(0)) < 0.8 * np.median(std, 0))
    ratio = err.std(0, ddof=1) / np.median(std, 0)
    assert np.all((ratio > 0.4) & (ratio < 1.6)), ratio
    acc = TABLE1 - s["estimates_per_seed"]["LS"]
    assert np.abs(acc.mean(0))[0] > 10 * np.median(s["std_per_seed"]["LS"], 0)[0]
    assert "LS-mom (filtered momentum form)" in table1.text()
