"""A whole log replayed at once (OnlineIdentifier.feed on a fresh tracker) against the same
rows fed one by one through update(), the live path: same rows used, estimates to rtol 1e-9
of each parameter's scale, identical change reports (times equal, values to 1e-9) with the
Hopfield network a step a row (``HOPFIELD_ROWS_PER_STEP = 1``, the per-row reference);
with its default 16 rows a step, RLS as before and the Hopfield estimates within
:data:`HOPFIELD_TOL` of each parameter's scale (largest |estimate| over the run; measured
at most 0.0031 on this log), its reports at the same times with the values within 0.5 %.

The log: 32 s of the tracking excitation from sim://guard with a 1 kg payload at 22 s.
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from guardid.capture import capture
from guardid.cli import main as cli
from guardid.excitation import load_trajectory
from guardid.identify.runs import load_run
from guardid.link import Session, open_port
from guardid.online import OnlineIdentifier, replay_loop
from guardid.robot import load_robot

GUARD = load_robot("guard")
PORT = "sim://guard?seed=4&payload_time=22&payload_mass=1.0&payload_com=0.12,0.02,0"
RTOL = 1e-9
HOPFIELD_TOL = 0.02


@pytest.fixture(scope="module")
def payload_log(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("replay")
    traj = tmp / "traj.yaml"
    res = CliRunner().invoke(
        cli, ["excite", "--base-freq", "0.2", "--harmonics", "3", "--starts", "1", "-o", str(traj)]
    )
    assert res.exit_code == 0, res.output
    trajectory = load_trajectory(traj)
    log = tmp / "pay.csv"
    port = open_port(PORT)
    try:
        session = Session(port)
        session.handshake()
        capture(session, GUARD, trajectory, 32.0, log, {"robot": "guard"})
    finally:
        port.close()
    return load_run(log), trajectory


def _both(run, trajectory, keep=None, **kwargs):
    """(row-by-row tracker, its reports, replayed tracker, its reports) on ``run``'s rows
    (``keep``: a row mask, to make gaps), the replay's Hopfield network a step a row; the
    replay with its default steps (:data:`HOPFIELD_ROWS_PER_STEP`) checked against the live
    tracker to the module's tolerances on the way."""
    t = (run.ticks - run.ticks[0]) * GUARD.sample_period
    rows = [t, run.q, run.current, run.voltage]
    if keep is not None:
        rows = [x[keep] for x in rows]

    def make():
        return OnlineIdentifier.for_trajectory(GUARD, ("rls", "hopfield"), trajectory, **kwargs)

    live = make()
    live_reports = []
    for tt, q, i, v in zip(*rows, strict=True):
        live_reports += live.update(float(tt), q, i, v)
    merged = make()
    _assert_close(live, live_reports, merged, merged.feed(*rows))
    default = replay_loop.HOPFIELD_ROWS_PER_STEP
    replay_loop.HOPFIELD_ROWS_PER_STEP = 1
    try:
        replayed = make()
        replay_reports = replayed.feed(*rows)
    finally:
        replay_loop.HOPFIELD_ROWS_PER_STEP = default
    return live, live_reports, replayed, replay_reports


def _assert_close(live, live_reports, replayed, replay_reports):
    """The replay with merged Hopfield steps against the live tracker (module docstring)."""
    assert replay_loop.HOPFIELD_ROWS_PER_STEP == 16
    assert (replayed.rows, replayed.used) == (live.rows, live.used)
    for m, tr in live.tracks().items():
        other = replayed.tracks()[m]
        assert np.array_equal(tr.t, other.t), m
        scale = np.abs(tr.theta).max(axis=0)
        tol = RTOL if m == "rls" else HOPFIELD_TOL
        assert np.all(np.abs(other.theta - tr.theta) <= tol * scale), m
    assert len(replay_reports) == len(live_reports) == len(replayed.reports)
    for a, b in zip(live_reports, replay_reports, strict=True):
        times = np.array([[x.time_s, x.latest_s, x.alarm_s, x.report_s] for x in (a, b)])
        assert a.method == b.method
        assert np.array_equal(times[0], times[1])
        assert a.method != "rls" or str(a) == str(b)
        tol = RTOL if a.method == "rls" else 5e-3
        assert np.allclose(a.after, b.after, rtol=tol, atol=0)


