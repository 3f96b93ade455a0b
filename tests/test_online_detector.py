"""The residual-CUSUM change detector on synthetic streams (no robot, no estimator needed).

A stream is a row every 15 ms of two joint equations: a-priori residuals (Gaussian, a
different scale per joint, plus an optional bias step) and the estimate of
(MX2R, MY2, Fv2) (old values plus small noise, optionally moving to new values). The
detector is driven as :class:`guardid.online.OnlineIdentifier` drives it: ``update`` on
every row, then ``settled`` while it is settling after an alarm.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from guardid.online import ChangeDetector, DetectorSettings
from guardid.online.detector import GAP_S, Alarm

DT = 0.015
NAMES = ("MX2R", "MY2", "Fv2")
UNITS = ("kg m", "kg m", "N m s/rad")
SCALES = np.array([0.5, 2.0])  # residual sigma of the two joints [N m]
OLD = np.array([0.77, 0.07, 0.5])
NEW = np.array([0.99, 0.09, 0.6])
SETTINGS = DetectorSettings(holdoff_s=10.0, reference_s=5.0, settle_s=5.0, new_s=1.0)
BOTH = np.array([True, True])


def index(t_s: float) -> int:
    """The row index of time ``t_s`` [s]."""
    return round(t_s / DT)


def make_stream(seed=0, seconds=60.0, bias=(), steps=()):
    """Rows ``t`` (N,), residuals (N, 2), estimates (N, 3).

    ``bias``: (t_from, t_to, joint, m) adds m sigma to that joint's residual in [t_from, t_to);
    ``steps``: (t_at, before, after) moves the estimate from ``before`` to ``after`` at t_at
    (exponential transition, 0.3 s time constant)."""
    rng = np.random.default_rng(seed)
    t = np.arange(index(seconds)) * DT
    residual = rng.normal(size=(len(t), 2)) * SCALES
    for t_from, t_to, joint, m in bias:
        residual[index(t_from) : index(t_to), joint] += m * SCALES[joint]
    theta = np.tile(OLD, (len(t), 1))
    for t_at, before, after in steps:
        k = index(t_at)
        ramp = 1.0 - np.exp(-(t[k:] - t[k]) / 0.3)
        theta[k:] += ramp[:, None] * (np.asarray(after) - np.asarray(before))
    theta *= 1.0 + 0.002 * rng.normal(size=theta.shape)
    return t, residual, theta


def window(t, begin_s: float, seconds: float) -> slice:
    """The rows of a reference window (module docstring of guardid.online.detector): it
    starts at the first row at or after ``begin_s`` [s] (that row itself not counted) and
    takes the rows after it up to and including the first ``seconds`` or more later."""
    k0 = int(np.argmax(t >= begin_s))
    k1 = k0 + 1 + int(np.argmax(t[k0 + 1 :] - t[k0] >= seconds))
    return slice(k0 + 1, k1 + 1)


def window_rms(t, residual, begin_s: float) -> np.ndarray:
    """Each joint's residual rms (2,) over the reference window from ``begin_s``."""
    return np.sqrt(np.mean(residual[window(t, begin_s, SETTINGS.reference_s)] ** 2, axis=0))


def drive(det, t, residual, theta):
    """Feed every row; returns the alarms and the reports in order."""
    alarms, reports = [], []
    for ti, ei, thi in zip(t, residual, theta, strict=True):
        alarm = det.update(ti, BOTH, ei, thi)
        if alarm is not None:
            alarms.append(alarm)
        if det.state == "settling":
            rep = det.settled(ti, thi)
            if rep is not None:
                reports.append(rep)
    return alarms, reports


def detector(**kw):
    settings = dataclasses.replace(SETTINGS, **kw)
    return ChangeDetector(NAMES, n_joints=2, method="rls", settings=settings, units=UNITS)


@pytest.mark.parametrize("seed", range(5))
def test_quiet_stream_gives_no_alarm_and_no_report(seed):
    det = detector()
    t, residual, theta = make_stream(seed=seed)
    alarms, reports = drive(det, t, residual, theta)
    assert alarms == [] and reports == []
    assert det.state == "armed"
    # each joint's own residual scale was learnt in the reference window (the rms of its
    # residuals there, computed here; about the stream's scales: 334 rows, ~4 % sampling)
    assert det.sigma == pytest.approx(window_rms(t, residual, SETTINGS.holdoff_s), rel=1e-9)
    assert det.sigma == pytest.approx(SCALES, rel=0.2)


