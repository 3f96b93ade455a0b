"""An error that repeats every excitation period is counted in the least squares std.

Truth: the estimates' spread over seeded numpy draws (an independent Monte Carlo of the
model y = A theta + c[phase] + white), the one-way ANOVA worked out by hand, phase labels
written out by hand, and the log header's excitation period (1 / base_freq).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from guardid.estimators import LeastSquares, WeightedLeastSquares
from guardid.estimators.ls import _anova_sums, _common_variances
from guardid.identify.rows import period_groups
from guardid.identify.runs import load_run, trajectory_period

PERIODS, PHASES = 12, 30  # rows: 12 periods of 30 phases


def _draws(n_draws: int, common_sd, seed: int = 7, periods: int = PERIODS, mask=None):
    """Per draw (A (M, 2, 3), y (M, 2)) with the regressor repeating every period (a
    periodic excitation), a common error per phase (sd ``common_sd``, scalar or per joint)
    and white noise of sd 0.5 (joint 0) and 1.0 (joint 1); theta = (1, -2, 0.5); ``mask``
    (2, 3): columns left out of a joint's equation (0)."""
    rng = np.random.default_rng(seed)
    phase = np.tile(np.arange(PHASES), periods)
    s = 2 * np.pi * phase / PHASES
    A = np.zeros((phase.size, 2, 3))
    A[:, 0, :] = np.column_stack([np.sin(s), np.cos(2 * s), np.ones_like(s)])
    A[:, 1, :] = np.column_stack([np.cos(s), np.sin(3 * s), np.sign(np.sin(s) + 0.1)])
    A += 0.05 * rng.standard_normal(A.shape)  # the motion varies a little from period to period
    if mask is not None:
        A *= np.asarray(mask, dtype=float)
    theta = np.array([1.0, -2.0, 0.5])
    out = []
    for _ in range(n_draws):
        common = common_sd * rng.standard_normal((PHASES, 2))[phase]
        white = rng.standard_normal((phase.size, 2)) * np.array([0.5, 1.0])
        out.append((A, A @ theta + common + white))
    return phase, theta, out


def _spread_over_std(estimator, phase, theta, draws):
    """(spread of the estimates over the draws / their mean reported std) per parameter."""
    est = [estimator().fit(A, y) for A, y in draws]
    values = np.array([e.theta_ for e in est])
    return values.std(axis=0, ddof=1) / np.mean([e.std_ for e in est], axis=0)


@pytest.mark.parametrize("cls", [LeastSquares, WeightedLeastSquares])
def test_std_covers_an_error_that_repeats_every_period(cls):
    phase, theta, draws = _draws(300, common_sd=0.4)
    grouped = _spread_over_std(lambda: cls(row_groups=phase), phase, theta, draws)
    plain = _spread_over_std(cls, phase, theta, draws)
    assert np.all(plain > 1.5)  # the rows' own std misses the repeating part
    assert np.all((grouped > 0.85) & (grouped < 1.15)), grouped


@pytest.mark.parametrize("cls", [LeastSquares, WeightedLeastSquares])
def test_without_a_repeating_error_the_std_stays_the_rows_own(cls):
    phase, theta, draws = _draws(300, common_sd=0.0, seed=8)
    grouped = _spread_over_std(lambda: cls(row_groups=phase), phase, theta, draws)
    assert np.all((grouped > 0.85) & (grouped < 1.15)), grouped
    A, y = draws[0]
    g, p = cls(row_groups=phase).fit(A, y), cls().fit(A, y)
    np.testing.assert_array_equal(g.theta_, p.theta_)  # the estimate is not touched
    assert np.all(g.std_ >= p.std_) and np.all(g.std_ < 1.2 * p.std_)


def test_repeating_std_per_output_estimates_the_common_part():
    phase, theta, draws = _draws(40, common_sd=0.4, seed=9)
    taus = np.array([WeightedLeastSquares(row_groups=phase).fit(A, y)
                     .repeating_std_per_output_ for A, y in draws])  # fmt: skip
    np.testing.assert_allclose(np.median(taus, axis=0), 0.4, rtol=0.2)


