"""The replay's C kernel (guardid/online/replay_rows.c) against independent truth: RLS on a
three-row problem worked by hand and the information-form recursion in a few lines of
numpy, the windowed Hopfield network against the numpy fast path it replaces
(:meth:`MethodReplay._hopfield`, its affine scans), a system that is not positive definite
reported, and no compiler -> no kernel (the numpy path). The whole replay, C against numpy,
on a log with a payload change: tests/test_online_replay.py; the CUSUM:
tests/test_replay_speed_paths.py."""

from __future__ import annotations

import numpy as np
import pytest

from guardid.estimators.hopfield import _SMAX, _TAU
from guardid.native import find_compiler
from guardid.online import OnlineIdentifier, replay_native
from guardid.online.replay_loop import MethodReplay, Rows
from guardid.robot import load_robot

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")
GUARD = load_robot("guard")


@pytest.fixture(scope="module")
def lib():
    lib = replay_native.kernel()
    assert lib is not None
    return lib


def test_rls_three_rows_worked_by_hand(lib):
    """lam 1/2, W0 = I, theta0 = 0, no floor; rows [1 0] y 2, [0 1] y 4, [1 1] y 3:
    W1 = diag(3/2, 1/2), b1 = (2, 0), theta1 = (4/3, 0); W2 = diag(3/4, 5/4), b2 = (1, 4),
    theta2 = (4/3, 16/5); W3 = [[11/8, 1], [1, 13/8]], b3 = (7/2, 5), det 79/64,
    theta3 = (44/79, 216/79); a-priori residuals 2, 4, 3 - 4/3 - 16/5 = -23/15."""
    A = np.array([[[1.0, 0.0]], [[0.0, 1.0]], [[1.0, 1.0]]])
    y = np.array([[2.0], [4.0], [3.0]])
    W, theta = np.eye(2), np.zeros(2)
    post, resid = replay_native.rls_rows(lib, A, y, 0.5, np.zeros(2), W, theta)
    assert np.allclose(post, [[4 / 3, 0.0], [4 / 3, 16 / 5], [44 / 79, 216 / 79]], 1e-14, 0)
    assert np.allclose(resid[:, 0], [2.0, 4.0, -23 / 15], 1e-14, 0)
    assert np.allclose(W, [[11 / 8, 1.0], [1.0, 13 / 8]], 1e-15, 0)
    assert np.array_equal(theta, post[-1])


def test_rls_rows_with_a_floor_follow_the_information_form(lib):
    """W_k = lam W_(k-1) + A^T A + diag(f), theta_k = theta_(k-1) + (lam W_(k-1) +
    A^T A)^-1 A^T (y - A theta_(k-1)), two equations a row, written out with numpy.solve."""
    rng = np.random.default_rng(3)
    L, n, p, lam = 50, 2, 5, 0.97
    A, y = rng.normal(size=(L, n, p)), rng.normal(size=(L, n))
    A[7, 1] = 0.0  # an absent joint's zero row
    f = rng.uniform(0.01, 0.1, p)
    W0 = np.diag(rng.uniform(1.0, 2.0, p))
    theta0 = rng.normal(size=p)
    W, theta = W0.copy(), theta0.copy()
    post, resid = replay_native.rls_rows(lib, A, y, lam, f, W, theta)
    Wt, th = W0.copy(), theta0.copy()
    for k in range(L):
        e = y[k] - A[k] @ th
        assert np.allclose(resid[k], e, rtol=1e-12, atol=1e-12)
        M = lam * Wt + A[k].T @ A[k]
        th = th + np.linalg.solve(M, A[k].T @ e)
        Wt = M + np.diag(f)
        assert np.allclose(post[k], th, rtol=1e-11, atol=1e-12), k
    assert np.allclose(W, Wt, rtol=1e-13, atol=0)
    Wi = W0.copy()
    replay_native.information_rows(lib, A[:20], lam, f, Wi)
    closed = lam**20 * W0 + sum(lam ** (19 - k) * (A[k].T @ A[k] + np.diag(f)) for k in range(20))
    assert np.allclose(Wi, closed, rtol=1e-13, atol=0)


def test_a_system_not_positive_definite_is_reported(lib):
    A, y = np.ones((3, 2, 4)), np.ones((3, 2))
    assert replay_native.rls_rows(lib, A, y, 0.9, np.zeros(4), -np.eye(4), np.zeros(4)) is None


@pytest.mark.parametrize(
    "W, theta",
    [(np.eye(4, dtype=np.float32), np.zeros(4)), (np.eye(4)[:, ::-1], np.zeros(4)),
     (np.eye(3), np.zeros(4)), (np.eye(4), np.zeros(5))],
)  # fmt: skip
def test_a_state_of_another_dtype_layout_or_shape_is_refused_before_the_call(lib, W, theta):
    """The C reads and writes p * p doubles from W's first byte: a float32, a reversed view
    or a wrong shape is a ValueError, not memory read or written out of bounds."""
    A, y = np.ones((3, 2, 4)), np.ones((3, 2))
    with pytest.raises(ValueError, match="replay kernel"):
        replay_native.rls_rows(lib, A, y, 0.9, np.zeros(4), W, theta)
    with pytest.raises(ValueError, match="replay kernel"):
        replay_native.rls_rows(lib, A, y[:, :1], 0.9, np.zeros(4), np.eye(4), np.zeros(4))