@pytest.mark.parametrize("seed", range(3))
def test_step_gives_an_alarm_and_a_report_with_time_and_values(seed):
    # the residual is biased until the estimator has caught up (about 1 s)
    t, residual, theta = make_stream(
        seed=seed, bias=[(30.0, 31.0, 0, 20.0)], steps=[(30.0, OLD, NEW)]
    )
    det = detector()
    alarms, reports = drive(det, t, residual, theta)

    assert len(alarms) == 1
    alarm = alarms[0]
    assert isinstance(alarm, Alarm)
    assert abs(alarm.time_s - 30.0) <= 2 * DT + 1e-9
    assert 30.0 <= alarm.alarm_s <= 30.0 + 5 * DT

    assert len(reports) == 1
    rep = reports[0]
    assert rep.method == "rls"
    assert rep.time_s == alarm.time_s and rep.alarm_s == alarm.alarm_s
    assert rep.report_s >= rep.time_s + SETTINGS.settle_s
    assert rep.report_s < rep.time_s + SETTINGS.settle_s + 2 * DT
    assert rep.names == ("MX2R", "MY2")  # the first moments, not Fv2
    assert rep.units == ("kg m", "kg m")
    assert rep.before == pytest.approx(OLD[:2], rel=0.01)
    assert rep.after == pytest.approx(NEW[:2], rel=0.01)
    # "after" is the mean over the last new_s before the report, not one noisy row
    last = (t > rep.report_s - SETTINGS.new_s - 1e-9) & (t <= rep.report_s + 1e-9)
    assert rep.after == pytest.approx(theta[last, :2].mean(axis=0), rel=1e-9)
    # the watched estimates' spread (std) over the reference window
    ref = theta[window(t, SETTINGS.holdoff_s, SETTINGS.reference_s), :2]
    assert rep.sigma == pytest.approx(ref.std(axis=0), rel=1e-9)
    assert rep.sigma == pytest.approx(0.002 * OLD[:2], rel=0.2)

    text = str(rep)
    assert text.startswith("payload changed at 30.0 s (RLS):")
    values = r"MX2R 0\.7[67]\d* -> 0\.9[89]\d* kg m, MY2 0\.0[67]\d* -> 0\.0[89]\d* kg m"
    assert re.fullmatch(r"payload changed at 30\.0 s \(RLS\): " + values, text), text
    assert det.reports == [rep]


def test_alarm_without_moving_estimates_gives_no_report_and_relearns():
    t, residual, theta = make_stream(bias=[(30.0, 31.0, 1, 20.0)])
    det = detector()
    end = index(30.0 + SETTINGS.settle_s + 0.5)
    alarms, reports = drive(det, t[:end], residual[:end], theta[:end])
    assert len(alarms) == 1 and abs(alarms[0].time_s - 30.0) <= 2 * DT + 1e-9
    assert reports == [] and det.reports == []
    # armed again at once (old residual scales) while it learns a fresh reference, with no
    # further alarm on the quiet rest
    assert det.state == "armed"
    alarms, reports = drive(det, t[end:], residual[end:], theta[end:])
    assert alarms == [] and reports == []
    # the fresh reference: the window from settle_s after the alarm
    fresh = window_rms(t, residual, det.alarms[0].latest_s + SETTINGS.settle_s)
    assert det.state == "armed" and det.sigma == pytest.approx(fresh, rel=1e-9)


def test_nothing_is_watched_during_the_holdoff():
    t, residual, theta = make_stream(bias=[(2.0, 9.5, 0, 1000.0)], steps=[(2.0, OLD, NEW)])
    det = detector()
    alarms, reports = drive(det, t, residual, theta)
    assert alarms == [] and reports == []
    assert det.state == "armed"
    # the reference is after the hold-off: the bias before it is not in the scales
    assert det.sigma == pytest.approx(window_rms(t, residual, SETTINGS.holdoff_s), rel=1e-9)


def test_two_changes_give_two_alarms_and_two_reports():
    mid = (OLD + NEW) / 2
    t, residual, theta = make_stream(
        bias=[(30.0, 31.0, 0, 20.0), (50.0, 51.0, 1, -20.0)],
        steps=[(30.0, OLD, mid), (50.0, mid, NEW)],
    )
    det = detector()
    alarms, reports = drive(det, t, residual, theta)
    assert len(alarms) == 2 and len(reports) == 2
    for alarm, rep, t_change in zip(alarms, reports, (30.0, 50.0), strict=True):
        assert abs(alarm.time_s - t_change) <= 2 * DT + 1e-9
        assert rep.time_s == alarm.time_s
    assert reports[0].before == pytest.approx(OLD[:2], rel=0.01)
    assert reports[0].after == pytest.approx(mid[:2], rel=0.01)
    assert reports[1].before == pytest.approx(mid[:2], rel=0.01)
    assert reports[1].after == pytest.approx(NEW[:2], rel=0.01)


def test_a_change_soon_after_the_settling_is_caught():
    """Re-armed with the old residual scales right after settling: a second change 1 s
    after that (6 s after the first) is caught, though no fresh reference exists yet."""
    second = 30.0 + SETTINGS.settle_s + 1.0
    t, residual, theta = make_stream(
        bias=[(30.0, 31.0, 0, 20.0), (second, second + 1.0, 1, -20.0)],
        steps=[(30.0, OLD, NEW), (second, NEW, OLD)],
    )
    alarms, reports = drive(detector(), t, residual, theta)
    assert [round(a.time_s, 1) for a in alarms] == [30.0, second]
    assert len(reports) == 2 and reports[1].after == pytest.approx(OLD[:2], rel=0.01)