def _tau2_of_a_mean(e, label):
    """tau^2 when the only column is a constant (the classical one-way ANOVA's model)."""
    ones = np.ones((len(e), 1))
    return _common_variances([(ones, np.asarray(e, float), np.asarray(label))],
                             np.array([[1.0 / len(e)]]))[0]  # fmt: skip


def test_common_variance_by_hand():
    # groups (1, 3) and (5, 7): means 2 and 6, grand mean 4; SSB = 2 (2 - 4)^2 + 2 (6 - 4)^2
    # = 16, SSW = 4; with a fitted mean the moments are the classical ANOVA's: MSW = 4 / 2
    # = 2, MSB = 16, n0 = (4 - 8 / 4) / 1 = 2: tau^2 = (16 - 2) / 2 = 7
    label = np.array([0, 0, 1, 1])
    ssb, ssw, n = _anova_sums(np.array([1.0, 3.0, 5.0, 7.0]), label)
    assert (ssb, ssw) == pytest.approx((16.0, 4.0)) and list(n) == [2, 2]
    assert _tau2_of_a_mean([1.0, 3.0, 5.0, 7.0], label) == pytest.approx(7.0)
    # equal group means: MSB = 0 < MSW, clipped at 0
    assert _tau2_of_a_mean([1.0, -1.0, 1.0, -1.0], label) == 0.0
    # one row per group: nothing repeats
    assert _tau2_of_a_mean([1.0, 2.0, 3.0], np.arange(3)) == 0.0


def test_common_variance_unbalanced_by_hand():
    # groups (1, 3) and (5): means 2 and 5, grand mean 3; MSW = 2 / (3 - 2) = 2,
    # MSB = 2 (2 - 3)^2 + 1 (5 - 3)^2 = 6, n0 = (3 - (4 + 1) / 3) / 1 = 4 / 3:
    # tau^2 = (6 - 2) / (4 / 3) = 3 (the mean group size 1.5 would give 8 / 3)
    assert _tau2_of_a_mean([1.0, 3.0, 5.0], [0, 0, 1]) == pytest.approx(3.0)


def test_few_groups_and_many_columns():
    # 10 phases and 6 columns that repeat every period: the fit takes up much of the
    # common error's group directions, which a plain ANOVA of the residuals would read as
    # a small tau (std too small); the moments that account for the fit do not
    rng = np.random.default_rng(31)
    phases, periods, p = 10, 30, 6
    phase = np.tile(np.arange(phases), periods)
    base = rng.standard_normal((phases, 1, p))
    A = base[phase] + 0.05 * rng.standard_normal((phase.size, 1, p))
    theta = rng.standard_normal(p)
    fits = []
    for _ in range(300):
        y = A @ theta + 0.5 * rng.standard_normal((phases, 1))[phase]
        fits.append(LeastSquares(row_groups=phase).fit(A, y + 0.3 * rng.standard_normal(y.shape)))
    ratio = np.array([f.theta_ for f in fits]).std(axis=0, ddof=1) / np.mean(
        [f.std_ for f in fits], axis=0)  # fmt: skip
    assert np.all((ratio > 0.8) & (ratio < 1.2)), ratio
    assert np.median([f.repeating_std_per_output_[0] for f in fits]) == pytest.approx(0.5, rel=0.25)


