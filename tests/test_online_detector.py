"""The change detector on synthetic estimate streams (no robot needed)."""

from __future__ import annotations

import numpy as np
import pytest

from guardid.online import ChangeDetector, DetectorSettings, detect_changes

NAMES = ("ZZ1R", "MX2R", "MY2")
DT = 0.015


def stream(step_at=None, seconds=60.0, seed=0, noise=0.005):
    """Estimates of (1.0, 0.77, 0.07) with 1 s-correlated noise and an optional step."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, DT)
    base = np.array([1.0, 0.77, 0.07])
    w = rng.normal(size=(len(t), 3))
    k = np.exp(-DT / 1.0)
    x = np.zeros_like(w)
    for i in range(1, len(t)):
        x[i] = k * x[i - 1] + np.sqrt(1 - k * k) * w[i]
    theta = base * (1 + noise * x)
    if step_at is not None:
        after = t >= step_at
        theta[after, 1] += 0.22 * (1 - np.exp(-(t[after] - step_at) / 0.5))
        theta[after, 2] += 0.02 * (1 - np.exp(-(t[after] - step_at) / 0.5))
    return t, theta


@pytest.mark.parametrize("seed", range(5))
def test_quiet_stream_gives_no_report(seed):
    t, theta = stream(seed=seed)
    assert detect_changes(t, theta, NAMES) == []


@pytest.mark.parametrize("seed", range(3))
def test_step_is_reported_with_time_and_new_values(seed):
    t, theta = stream(step_at=31.2, seed=seed)
    reports = detect_changes(t, theta, NAMES, "rls", units=("kg m^2", "kg m", "kg m"))
    assert len(reports) == 1
    rep = reports[0]
    assert rep.names == ("MX2R", "MY2")  # the first-moment parameters are watched
    assert abs(rep.time_s - 31.2) < 0.3
    assert rep.after == pytest.approx([0.99, 0.09], rel=0.03)
    assert rep.before == pytest.approx([0.77, 0.07], rel=0.03)
    assert str(rep).startswith("payload changed at 31.") and "MX2R 0.7" in str(rep)
    assert "-> 0.98" in str(rep) or "-> 0.99" in str(rep)


def test_nothing_is_watched_during_the_hold_off():
    t, theta = stream(step_at=5.0)
    det = ChangeDetector(NAMES, "x", DetectorSettings(holdoff_s=10.0))
    for ti, th in zip(t, theta, strict=True):
        det.update(ti, th)
    assert det.reports == []  # the step is inside hold-off + reference: it is the reference


def test_two_changes_give_two_reports():
    t, theta = stream(step_at=25.0, seconds=70.0)
    later = t >= 50.0
    theta[later, 1] -= 0.22
    reports = detect_changes(t, theta, NAMES)
    assert [round(r.time_s) for r in reports] == [25, 50]
