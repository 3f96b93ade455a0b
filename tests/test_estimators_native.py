"""The estimators' offline loops in C (guardid/estimators/sample_loops.c) against their
Python paths, which are separate code: the Hopfield network against ``update`` called
sample after sample (its Python fast path) and against the general per-sample step
(``_sample_step``, plain numpy), including runs where the fraction-to-boundary rule cuts
steps; the gradient estimator against its Python loop, diverging included. Tolerance: the
two sum in different orders (BLAS against a plain loop), so they agree to round-off, not
bit for bit: 1e-9 on the Hopfield state s in (-1, 1) (the boundary rule's cuts divide by
the distance to the face, which amplifies round-off near it; seen up to 2e-10), 1e-12
relative on the gradient's theta and the MLP's weights and losses (its mini-batch epochs
in C against numpy's matrix products; seen up to 5e-15). Without the kernel (turned off,
GUARDID_NATIVE=0, no compiler) the estimators take the Python paths."""

from __future__ import annotations

import numpy as np
import pytest

from guardid.estimators import MLP, Gradient, Hopfield, hopfield, native_loops
from guardid.native import find_compiler

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")
P = 4


def _data(seed: int, n: int = 3000, truth=(0.5, -0.3, 0.9, 0.1), noise: float = 0.1):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, 2, P))
    A[17] = 0.0  # a skipped sample's zero rows
    return A, A @ np.asarray(truth) + noise * rng.normal(size=(n, 2))


def _hopfield(beta: float, every: int = 3) -> Hopfield:
    return Hopfield(np.full(P, 0.2), half_widths=np.ones(P), beta=beta, dt=0.01,
                    fit_block=1, history_every=every)  # fmt: skip


@pytest.fixture
def python_only(monkeypatch):
    """Run the Python paths (the kernel turned off) inside the ``with`` block."""

    class Off:
        def __enter__(self):
            monkeypatch.setattr(native_loops, "USE_NATIVE", False)

        def __exit__(self, *exc):
            monkeypatch.setattr(native_loops, "USE_NATIVE", True)

    return Off()


def _by_update(est: Hopfield, A, y, every: int):
    """The Python fast path: ``update`` sample after sample, s after every ``every``-th."""
    est.reset()
    hist = []
    for i in range(A.shape[0]):
        est.update(A[i], y[i])
        if (i + 1) % every == 0:
            hist.append(est.s_)
    return np.array(hist)


def _by_sample_step(est: Hopfield, A, y):
    """The general per-sample step (plain numpy), s after each sample."""
    s, inv_c, hist = est._s0.copy(), est.beta / est.dt, []
    for i in range(A.shape[0]):
        s = hopfield._sample_step(s, A[i] * est.scale_, y[i] - A[i] @ est.center_, inv_c)
        hist.append(s)
    return np.array(hist)


@pytest.mark.parametrize(
    "beta, truth, cuts",
    [
        (1e-1, (0.5, -0.3, 0.9, 0.1), False),  # slow network, inside the box
        (1e-5, (0.5, -0.3, 2.5, -3.0), True),  # fast network pushed against two faces
    ],
)
def test_hopfield_fit_in_c_follows_update_and_the_plain_step(beta, truth, cuts, monkeypatch):
    A, y = _data(1, truth=truth)
    assert native_loops.kernel() is not None
    est = _hopfield(beta).fit(A, y)
    calls = []
    real = hopfield._boundary_step
    monkeypatch.setattr(hopfield, "_boundary_step", lambda s, ds: calls.append(1) or real(s, ds))
    by_update = _by_update(_hopfield(beta), A, y, 3)
    assert bool(calls) == cuts  # the rule's cuts are exercised (or not) as intended
    s_hist = (est.history_ - est.center_) / est.scale_
    assert est.history_.shape == (1000, P)
    assert np.array_equal(est.history_samples_, np.arange(3, 3001, 3))
    assert np.max(np.abs(s_hist - by_update)) < 1e-9
    plain = _by_sample_step(_hopfield(beta), A, y)
    assert np.max(np.abs(s_hist - plain[2::3])) < 1e-9
    assert np.max(np.abs(est.s_ - plain[-1])) < 1e-9
    assert np.max(np.abs(est.s_)) < 1.0
    if cuts:  # at the faces the truth lies beyond
        assert est.s_[2] > 0.99 and est.s_[3] < -0.99
    assert est.n_samples_ == 3000 and est.theta_ == pytest.approx(est.history_[-1], abs=1e-15)


