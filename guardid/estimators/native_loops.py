"""The estimators' offline per-sample loops in C (``sample_loops.c`` beside this module),
a whole log per call through ctypes: the Hopfield network's n_out = 2 fast path
(:meth:`guardid.estimators.Hopfield.update` sample after sample) and its explicit Euler
loop, the gradient estimator's loop (:meth:`guardid.estimators.Gradient.fit`) and an epoch
of the MLP's mini-batch descent (:meth:`guardid.estimators.MLP.fit`). The same estimates
as the Python paths to round-off (tests/test_estimators_native.py).

Built once into guardid's cache by :func:`guardid.native.cached_library`; without a
compiler, with ``GUARDID_NATIVE=0``, a cache directory that cannot be written or a library
that does not load, a build that fails (one warning naming it), or with :data:`USE_NATIVE`
False, :func:`kernel` is None and the estimators keep their Python loops.
"""

from __future__ import annotations

import ctypes
from functools import lru_cache
from pathlib import Path

import numpy as np

SOURCE = Path(__file__).with_name("sample_loops.c")
USE_NATIVE = True
"""False: the estimators take their Python loops even where the C kernel builds."""

_INT, _DBL, _PTR = ctypes.c_int, ctypes.c_double, ctypes.c_void_p


@lru_cache(maxsize=1)
def _load():
    from guardid.native import load_cached

    return load_cached("sample_loops", [SOURCE], {
        "guardid_hopfield_samples": ([_INT, _INT, *[_PTR] * 4, _DBL, _DBL, _INT, *[_PTR] * 3],
                                     None),
        "guardid_gradient_samples": ([_INT, _INT, _INT, *[_PTR] * 3, _INT, _INT, _DBL, _DBL,
                                      *[_PTR] * 3], _INT),
        "guardid_mlp_epoch": ([*[_INT] * 6, *[_PTR] * 4, _DBL, _DBL, _DBL, *[_PTR] * 3], None),
    })  # fmt: skip


def kernel():
    """The loaded C library, or None (no compiler, ``GUARDID_NATIVE=0``, or
    :data:`USE_NATIVE` off)."""
    return _load() if USE_NATIVE else None


def _c(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float)


def hopfield_samples(lib, A, y, S, c, s0, inv_c: float, smax: float, every: int):
    """The Hopfield network over A (N, 2, p), y (N, 2) from the state s0 (p,): (final
    state (p,), states after every ``every``-th sample (N // every, p)). S, c (p,) the box's
    half-widths and centre (or one for all: broadcast to (p,) as the Python path does),
    ``inv_c`` = beta / dt [unit of y^2], ``smax`` the clip."""
    N, n, p = A.shape
    if n != 2 or y.shape != (N, 2) or np.shape(s0) != (p,) or int(every) < 1:
        raise ValueError(f"hopfield kernel: A {A.shape}, y {y.shape}, s {np.shape(s0)}")
    A, y = _c(A), _c(y)
    S, c = (_c(np.broadcast_to(np.asarray(x, dtype=float), (p,))) for x in (S, c))
    s = np.array(s0, dtype=float)
    hist, work = np.empty((N // every, p)), np.empty(4 * p)
    lib.guardid_hopfield_samples(N, p, A.ctypes.data, y.ctypes.data, S.ctypes.data,
                                 c.ctypes.data, inv_c, smax, int(every), s.ctypes.data,
                                 hist.ctypes.data, work.ctypes.data)  # fmt: skip
    return s, hist


def gradient_samples(lib, A, y, gAT, theta0, every: int, check: int, blowup: float,
                     hop_gain: float = 0.0):  # fmt: skip
    """theta += gAT_k (y_k - A_k theta) over A (N, n, p), y (N, n), gAT (N, p, n) from
    theta0 (p,), stopping at a check (every ``check`` samples) where max |theta| is not
    below ``blowup``: (theta (p,), theta after every ``every``-th sample done, samples
    done). ``hop_gain`` > 0: theta += hop_gain (1 - theta^2) gAT_k (y_k - A_k theta)
    instead (the Hopfield network's explicit Euler step in s)."""
    N, n, p = A.shape
    if y.shape != (N, n) or gAT.shape != (N, p, n) or np.shape(theta0) != (p,):
        raise ValueError(f"gradient kernel: A {A.shape}, y {y.shape}, gAT {gAT.shape}")
    if int(every) < 1 or int(check) < 1:
        raise ValueError("gradient kernel: every and check must be >= 1")
    A, y, gAT = _c(A), _c(y), _c(gAT)
    th = np.array(theta0, dtype=float)
    hist, work = np.empty((N // every, p)), np.empty(n)
    done = lib.guardid_gradient_samples(N, n, p, A.ctypes.data, y.ctypes.data, gAT.ctypes.data,
                                        int(every), int(check), blowup, hop_gain, th.ctypes.data,
                                        hist.ctypes.data, work.ctypes.data)  # fmt: skip
    return th, hist[: done // every], done


def mlp_epoch(lib, Xn, An, yn, perm, B: int, lr: float, mu: float, wd: float, w, vel, h: int):
    """One epoch of the MLP's mini-batch descent over the samples in the order ``perm``
    (N,), batches of ``B``: Xn (N, k), An (N, n, p), yn (N, n) normalised; the weights
    W1 (k, h), b1 (h,), W2 (h, p), b2 (p,) flat in that order in ``w`` and their
    velocities in ``vel`` (C-ordered float64), updated in place."""
    N, n, p = An.shape
    k = Xn.shape[1]
    size = k * h + h + h * p + p
    for a in (w, vel):
        if not (a.dtype == np.float64 and a.shape == (size,) and a.flags.c_contiguous):
            raise ValueError(f"mlp kernel: weights of {a.dtype} {a.shape}, expected ({size},)")
    Xn, An, yn = _c(Xn), _c(An), _c(yn)
    perm = np.ascontiguousarray(perm, dtype=np.int64)
    if Xn.shape != (N, k) or yn.shape != (N, n) or perm.shape != (N,) or not 1 <= B <= N:
        raise ValueError(f"mlp kernel: Xn {Xn.shape}, An {An.shape}, yn {yn.shape}, B {B}")
    if N and (perm.min() < 0 or perm.max() >= N):
        raise ValueError("mlp kernel: perm indexes beyond the samples")
    work = np.empty(2 * B * h + B * p + n + p + size)
    lib.guardid_mlp_epoch(N, int(B), k, h, n, p, Xn.ctypes.data, An.ctypes.data,
                          yn.ctypes.data, perm.ctypes.data, lr, mu, wd, w.ctypes.data,
                          vel.ctypes.data, work.ctypes.data)  # fmt: skip