def test_a_change_while_the_joint_is_at_rest_is_reported_as_the_interval():
    """Joint 1 has no rows from 29 s to 31 s (held near stiction) and the change happens at
    30 s: the alarm dates it from its last row before the gap to its first row after it, the
    report names that interval, and the new values are taken 5 s after the gap's end."""
    t, residual, theta = make_stream(bias=[(31.0, 32.0, 1, 20.0)], steps=[(31.0, OLD, NEW)])
    det = detector()
    alarms, reports = [], []
    for ti, ei, thi in zip(t, residual, theta, strict=True):
        rows = np.array([True, not 29.0 <= ti < 31.0])
        alarm = det.update(ti, rows, ei[rows], thi)
        alarms += [alarm] if alarm is not None else []
        rep = det.settled(ti, thi)
        reports += [rep] if rep is not None else []
    (alarm,) = alarms
    assert alarm.time_s == pytest.approx(29.0, abs=DT) and alarm.latest_s == pytest.approx(
        31.0, abs=DT
    )
    (rep,) = reports
    assert rep.report_s == pytest.approx(31.0 + SETTINGS.settle_s, abs=2 * DT)
    assert str(rep).startswith("payload changed between 29.0 and 31.0 s (joint at rest")
    assert rep.at_s == pytest.approx(30.0, abs=DT)
    assert rep.after == pytest.approx(NEW[:2], rel=0.01)


def test_a_change_in_a_short_gap_is_reported_at_its_middle():
    """A gap shorter than GAP_S (the stiction guard around a reversal): one time, the middle."""
    t, residual, theta = make_stream(bias=[(30.2, 31.2, 1, 20.0)], steps=[(30.2, OLD, NEW)])
    det = detector()
    for ti, ei, thi in zip(t, residual, theta, strict=True):
        rows = np.array([True, not 29.9 <= ti < 30.2])
        det.update(ti, rows, ei[rows], thi)
        det.settled(ti, thi)
    (rep,) = det.reports
    assert rep.latest_s - rep.time_s < GAP_S
    assert rep.at_s == pytest.approx(30.05, abs=DT)
    assert str(rep).startswith("payload changed at 30.0 s") or str(rep).startswith(
        "payload changed at 30.1 s"
    )


def test_row_with_one_joint_leaves_the_other_cusum_unchanged():
    s = 0.5
    det = detector(holdoff_s=1.0, reference_s=1.0)
    t = 0.0
    # deterministic residuals: +-s on both joints, so sigma is exactly s
    while det.state != "armed":
        sign = 1.0 if index(t) % 2 else -1.0
        assert det.update(t, BOTH, [sign * s, sign * s], OLD) is None
        t += DT
    assert det.sigma == pytest.approx([s, s], rel=1e-12)

    # joint 0 at 15 sigma: G+ grows by 15 - kappa = 11 per row, 33 after three rows
    t_zero = t - DT  # the last row with G = 0
    for _ in range(3):
        assert det.update(t, BOTH, [15 * s, 0.0], OLD) is None
        t += DT
    # rows with only joint 1 (residual of length 1) must leave joint 0's G at 33
    for _ in range(20):
        assert det.update(t, [False, True], [0.0], OLD) is None
        t += DT
    # one more joint-0 row takes it to 44 > h = 40 (it would be 11 had G decayed)
    alarm = det.update(t, BOTH, [15 * s, 0.0], OLD)
    assert alarm is not None
    assert alarm.time_s == pytest.approx(t_zero) and alarm.alarm_s == pytest.approx(t)


def test_watch_with_an_unknown_name_raises():
    with pytest.raises(ValueError, match="MZ9"):
        ChangeDetector(NAMES, n_joints=2, settings=DetectorSettings(watch=("MX2R", "MZ9")))
    det = ChangeDetector(NAMES, n_joints=2, settings=DetectorSettings(watch=("Fv2",)))
    assert det.names == ("Fv2",)


def test_a_joint_absent_from_the_reference_window_is_not_watched():
    """No rows of joint 1 while the reference is learnt: it has no residual scale, so its
    ordinary residuals afterwards must not fire (joint 0 stays watched)."""
    rng = np.random.default_rng(7)
    det = ChangeDetector(NAMES, n_joints=2, method="rls",
                         settings=DetectorSettings(holdoff_s=1.0, reference_s=1.0))  # fmt: skip
    theta = np.array([0.77, 0.07, 0.5])
    alarms = []
    for k in range(int(10.0 / 0.015)):
        t = k * 0.015
        rows = np.array([True, t > 2.5])
        alarm = det.update(t, rows, rng.normal(size=int(rows.sum())), theta)
        if alarm is not None:
            alarms.append(alarm)
    assert alarms == [] and det.state == "armed"
    assert np.isfinite(det.sigma[0]) and np.isinf(det.sigma[1])