def test_hopfield_update_continues_after_a_c_fit():
    """``update`` after the C fit goes on from its state as after the Python fit."""
    A, y = _data(2)
    est = _hopfield(1e-3).fit(A[:2000], y[:2000])
    ref = _hopfield(1e-3)
    _by_update(ref, A[:2000], y[:2000], 1)
    for i in range(2000, 2100):
        est.update(A[i], y[i])
        ref.update(A[i], y[i])
    assert np.max(np.abs(est.s_ - ref.s_)) < 1e-9 and est.n_samples_ == 2100


def _close(a, b, rel: float = 1e-12) -> bool:
    """a == b to ``rel`` of the largest |b| of each row (last axis), NaN where b has NaN."""
    nan = np.isnan(b)
    scale = np.max(np.where(nan, 0.0, np.abs(b)), axis=-1, keepdims=True)
    err = np.where(nan, 0.0, np.abs(a - b))
    return bool(np.array_equal(np.isnan(a), nan) and np.all(err <= rel * scale))


@pytest.mark.parametrize(
    "integrator, eta, diverges_at",
    [("euler", 1e-1, None), ("implicit", 1e2, None), ("euler", 3e2, 64), ("implicit", 1.0, 128)],
)
def test_gradient_fit_in_c_follows_the_python_loop(integrator, eta, diverges_at, python_only):
    """Converging, blowing up (found at the check after sample 64) and NaN from a bad
    sample at 100 (found at the check after 128)."""
    A, y = _data(3)
    if diverges_at == 128:
        y[100, 1] = np.nan
    truth = np.array([0.5, -0.3, 0.9, 0.1])
    est = Gradient(eta=eta, dt=0.01, integrator=integrator, history_every=5, blowup=1e6)
    est.fit(A, y)
    with python_only:
        ref = Gradient(eta=eta, dt=0.01, integrator=integrator, history_every=5, blowup=1e6)
        ref.fit(A, y)
    assert est.diverged_at_ == ref.diverged_at_ == diverges_at
    assert est.n_samples_ == ref.n_samples_ == (diverges_at or 3000)
    assert np.array_equal(est.history_samples_, ref.history_samples_)
    assert est.history_.shape == ref.history_.shape == (len(ref.history_samples_), P)
    assert _close(est.history_, ref.history_) and _close(est.theta_, ref.theta_)
    if diverges_at is None:  # and both found the truth (the noise is 0.1 on 3000 samples)
        assert np.max(np.abs(est.theta_ - truth)) < 0.05
    else:
        assert est.diverged_ and not np.max(np.abs(est.theta_)) < 1e6


def test_no_kernel_when_turned_off_or_without_a_compiler(monkeypatch, tmp_path, python_only):
    """Off, GUARDID_NATIVE=0, an unwritable cache, no compiler: no kernel, and the fits
    still run (their Python paths)."""
    assert native_loops.kernel() is not None
    with python_only:
        assert native_loops.kernel() is None
    native_loops._load.cache_clear()
    try:
        monkeypatch.setenv("GUARDID_NATIVE", "0")
        assert native_loops.kernel() is None
        monkeypatch.delenv("GUARDID_NATIVE")
        native_loops._load.cache_clear()
        blocked = tmp_path / "not-a-directory"
        blocked.write_text("")
        monkeypatch.setenv("GUARDID_CACHE_DIR", str(blocked / "cache"))  # cannot be made
        assert native_loops.kernel() is None
        native_loops._load.cache_clear()
        monkeypatch.setenv("CC", "/nonexistent/cc")
        assert native_loops.kernel() is None
        A, y = _data(4, n=300)
        est = _hopfield(1e-3).fit(A, y)
        by_update = _by_update(_hopfield(1e-3), A, y, 3)
        assert np.array_equal(est.history_, est.center_ + est.scale_ * by_update)
        assert Gradient(eta=1e-1, dt=0.01).fit(A, y).n_samples_ == 300
    finally:
        native_loops._load.cache_clear()