def test_unbalanced_groups_and_a_cut_joint():
    # groups of 1 to 3 rows whose regressor repeats within the group, a large common error
    # (sd 1) against the white (0.3, 0.6): the groups' sums hold most of the covariance, so
    # counting a group's own rows twice (the white part is already in the pooled sigma^2)
    # would show; joint 1's equation cut on a third of the rows (rows of zeros: A and y),
    # which must not dilute its common part
    rng = np.random.default_rng(21)
    sizes = rng.integers(1, 4, 160)
    label = np.repeat(np.arange(sizes.size), sizes)
    A = rng.standard_normal((sizes.size, 2, 3))[label] + 0.1 * rng.standard_normal(
        (label.size, 2, 3)
    )
    cut = np.arange(label.size) % 3 == 0
    A[cut, 1, :] = 0.0
    theta, tau = np.array([1.0, -2.0, 0.5]), np.array([1.0, 1.0])
    est, std, taus = [], [], []
    for _ in range(300):
        common = tau * rng.standard_normal((sizes.size, 2))[label]
        y = A @ theta + common + rng.standard_normal((label.size, 2)) * np.array([0.3, 0.6])
        y[cut, 1] = 0.0
        fit = WeightedLeastSquares(row_groups=label).fit(A, y)
        est.append(fit.theta_), std.append(fit.std_), taus.append(fit.repeating_std_per_output_)
    ratio = np.std(est, axis=0, ddof=1) / np.mean(std, axis=0)
    assert np.all((ratio > 0.9) & (ratio < 1.15)), ratio  # counted twice: 0.83-0.89
    np.testing.assert_allclose(np.median(taus, axis=0), tau, rtol=0.1)


def test_row_groups_must_match_the_rows():
    A = np.random.default_rng(1).standard_normal((20, 2))
    with pytest.raises(ValueError, match="row_groups"):
        LeastSquares(row_groups=np.zeros(19, dtype=int)).fit(A, A @ np.ones(2))


def _cond(t, mask=None):
    t = np.asarray(t, dtype=float)
    return SimpleNamespace(t=t, mask=np.ones(t.size, bool) if mask is None else mask)


def test_period_groups_by_hand():
    # rows every 0.25 s over three periods of 1 s: four phases, labels 0 1 2 3 0 1 2 3 ...
    a = _cond(np.arange(12) * 0.25)
    np.testing.assert_array_equal(period_groups([a], [1.0]), np.tile([0, 1, 2, 3], 3))
    # a masked row drops out; a second run's labels follow the first's; a run without a
    # period (or shorter than two periods) has a group per row
    mask = np.ones(12, bool)
    mask[5] = False
    b, short = _cond(np.arange(12) * 0.25, mask), _cond(np.arange(6) * 0.25)
    got = period_groups([b, short, a], [1.0, 1.0, None])
    want = np.concatenate([[0, 1, 2, 3, 0, 2, 3, 0, 1, 2, 3], 4 + np.arange(6), 10 + np.arange(12)])
    np.testing.assert_array_equal(got, want)
    assert period_groups([a, short], [None, 1.0]) is None


def test_trajectory_period():
    assert trajectory_period({"kind": "fourier", "base_freq": 0.25, "harmonics": 5}) == 4.0
    sines = {"kind": "sines", "frequencies": [[0.1, 0.3], [0.2]]}
    assert trajectory_period(sines) == pytest.approx(10.0)
    assert trajectory_period({"kind": "sines", "frequencies": [[0.1, 0.1 * np.sqrt(2)]]}) is None
    assert trajectory_period(None) is None
    assert trajectory_period({"kind": "fourier"}) is None


