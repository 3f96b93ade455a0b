"""A whole log through an :class:`~guardid.online.tracker.OnlineIdentifier` at once.

What :meth:`OnlineIdentifier.update` does row by row and that does not depend on the
estimators' state is done here over all rows (module docstring of
:mod:`guardid.online.tracker` for the steps): the motor-equation current
(:meth:`MotorCurrent.replay`), the causal filter as one ``sosfilt`` call per run of rows
between gaps from the same steady-state start, the derivatives, the stiction and
no-count flags with the guard window, and the base regressor, known torques and torques of
every used row. Only the estimators' recursion and the change detectors stay in a loop,
over the used rows in order. Rows a gap cuts off (the guard's pending rows) and the rows of
the warm-up are dropped as the stream drops them, so the estimates and the change reports
are those of the row-by-row replay (to round-off: tests/test_online_replay.py).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.signal import sosfilt, sosfilt_zi

from guardid.online.replay_loop import MethodReplay, Rows, run_together

CHUNK_ROWS = 20000
"""Used rows whose regressor is formed at a time (memory: about 0.5 kB per row)."""


def replay(tracker, t_s, q_rad, current_a, voltage_v=None, restarts=()) -> list:
    """Feed ``tracker`` (fresh) the rows t (N,) [s], q (N, n) [rad], currents and voltages
    (N, n) [A], [V]; returns the change reports. The tracker then takes no more rows.
    ``restarts``: indices of rows before which the conditioner restarts as after a gap
    (a jump, :mod:`guardid.identify.jumps`)."""
    started = time.perf_counter()
    tk = tracker
    t = np.asarray(t_s, dtype=float)
    q = np.asarray(q_rad, dtype=float)
    effort = np.asarray(current_a, dtype=float)
    N, n = q.shape
    new_run = np.zeros(N, dtype=bool)
    new_run[0] = True
    new_run[1:] = np.diff(t) > 1.5 * tk.dt  # a gap restarts the conditioner (as update)
    new_run[np.asarray(restarts, dtype=np.int64)] = True
    if tk.motor is not None:
        if voltage_v is None:
            raise ValueError("effort='voltage' needs the voltages of every row")
        effort = tk.motor.replay(voltage_v, q, effort, new_run)
    starts = np.flatnonzero(new_run)
    ends = np.append(starts[1:], N)
    tk.rows = N
    tk._k = N - 1
    tk._replayed = True
    methods = [MethodReplay(tk, m, order) for order, m in enumerate(tk.methods)]
    stream = _Stream(tk, t, n, methods)
    flags = np.zeros((N, n), dtype=bool)  # the stream's flag ring, unrolled
    for s, e in zip(starts, ends, strict=True):
        _segment(tk, q, effort, flags, s, e, stream)
    del flags
    stream.finish()
    for method in methods:
        method.finish()
    tk.used = stream.used
    if tk.keep_history:
        tk._hist_t.extend(stream.rows.t[: stream.used])
    found = sorted((r for method in methods for r in method.reports), key=lambda r: r[:2])
    reports = [r[2] for r in found]
    tk.reports += reports
    tk.busy_s = time.perf_counter() - started
    return reports


SEGMENT_CHUNK = 65536
"""Rows of a run between gaps conditioned at a time (the filter's state and its last two
outputs carried over; peak memory of long logs)."""


def _segment(tk, q, effort, flags, s, e, keep) -> None:
    """Rows s .. e - 1 (a run between gaps) through the causal conditioning by chunks of
    :data:`SEGMENT_CHUNK` rows: the stream's flags set in ``flags`` (N, n), the rows the
    guard releases and some joint uses given to ``keep`` (:class:`_Stream`: rows k, bad, q,
    qd, qdd, tau), each as soon as the flags within its guard are final."""
    cond, n = tk.conditioner, q.shape[1]
    lag, g, warmup, dt = tk._lag, tk.guard, tk.warmup, cond.dt
    x0 = np.concatenate([q[s], effort[s]])
    zi = sosfilt_zi(cond.sos)[:, :, None] * x0[None, None, :]
    prev = np.repeat(x0[None, :], 2, axis=0)  # the two outputs before the chunk
    pending = []  # released rows (k, q, qd, qdd, tau) whose guard's flags may still change
    for cs in range(s, e, SEGMENT_CHUNK):
        ce = min(cs + SEGMENT_CHUNK, e)
        y, zi = sosfilt(cond.sos, np.concatenate([q[cs:ce], effort[cs:ce]], axis=1), axis=0,
                        zi=zi)  # fmt: skip
        full = np.concatenate([prev, y], axis=0)
        prev = full[-2:]
        y0, y1, y2 = full[2:], full[1:-1], full[:-2]
        qd = (y0[:, :n] - y2[:, :n]) / (2.0 * dt)
        qdd = (y0[:, :n] - 2.0 * y1[:, :n] + y2[:, :n]) / (dt * dt)
        tau = 0.5 * (y0[:, n:] + y1[:, n:]) if cond.period_mean else y1[:, n:]
        if cond.gain is not None:
            tau = tau * cond.gain
        slow = (
            np.abs(qd) < cond.threshold if cond.threshold is not None else np.zeros_like(qd, bool)
        )
        a = max(cs, s + 1)
        flat = q[a:ce] == q[a - 1 : ce - 1]  # no count in the period: both rows flagged
        flags[a:ce] |= flat
        flags[a - 1 : ce - 1] |= flat
        k = np.arange(cs, ce)
        j = k - lag
        warm = j < s + warmup
        mark = slow if tk.per_joint else np.repeat(slow.any(axis=1, keepdims=True), n, 1)
        ok = j >= 0
        flags[j[ok & ~warm]] |= mark[ok & ~warm]
        flags[j[ok & warm]] = True
        released = k + g <= e - 1  # the guard's pending rows at a gap or the end are dropped
        released &= j >= 0  # a sample before the first row is in the warm-up: never used
        r = np.flatnonzero(released)
        pending.append((k[r], y1[r, :n], qd[r], qdd[r], tau[r]))
        # flags up to row ce - lag - 2 are final (later rows flag their sample k - lag and
        # no-count pairs from ce - 1 on); the segment's are final at its end (a later
        # segment only flags its own warm-up)
        pending = _release(tk, flags, pending, ce - g - 2 if ce < e else e, keep)


def _release(tk, flags, pending, last_k, keep) -> list:
    """Give the pending rows k <= ``last_k`` that some joint uses to ``keep`` with their
    bad joints (any flag within the guard of the sample j = k - lag, j - g .. j + g); the
    rest stay pending (returned)."""
    lag, g, n = tk._lag, tk.guard, flags.shape[1]
    kk, qf, qd, qdd, tau = (np.concatenate(f) for f in zip(*pending, strict=True))
    now = kk <= last_k
    later = [tuple(f[~now] for f in (kk, qf, qd, qdd, tau))]
    kk, qf, qd, qdd, tau = (f[now] for f in (kk, qf, qd, qdd, tau))
    if not len(kk):
        return later
    jj = kk - lag
    lo = int(jj[0]) - g
    window = flags[max(lo, 0) : int(jj[-1]) + g + 1]
    if lo < 0:
        window = np.concatenate([np.zeros((-lo, n), bool), window])
    csum = np.concatenate([np.zeros((1, n), np.int64), np.cumsum(window, axis=0)])
    bad = (csum[jj + g + 1 - lo] - csum[jj - g - lo]) > 0
    if not tk.per_joint:
        bad[:] = bad.any(axis=1, keepdims=True)
    use = ~bad.all(axis=1)
    keep.add(kk[use], bad[use], qf[use], qd[use], qdd[use], tau[use])
    return later


class _Stream:
    """The used rows, as the conditioning releases them, through the estimators by chunks
    of :data:`CHUNK_ROWS` rows (the same chunks as if all rows were formed first): only the
    times and the joints' use of every row are kept (``rows``), the conditioned signals
    only until their chunk has run (memory of long logs)."""

    def __init__(self, tk, t, n, methods) -> None:
        self.tk, self.t, self.methods = tk, t, methods
        self.rows = Rows(np.empty(len(t)), np.empty((len(t), n), dtype=bool))
        self.used = 0  # rows released so far
        self.done = 0  # rows through the estimators
        self.parts: list = []  # (bad, q, qd, qdd, tau) of the rows released, not yet run

    def add(self, k, bad, qf, qd, qdd, tau) -> None:
        """Rows ``k`` released (their bad joints and conditioned signals)."""
        a, b = self.used, self.used + len(k)
        self.rows.t[a:b] = self.t[k] - self.tk.conditioner.delay_s
        self.rows.ok[a:b] = ~bad
        self.used = b
        self.parts.append((bad, qf, qd, qdd, tau))
        while self.used - self.done >= CHUNK_ROWS:
            self._run(CHUNK_ROWS)

    def finish(self) -> None:
        """The last rows (a chunk shorter than :data:`CHUNK_ROWS`)."""
        if self.used > self.done:
            self._run(self.used - self.done)

    def _run(self, size: int) -> None:
        fields = [np.concatenate(f) for f in zip(*self.parts, strict=True)]
        self.parts = [tuple(f[size:] for f in fields)] if len(fields[0]) > size else []
        absent, qf, qd, qdd, tau = (f[:size] for f in fields)
        c0, c1 = self.done, self.done + size
        A, y = _equations(self.tk, qf, qd, qdd, tau)
        A[absent] = 0.0  # an absent joint's equation as a zero row: it adds nothing
        y[absent] = 0.0
        self.rows.set_chunk(c0, A, y)
        run_together(self.methods, self.rows, c0, c1)
        self.done = c1


def _equations(tk, q, qd, qdd, tau):
    """Base regressor rows A (M, n, b) of the identified columns and torques y (M, n) [N m]
    of the used samples, as :meth:`OnlineIdentifier._estimate` forms them one by one."""
    model = tk.model
    b = len(tk.free)
    fixed = tk._fixed
    A = _base_columns(model, q, qd, qdd, tk.free if fixed is None else [*tk.free, *fixed[0]])
    y = tau
    if tk._known:
        y = y - model.known_torque(q, qd, qdd)
    if fixed is not None:
        y = y - A[:, :, b:] @ fixed[1]
    return np.ascontiguousarray(A[:, :, :b]), np.ascontiguousarray(y, dtype=float)


def _base_columns(model, q, qd, qdd, cols):
    """``model.base_regressor(q, qd, qdd)[:, :, cols]`` (M, n, len(cols)), C-ordered; a
    chain's as one matrix product of its full regressor's (M n, P) rows (numpy's (M, n, P)
    @ (P, b) is a product per sample, several times slower)."""
    from guardid.dynamics import ChainModel

    if not isinstance(model, ChainModel):
        return np.ascontiguousarray(model.base_regressor(q, qd, qdd)[:, :, cols])
    Y = model.regressor(q, qd, qdd)
    M, n, P = Y.shape
    B = np.ascontiguousarray(model.base.B[:, cols])
    return (Y.reshape(M * n, P) @ B).reshape(M, n, len(cols))