@pytest.mark.parametrize("beta, diverges_at", [(1e-1, None), (1e-3, 64)])
def test_hopfield_euler_fit_in_c_follows_the_python_loop(beta, diverges_at, python_only):
    """The explicit Euler integrator: settling (slow) and blowing up (found at the first
    check, after sample 64), C against the Python loop."""
    A, y = _data(5)
    est = Hopfield(np.zeros(P), half_widths=np.ones(P), beta=beta, dt=0.01, integrator="euler",
                   history_every=5).fit(A, y)  # fmt: skip
    with python_only:
        ref = Hopfield(np.zeros(P), half_widths=np.ones(P), beta=beta, dt=0.01,
                       integrator="euler", history_every=5).fit(A, y)  # fmt: skip
    assert est.diverged_at_ == ref.diverged_at_ == diverges_at
    assert est.n_samples_ == ref.n_samples_ == (diverges_at or 3000)
    assert np.array_equal(est.history_samples_, ref.history_samples_)
    assert _close(est.history_, ref.history_) and _close(est.s_, ref.s_)
    if diverges_at is None:
        assert np.max(np.abs(est.theta_ - [0.5, -0.3, 0.9, 0.1])) < 0.05


@pytest.mark.parametrize(
    "settings",
    [
        dict(momentum=0.0, weight_decay=0.0, lr=0.1),  # seed 001's plain backpropagation
        dict(momentum=0.9, weight_decay=0.3, lr=0.02, init_scale=1.0),
    ],
)
def test_mlp_epochs_in_c_follow_numpy(settings, python_only):
    """Mini-batch epochs (500 samples in batches of 64: the last one of 52), C against the
    numpy backprop (itself checked against finite differences in tests/test_mlp.py)."""
    rng = np.random.default_rng(6)
    A, X = rng.normal(size=(500, 2, 5)), rng.normal(size=(500, 6)) * [0.5, 2, 1, 10, 3, 1]
    y = A @ [1.5, -0.5, 0.25, 2.0, 1.0] + 0.05 * rng.normal(size=(500, 2))
    net = MLP(epochs=4, seed=2, **settings).fit(A, y, X=X)
    with python_only:
        ref = MLP(epochs=4, seed=2, **settings).fit(A, y, X=X)
    assert net.n_epochs_ == ref.n_epochs_ == 4
    for name, w in ref.weights_.items():
        assert _close(net.weights_[name].ravel(), w.ravel()), name
    assert _close(net.loss_history_, ref.loss_history_) and _close(net.theta_, ref.theta_)
    assert ref.loss_history_[-1] < 0.5 * ref.loss_history_[0]  # it did learn


def test_hopfield_fit_in_c_with_scalar_bounds(python_only):
    """Bounds given as two numbers (one box for every parameter, theta_n (p,)): the C fit
    gives each parameter the same half-width and centre, as the Python path broadcasts
    them, and both find the truth (a fast network, little noise)."""
    A, y = _data(7, n=600, noise=0.01)
    est = Hopfield(np.full(P, 0.2), bounds=(-2.0, 2.0), beta=1e-4, dt=0.01, fit_block=1)
    est.fit(A, y)
    with python_only:
        ref = Hopfield(np.full(P, 0.2), bounds=(-2.0, 2.0), beta=1e-4, dt=0.01, fit_block=1)
        ref.fit(A, y)
    assert np.max(np.abs(est.s_ - ref.s_)) < 1e-9
    assert np.max(np.abs(est.theta_ - [0.5, -0.3, 0.9, 0.1])) < 0.02


def test_a_build_that_fails_is_a_warning_and_the_python_loops(monkeypatch, tmp_path):
    """A compiler that errs (here a script printing an error and exiting 1): one warning
    naming the build, no kernel, and the fits run their Python loops (a speed-up lost is
    not an error of the fit)."""
    bad = tmp_path / "badcc"
    bad.write_text("#!/bin/sh\necho 'cc: internal compiler error: killed' >&2\nexit 1\n")
    bad.chmod(0o755)
    native_loops._load.cache_clear()
    try:
        monkeypatch.setenv("CC", str(bad))
        monkeypatch.setenv("GUARDID_CACHE_DIR", str(tmp_path / "cache"))
        with pytest.warns(UserWarning, match="C fast path sample_loops is off: building"):
            assert native_loops.kernel() is None
        A, y = _data(4, n=300)
        est = _hopfield(1e-3).fit(A, y)
        by_update = _by_update(_hopfield(1e-3), A, y, 3)
        assert np.array_equal(est.history_, est.center_ + est.scale_ * by_update)
    finally:
        native_loops._load.cache_clear()
