"""The replay's per-row recursions in C (``replay_rows.c`` beside this module), a block of
rows per call through ctypes: RLS in information form and the windowed Hopfield network
:data:`~guardid.online.replay_loop.HOPFIELD_ROWS_PER_STEP` rows a step, the arithmetic of
the numpy fast path of :mod:`guardid.online.replay_loop` row after row (the same estimates
to round-off: tests/test_replay_native.py), without its (block, p, p) arrays.

Built once into guardid's cache by :func:`guardid.native.cached_library`; without a
compiler, with a cache directory that cannot be written or a library that does not load
(or with :data:`USE_NATIVE` False) :func:`kernel` is None and the replay keeps its numpy
path, as after a build that fails (one warning naming it: :func:`guardid.native.load_cached`).
"""

from __future__ import annotations

import ctypes
from functools import lru_cache
from pathlib import Path

import numpy as np

SOURCE = Path(__file__).with_name("replay_rows.c")
USE_NATIVE = True
"""False: the replay takes its numpy path even where the C kernel builds (tests, bench)."""

_INT, _DBL, _PTR = ctypes.c_int, ctypes.c_double, ctypes.c_void_p


@lru_cache(maxsize=1)
def _load():
    from guardid.native import load_cached

    hopfield_args = [
        _INT, _INT, _INT, _INT, _PTR, _PTR, _DBL, _PTR, _PTR, _PTR, _DBL, _DBL, _DBL,
        *[_PTR] * 6,
    ]  # fmt: skip
    return load_cached("replay_rows", [SOURCE], {
        "guardid_rls_rows": ([_INT, _INT, _INT, _PTR, _PTR, _DBL, *[_PTR] * 6], _INT),
        "guardid_hopfield_rows": (hopfield_args, _INT),
        "guardid_information_rows": ([_INT, _INT, _INT, _PTR, _DBL, _PTR, _PTR], None),
        "guardid_cusum_rows": ([_INT, _INT, _PTR, _PTR, _PTR, _DBL, _DBL, *[_PTR] * 3], _INT),
    })  # fmt: skip


def kernel():
    """The loaded C library, or None (no compiler, or :data:`USE_NATIVE` off)."""
    return _load() if USE_NATIVE else None


def _c(a: np.ndarray, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """``a`` as C-ordered float64 (a copy when it is not), of ``shape`` when given."""
    a = np.ascontiguousarray(a, dtype=float)
    if shape is not None and a.shape != shape:
        raise ValueError(f"replay kernel: an input of shape {a.shape}, expected {shape}")
    return a


def _inout(a: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``a``, which the kernel updates in place: refused unless C-ordered writable float64
    of ``shape`` (the C reads and writes ``prod(shape)`` doubles from its first)."""
    ok = isinstance(a, np.ndarray) and a.dtype == np.float64 and a.shape == shape
    if not (ok and a.flags.c_contiguous and a.flags.writeable):
        what = f"{getattr(a, 'dtype', type(a).__name__)} {getattr(a, 'shape', '')}"
        raise ValueError(f"replay kernel: a state of {what}, expected C-ordered float64 {shape}")
    return a


def rls_rows(lib, A, y, lam, f, W, theta):
    """RLS over the rows A (L, n, p), y (L, n) from the information W (p, p) and estimate
    theta (p,), both updated in place: (estimates after each row (L, p), a-priori
    residuals (L, n)), or None when a row's system is not positive definite (W and theta
    then partly updated)."""
    L, n, p = A.shape
    A, y, f = _c(A), _c(y, (L, n)), _c(f, (p,))
    W, theta = _inout(W, (p, p)), _inout(theta, (p,))
    post, resid, work = np.empty((L, p)), np.empty((L, n)), np.empty(p * p + 2 * p)
    args = [A, y, f, W, theta, post, resid, work]
    if lib.guardid_rls_rows(L, n, p, A.ctypes.data, y.ctypes.data, lam,
                            *(a.ctypes.data for a in args[2:])):  # fmt: skip
        return None
    return post, resid


def hopfield_rows(lib, A, y, lam, f, S, c, g, K, tau, smax, W, b, s):
    """The windowed Hopfield network over A (L, n, p), y (L, n), ``K`` rows a step, from
    the weights W (p, p), biases b (p,) and state s (p,), all updated in place: (states
    after each row (L, p), a-priori residuals (L, n)), or None when a step's system is not
    positive definite."""
    L, n, p = A.shape
    A, y = _c(A), _c(y, (L, n))
    f, S, c = (_c(x, (p,)) for x in (f, S, c))
    W, b, s = _inout(W, (p, p)), _inout(b, (p,)), _inout(s, (p,))
    if int(K) < 1:
        raise ValueError(f"replay kernel: {K} rows a step, expected at least 1")
    states, resid = np.empty((L, p)), np.empty((L, n))
    work = np.empty(2 * p * p + K * p + 9 * p + 2 * K)
    ptrs = [a.ctypes.data for a in (W, b, s, states, resid, work)]
    code = lib.guardid_hopfield_rows(
        L, n, p, K, A.ctypes.data, y.ctypes.data, lam, f.ctypes.data, S.ctypes.data,
        c.ctypes.data, g, tau, smax, *ptrs,
    )  # fmt: skip
    return None if code else (states, resid)


def information_rows(lib, A, lam, f, W) -> None:
    """W (p, p) <- the information after the rows A (L, n, p), in place."""
    L, n, p = A.shape
    A, f, W = _c(A), _c(f, (p,)), _inout(W, (p, p))
    lib.guardid_information_rows(L, n, p, A.ctypes.data, lam, f.ctypes.data, W.ctypes.data)


def cusum_rows(lib, det, t, z, ok):
    """The two-sided CUSUM of the armed detector ``det`` over t (L,) [s], z (L, n)
    residuals in sigma, ok (L, n) present joint equations, its state advanced (as
    :func:`guardid.online.replay_loop._cusum_block`): the row of the first alarm or None."""
    L, n = z.shape
    t, z = _c(t, (L,)), _c(z)
    ok = np.ascontiguousarray(ok, dtype=np.bool_)
    if ok.shape != (L, n):
        raise ValueError(f"replay kernel: ok of shape {ok.shape}, expected {(L, n)}")
    state = [_c(np.array(x, dtype=float), (2, n)) for x in (det._g, det._zero_t, det._rise_t)]
    s = det.settings
    first = lib.guardid_cusum_rows(L, n, t.ctypes.data, z.ctypes.data, ok.ctypes.data,
                                   s.kappa, s.h, *(x.ctypes.data for x in state))  # fmt: skip
    det._g, det._zero_t, det._rise_t = (x.tolist() for x in state)
    return None if first < 0 else first