def test_a_capture_log_is_grouped_by_its_excitation_period(gap_guard_captures, tmp_path):
    log = gap_guard_captures[1]
    header = yaml.safe_load("\n".join(line[2:] for line in log.read_text().splitlines()
                                      if line.startswith("# ")))  # fmt: skip
    run = load_run(log)
    assert run.excitation_period_s == pytest.approx(1.0 / header["trajectory"]["base_freq"])
    from guardid.identify.pipeline import IdentifyOptions, identify
    from guardid.robot import load_robot

    result = identify([run], load_robot("guard"), IdentifyOptions(methods=("ls", "wls")))
    for m in ("ls", "wls"):
        rep = result.results[m].settings["repeating_residual"]
        assert len(rep["std_per_joint"]) == 2 and all(x >= 0 for x in rep["std_per_joint"])
        share = rep["variance_share"]
        assert len(share) == len(result.names) and all(0.0 <= x <= 1.0 for x in share)
        # groups: about one per row spacing of the period (the spacing recorded, in ticks)
        spacing = result.conditioning.decimate * run.sample_period_s
        assert 0.5 * run.excitation_period_s / spacing <= rep["groups"]
        assert rep["groups"] <= 1.5 * run.excitation_period_s / spacing

    # the command's line: said when the reference method (WLS) has a repeating part, not when
    # it has none
    from guardid.commands.identify import _repeating_line

    result.results["wls"].settings["repeating_residual"] = {
        "groups": 40,
        "std_per_joint": [0.002, 0.0],
    }
    line = _repeating_line(result, load_robot("guard"))
    assert line.startswith("WLS: its std counts an error that repeats every excitation period")
    assert "pan 0.002, tilt 0 N m per row, over 40 phase groups;" in line
    share = [0.0] * len(result.names)
    share[3] = 0.25
    result.results["wls"].settings["repeating_residual"]["variance_share"] = share
    line = _repeating_line(result, load_robot("guard"))
    assert f"up to 25 % of a parameter's variance ({result.names[3]})" in line
    result.results["wls"].settings["repeating_residual"]["std_per_joint"] = [0.0, 0.0]
    assert _repeating_line(result, load_robot("guard")) == ""