@pytest.fixture(scope="module")
def tracker():
    return OnlineIdentifier(GUARD, ("hopfield",), detector=False, keep_history=False)


def _hopfield_method(tk, beta, rows_per_step, seed):
    """The tracker's Hopfield method with gain ``beta`` on its fast path from a random state
    inside the box, with random weights and biases, and a block of random rows (zero rows
    for absent joints) of a parameter vector inside the box, with noise."""
    tk.estimators["hopfield"].beta = beta
    method = MethodReplay(tk, "hopfield", 0)
    method.rows_per_step = rows_per_step
    method._load()
    rng = np.random.default_rng(seed)
    p = len(tk.names)
    method.fast["s"] = rng.uniform(-0.6, 0.6, p)
    Q = rng.normal(size=(p, p)) / method.est.scale_[:, None]
    method.fast["W"] += 0.1 * Q @ Q.T
    method.fast["b"] = method.fast["W"] @ (method.est.center_ + 0.1 * rng.normal(size=p))
    L, n = 203, 2  # not a whole number of steps
    S = method.est.scale_
    A = rng.normal(size=(L, n, p)) / S[None, None, :]
    A[rng.random((L, n)) < 0.1] = 0.0
    truth = method.est.center_ + 0.4 * S * rng.uniform(-1.0, 1.0, p)  # inside the box
    y = A @ truth + 0.3 * rng.normal(size=(L, n))
    rows = Rows(np.arange(L) * 0.015, np.ones((L, n), bool))
    rows.set_chunk(0, A, y)
    return method, rows, A, y


@pytest.mark.parametrize(
    ("beta", "per_step", "seed"), [(3.0, 16, 0), (3.0, 1, 1), (3.0, 5, 2), (0.002, 16, 3)]
)
def test_hopfield_rows_equal_the_numpy_fast_path(lib, tracker, beta, per_step, seed):
    """C against the numpy path (affine scans, one Cholesky per step) over a block: states,
    a-priori residuals, weights, biases and state after it; beta 0.002 takes large steps
    that the fraction-to-boundary rule cuts short."""
    method, rows, A, y = _hopfield_method(tracker, beta, per_step, seed)
    start = {k: np.copy(v) for k, v in method.fast.items()}
    prior, post, e, commit = method._numpy(rows, 0, len(A), A, y)
    commit(len(A))
    est = method.est
    W, b, s = start["W"].copy(), start["b"].copy(), start["s"].copy()
    g = est.dt / est.beta

    def c_rows(tau, W, b, s):
        return replay_native.hopfield_rows(
            lib, A, y, method.tk.lam, method.f, est.scale_, est.center_, g, per_step, tau,
            _SMAX, W, b, s,
        )  # fmt: skip

    states, resid = c_rows(_TAU, W, b, s)
    assert np.allclose(est.center_ + est.scale_ * states, post, rtol=0, atol=1e-12 * est.scale_)
    assert np.allclose(resid, e, rtol=0, atol=1e-12 * np.abs(e).max())
    assert np.allclose(W, method.fast["W"], rtol=1e-13, atol=0)
    assert np.allclose(b, method.fast["b"], rtol=0, atol=1e-13 * np.abs(b).max())
    assert np.allclose(s, method.fast["s"], rtol=0, atol=1e-12)
    if beta < 0.01:  # steps the fraction-to-boundary rule cuts short: without it, others
        free, _ = c_rows(1e9, start["W"].copy(), start["b"].copy(), start["s"].copy())
        assert np.abs(free - states).max() > 1e-3


@pytest.mark.parametrize("kind", ["rls", "hopfield"])
def test_a_block_cut_at_an_alarm_keeps_the_state_of_that_row(lib, tracker, kind):
    """After an alarm at a block's row 100 the method goes on from its state after that row:
    C (the information recomputed to the row, the biases by the live network's recursion)
    against the numpy path's (the block's own rows)."""
    method, rows, A, y = _hopfield_method(tracker, 3.0, 16, 4)
    if kind == "rls":
        rls = OnlineIdentifier(GUARD, ("rls",), detector=False, keep_history=False)
        method = MethodReplay(rls, "rls", 0)
        method._load()
    start = {k: np.copy(v) for k, v in method.fast.items()}
    method._numpy(rows, 0, len(A), A, y)[3](101)
    by_numpy = method.fast
    method.fast = start
    method._native(lib, A, y)[3](101)
    assert by_numpy.keys() == method.fast.keys()
    for key, value in by_numpy.items():
        scale = np.abs(value).max()
        assert np.allclose(method.fast[key], value, rtol=0, atol=1e-12 * scale), key


def test_no_kernel_when_turned_off_or_without_a_compiler(monkeypatch, tmp_path):
    """Off, an unwritable cache, no compiler: no kernel (the replay's numpy path)."""
    assert replay_native.kernel() is not None
    monkeypatch.setattr(replay_native, "USE_NATIVE", False)
    assert replay_native.kernel() is None
    monkeypatch.setattr(replay_native, "USE_NATIVE", True)
    blocked = tmp_path / "not-a-directory"
    blocked.write_text("")
    replay_native._load.cache_clear()
    try:
        monkeypatch.setenv("GUARDID_CACHE_DIR", str(blocked / "cache"))  # cannot be made
        assert replay_native.kernel() is None
        replay_native._load.cache_clear()
        monkeypatch.setenv("CC", "/nonexistent/cc")
        assert replay_native.kernel() is None
    finally:
        replay_native._load.cache_clear()