def _assert_same(live, live_reports, replayed, replay_reports):
    assert (replayed.rows, replayed.used) == (live.rows, live.used)
    for m, tr in live.tracks().items():
        other = replayed.tracks()[m]
        assert np.array_equal(tr.t, other.t), m  # the same rows, at the same instants
        scale = np.abs(tr.theta).max(axis=0)
        assert np.all(np.abs(other.theta - tr.theta) <= RTOL * scale), m
    assert len(replay_reports) == len(live_reports) == len(replayed.reports)
    for a, b in zip(live_reports, replay_reports, strict=True):
        assert (a.method, a.time_s, a.latest_s, a.alarm_s, a.report_s) == (
            b.method, b.time_s, b.latest_s, b.alarm_s, b.report_s)  # fmt: skip
        assert np.allclose(a.after, b.after, rtol=RTOL, atol=0) and str(a) == str(b)


def test_replay_gives_the_live_estimates_and_reports(payload_log):
    run, trajectory = payload_log
    live, live_reports, replayed, replay_reports = _both(run, trajectory)
    assert {r.method for r in live_reports} == {"rls", "hopfield"}  # the payload is seen
    assert all(21.0 < r.at_s < 24.0 for r in live_reports)
    _assert_same(live, live_reports, replayed, replay_reports)


def test_replay_with_gaps_restarts_as_the_stream_does(payload_log):
    run, trajectory = payload_log
    keep = np.ones(len(run.ticks), dtype=bool)
    keep[700:712] = False  # a 12-row gap, then single lost rows
    keep[[1200, 1203, 1900]] = False
    _assert_same(*_both(run, trajectory, keep=keep))


def test_replay_by_short_chunks_with_gaps_is_the_stream(payload_log, monkeypatch):
    """Issue 30 (memory): the conditioning of each run between gaps 37 rows at a time (the
    filter's state and last outputs carried over, each row released once the flags within
    its guard are final), the motor-equation current 37 rows at a time and the released rows
    through the estimators 1201 at a time, as they come (more than the tracker's
    replay span of rows: the rows keep two chunks): still the live tracker's rows,
    estimates and reports (chunk boundaries near the gaps and the payload)."""
    from guardid.online import motor, replay

    monkeypatch.setattr(replay, "SEGMENT_CHUNK", 37)
    monkeypatch.setattr(replay, "CHUNK_ROWS", 1201)
    monkeypatch.setattr(motor, "REPLAY_CHUNK", 37)
    run, trajectory = payload_log
    keep = np.ones(len(run.ticks), dtype=bool)
    keep[700:712] = False
    keep[[1200, 1203, 1900]] = False
    _assert_same(*_both(run, trajectory, keep=keep))


@pytest.mark.parametrize("options", [{"effort": "current"}, {"per_joint": False}])
def test_replay_options_match_the_stream(payload_log, options):
    run, trajectory = payload_log
    _assert_same(*_both(run, trajectory, **options))


def test_a_replayed_tracker_takes_no_more_rows(payload_log):
    run, trajectory = payload_log
    tracker = OnlineIdentifier.for_trajectory(GUARD, ("rls",), trajectory)
    t = (run.ticks - run.ticks[0]) * GUARD.sample_period
    tracker.feed(t[:200], run.q[:200], run.current[:200], run.voltage[:200])
    with pytest.raises(RuntimeError, match="takes no more rows"):
        tracker.update(float(t[200]), run.q[200], run.current[200], run.voltage[200])