@pytest.mark.parametrize("period_ticks, row_ticks", [(320, 16), (200, 8), (800, 40)])
def test_rows_of_one_phase_share_one_group_on_the_tick_grid(period_ticks, row_ticks):
    # a period a whole number of row spacings (4.8 s = 20 rows of 16 ticks of 15 ms): the
    # rows repeat at exactly the same phases, which sit on the bins' edges; rounding must
    # not scatter one phase over two groups (nor put two phases in one), whatever the
    # first row's tick
    for first in range(row_ticks):
        ticks = first + row_ticks * np.arange(30 * period_ticks // row_ticks)
        got = period_groups([_cond(ticks * 0.015)], [period_ticks * 0.015])
        phase = ticks % period_ticks  # the same point of the trajectory, in whole ticks
        pairs = np.unique(np.column_stack([phase, got]), axis=0)
        assert len(pairs) == len(np.unique(phase)) == len(np.unique(got)), first


def test_runs_from_arrays_name_their_period(gap_guard_captures):
    # the Python API's runs (notebooks, simulations) are grouped as a capture log is when
    # given the period; without it, not
    from guardid.identify import IdentifyOptions, identify, run_from_arrays
    from guardid.robot import load_robot

    log = load_run(gap_guard_captures[1])
    kw = {"ticks": log.ticks, "highest_harmonic_hz": log.highest_harmonic_hz}
    options, guard = IdentifyOptions(methods=("wls",)), load_robot("guard")
    for period, grouped in ((log.excitation_period_s, True), (None, False)):
        run = run_from_arrays(log.t, log.q, log.current, excitation_period_s=period, **kw)
        settings = identify([run], guard, options).results["wls"].settings
        assert ("repeating_residual" in settings) is grouped


def test_the_groups_counted_are_the_phases_not_the_ungrouped_rows():
    # a run over three periods (four phases) stacked with a short run (six rows, a group
    # each): params.yaml and the notes say 4 phase groups, not 10
    from guardid.identify.methods import repeating_settings
    from guardid.identify.rows import phase_group_count

    groups = period_groups([_cond(np.arange(12) * 0.25), _cond(np.arange(6) * 0.25)], [1.0, 1.0])
    assert phase_group_count(groups) == 4
    est = SimpleNamespace(repeating_std_per_output_=np.zeros(2))
    assert repeating_settings(est, groups)["repeating_residual"]["groups"] == 4


# -- the share of the variance that repeats, and what a longer run does to it -------------


def test_repeating_share_by_hand():
    # the constant column alone, groups (1, 3), (5, 7), (4, 6): means 2, 6, 5, grand mean
    # 13 / 3; SSB = 2 (49 + 25 + 4) / 9 = 52 / 3, SSW = 6; MSB = 26 / 3, MSW = 2, n0 = 2:
    # tau^2 = (26 / 3 - 2) / 2 = 10 / 3. The mean's variance: s^2 / N with s^2 = (SSB + SSW)
    # / 5 = 14 / 3, plus tau^2 (sum n_g^2 - N) / N^2 = (10 / 3) 6 / 36: 7 / 9 + 5 / 9 = 4 / 3.
    # The common part's whole share: tau^2 sum n_g^2 / N^2 = 10 / 9, over 4 / 3: 5 / 6 (the
    # white part, (s^2 - tau^2) / N = 2 / 9, the rest)
    est = LeastSquares(row_groups=np.array([0, 0, 1, 1, 2, 2])).fit(
        np.ones((6, 1)), np.array([1.0, 3.0, 5.0, 7.0, 4.0, 6.0])
    )
    assert est.repeating_std_per_output_[0] ** 2 == pytest.approx(10.0 / 3.0)
    assert est.cov_[0, 0] == pytest.approx(4.0 / 3.0)
    assert est.repeating_share_[0] == pytest.approx(5.0 / 6.0)
    # nothing common: no share
    flat = LeastSquares(row_groups=np.array([0, 0, 1, 1])).fit(
        np.ones((4, 1)), np.array([1.0, -1.0, 1.0, -1.0])
    )
    assert flat.repeating_share_[0] == 0.0
    # a sample added afterwards: the groups no longer describe the rows; the mean of all
    # seven is 30 / 7 and its variance the white one, s^2 / 7 with s^2 their sample variance
    est.update(np.ones((1, 1)), np.array([4.0]))
    assert not hasattr(est, "repeating_share_") and not hasattr(est, "repeating_std_per_output_")
    assert est.theta_[0] == pytest.approx(30.0 / 7.0)
    assert est.cov_[0, 0] == pytest.approx((sum((v - 30.0 / 7.0) ** 2 for v in
                                                 (1, 3, 5, 7, 4, 6, 4)) / 6.0) / 7.0)  # fmt: skip


def _exact_share(A, phase, common_sd):
    """The share of each LS parameter's variance that the common part makes, from the
    model of :func:`_draws` (white sd 0.5 and 1.0, common sd per joint), in numpy."""
    Hi = np.linalg.inv(np.einsum("nja,njb->ab", A, A))
    white, common = np.zeros((3, 3)), np.zeros((3, 3))
    for j, (sd_white, sd_common) in enumerate(zip((0.5, 1.0), common_sd, strict=True)):
        sums = np.zeros((PHASES, 3))
        np.add.at(sums, phase, A[:, j, :])
        white += sd_white**2 * A[:, j, :].T @ A[:, j, :]
        common += sd_common**2 * sums.T @ sums
    return np.diag(Hi @ common @ Hi) / np.diag(Hi @ (white + common) @ Hi)


def test_repeating_share_is_the_models():
    # both joints' rows inform every parameter: the median share over the draws is the
    # model's to a few per cent (without the common part's own rows' term, 1 - 1/12 of it)
    sd = np.array([0.4, 0.25])
    phase, _, data = _draws(200, sd, seed=31)
    shares = [LeastSquares(row_groups=phase).fit(A, y).repeating_share_ for A, y in data]
    exact = _exact_share(data[0][0], phase, sd)
    np.testing.assert_allclose(np.median(shares, axis=0), exact, rtol=0.04)
    # a parameter only joint 0 informs (its common part large) against one only joint 1
    # informs (small): the shares follow the parameters
    sd = np.array([0.4, 0.1])
    phase, _, data = _draws(200, sd, seed=32, mask=[[1, 0, 1], [0, 1, 1]])
    shares = np.median(
        [LeastSquares(row_groups=phase).fit(A, y).repeating_share_ for A, y in data], axis=0
    )
    exact = _exact_share(data[0][0], phase, sd)
    assert exact[0] > 0.8 and exact[1] < 0.2
    assert shares[0] > 0.65 and shares[1] < 0.25, shares


def _spread(periods, draws, common_sd, seed):
    """(spread of LS estimates over the draws (3,), median repeating share (3,)) with
    ``periods`` periods of :func:`_draws`' regressor and common error."""
    phase, _, data = _draws(draws, common_sd, seed, periods)
    fits = [LeastSquares(row_groups=phase).fit(A, y) for A, y in data]
    values = [f.theta_ for f in fits]
    return np.std(values, axis=0, ddof=1), np.median([f.repeating_share_ for f in fits], axis=0)


def test_the_share_that_repeats_is_what_a_longer_run_does_not_reduce():
    # twice the periods halve the rows' own variance and leave the common part's: the
    # spread's ratio is sqrt((1 - s) / 2 + s), s the share, not 1 / sqrt(2)
    short, share = _spread(12, 400, common_sd=0.25, seed=21)
    long, _ = _spread(24, 400, common_sd=0.25, seed=22)
    predicted = np.sqrt((1.0 - share) / 2.0 + share)
    assert np.all((share > 0.2) & (share < 0.8)), share
    np.testing.assert_allclose(long / short, predicted, rtol=0.1)
    assert np.all(long / short > 1.1 / np.sqrt(2.0))


def test_poorly_identifiable_says_what_would_help():
    from guardid.identify.pipeline import poorly_identifiable

    names = ("a", "b", "c", "d")
    got = poorly_identifiable(names, [5.0, 40.0, 40.0, float("nan")], [0.9, 0.49, 0.5, 0.9])
    assert len(got) == 2  # 5 % is identified; an undefined relative std is not judged
    assert got[0] == (
        "b: relative standard deviation 40 % (poorly identifiable; a richer excitation or "
        "a longer run would help)"
    )
    assert got[1].startswith("c: relative standard deviation 40 % (poorly identifiable; 50 %")
    assert "a longer run of the same excitation does not average out" in got[1]
    assert "another excitation would help" in got[1]
    # without groups, the plain advice
    plain = poorly_identifiable(names[:1], [40.0])
    assert plain[0].endswith("a richer excitation or a longer run would help)")


def test_identify_tells_a_repeating_variance_in_its_warnings(gap_guard_captures, monkeypatch):
    # with the threshold at a hair above 0, every poorly identified parameter with any
    # repeating share is told so: the share reaches the warnings from the verdict's method
    from guardid.identify import pipeline
    from guardid.identify.pipeline import IdentifyOptions, identify
    from guardid.robot import load_robot

    monkeypatch.setattr(pipeline, "REPEATING_SHARE", 1e-9)
    run = load_run(gap_guard_captures[3])  # seed 3: both joints have a repeating part
    result = identify([run], load_robot("guard"), IdentifyOptions(methods=("wls",)))
    share = result.results["wls"].settings["repeating_residual"]["variance_share"]
    poor = [w for w in result.warnings if "poorly identifiable" in w]
    assert poor and any(s > 0 for s in share)
    for w in poor:
        k = result.names.index(w.split(":")[0])
        assert ("repeats every excitation period" in w) is (share[k] > 0), w


@pytest.mark.parametrize("cls", [LeastSquares, WeightedLeastSquares])
def test_a_column_the_rows_never_excite_leaves_the_std_not_finite(cls):
    """A joint that never moved gives zero columns: the fit still ends (its white
    covariance is not finite and stays so; the trust checks name the columns) instead of
    failing in the error model's decompositions (SVD / eigh did not converge: a traceback
    from identify before). Finite columns and a structure: a finite std, as before."""
    rng = np.random.default_rng(3)
    N, p = 400, 3
    A = rng.normal(size=(N, 2, p))
    A[:, :, 2] = 0.0  # nothing excites the third parameter
    y = A @ np.array([1.0, -2.0, 0.5]) + rng.normal(scale=0.1, size=(N, 2))
    kw = {"row_groups": np.arange(N) % 20}
    est = cls(**kw).fit(A, y)
    assert not np.isfinite(est.std_[2])
    A[:, :, 2] = rng.normal(size=(N, 2))
    assert np.all(np.isfinite(cls(**kw).fit(A, y).std_))