def test_identify_tracks_in_a_forked_process_with_the_in_process_output(payload_log, monkeypatch):
    """``guardid identify`` replays the log in a forked process while it fits (two cores):
    the same printed tracking lines and change warning as the replay in the process."""
    import guardid.online.offline as offline

    run, _ = payload_log
    made = []
    real = offline.ForkedTracking

    def spy(*args, **kwargs):
        made.append(real(*args, **kwargs))
        return made[-1]

    monkeypatch.setattr(offline, "ForkedTracking", spy)
    monkeypatch.setattr("os.sched_getaffinity", lambda pid: {0, 1}, raising=False)

    def lines(result):
        return [x for x in result.output.splitlines() if not x.startswith("identify: done")]

    forked = CliRunner().invoke(cli, ["identify", str(run.path)])
    assert len(made) == 1 and not made[0]._proc.is_alive()
    monkeypatch.setattr(offline, "start_tracking", lambda *args, **kwargs: None)
    inside = CliRunner().invoke(cli, ["identify", str(run.path)])
    assert forked.exit_code == inside.exit_code == 0, inside.output
    assert any(x.startswith("tracking (the log replayed") for x in lines(forked))
    assert any(x.startswith("payload changed") for x in lines(forked))  # the 1 kg at 22 s
    assert lines(forked) == lines(inside)


def test_replay_c_kernel_equals_its_numpy_path(payload_log, monkeypatch):
    """The replay's C kernel (guardid/online/replay_rows.c; tests/test_replay_native.py)
    against its numpy path on the payload log with gaps: the same rows, estimates within
    RTOL of each parameter's scale, the same change reports (times equal, text identical);
    and with every other block handed back to the numpy path (as when a system is not
    positive definite by round-off): the same again. Blocks of 32 rows for numpy, 4 x 32
    for C (many, an alarm inside one; the Hopfield steps on the same rows)."""
    from guardid.online import replay_native

    if replay_native.kernel() is None:
        pytest.skip("needs a C compiler")
    monkeypatch.setattr(replay_loop, "BLOCK", 32)  # many blocks, one across the payload
    run, trajectory = payload_log
    keep = np.ones(len(run.ticks), dtype=bool)
    keep[700:712] = False
    keep[[1200, 1903]] = False
    t = (run.ticks - run.ticks[0]) * GUARD.sample_period
    rows = [x[keep] for x in (t, run.q, run.current, run.voltage)]

    def replayed():
        tk = OnlineIdentifier.for_trajectory(GUARD, ("rls", "hopfield"), trajectory)
        return tk, tk.feed(*rows)

    native = replayed()
    calls = {"n": 0}

    def every_other(kernel):
        def call(*args):
            calls["n"] += 1
            return kernel(*args) if calls["n"] % 2 else None

        return call

    for name in ("rls_rows", "hopfield_rows"):
        monkeypatch.setattr(replay_native, name, every_other(getattr(replay_native, name)))
    mixed = replayed()
    assert calls["n"] >= 6
    monkeypatch.setattr(replay_native, "USE_NATIVE", False)
    by_numpy = replayed()
    assert {r.method for r in by_numpy[1]} == {"rls", "hopfield"}  # the payload is seen
    _assert_same(*by_numpy, *native)
    _assert_same(*by_numpy, *mixed)


def test_a_restart_given_replays_as_the_stream_restarts(payload_log):
    """Rows after a jump (a log's rows lost without a gap in the ticks) restart the
    conditioner: the replay's restart equals the row-by-row feed's, and costs a warm-up."""
    run, trajectory = payload_log
    t = (run.ticks - run.ticks[0]) * GUARD.sample_period
    rows = [t, run.q, run.current, run.voltage]

    def make():
        return OnlineIdentifier.for_trajectory(GUARD, ("rls",), trajectory)

    live = make()
    reports = live.update(float(t[0]), run.q[0], run.current[0], run.voltage[0])
    reports += live.feed(*[x[1:] for x in rows], restarts=[699])  # the run's row 700
    replayed = make()
    _assert_same(live, reports, replayed, replayed.feed(*rows, restarts=[700]))
    plain = make()
    plain.feed(*rows)
    assert plain.used > replayed.used  # the warm-up after the restart
