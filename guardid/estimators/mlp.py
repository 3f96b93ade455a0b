"""Multilayer-perceptron estimator (seed 001 section 3.3, eqs. 14-31; DESIGN.md section 5).

A one-hidden-layer network maps the state of a sample to the parameter vector,

    x = (q, q', q'')  (3n inputs, eq. 14/31)  ->  20 tanh units (eq. 30)  ->  p linear
    outputs = theta_net(x)  (eq. 15),

and is trained by backpropagation *through the regressor*: the output is not compared with
a target theta (none is known) but enters the torque prediction tau_hat = A(x) theta_net(x),
and the loss is the squared torque error (eq. 23). The chain rule of eqs. 24-28 is

    dF/dtheta_net = A^T (tau_hat - tau),  then the usual output- and hidden-layer steps.

What is reported: ``theta_`` is the network's mean output over the fit data and
``output_spread_`` its spread (standard deviation over the samples, ddof = 0). The true
parameters are constant, so a well-trained network has a small spread; the spread is *not*
a standard deviation of the estimate (the network is free to move its output along the
regressor's null space, which the torque cannot see, and that freedom grows as the rows get
fewer: on 16 seeded 60 s guard captures, ``sim://guard?seed=N&phase=1``, 2026-11-26, the
truth lay within 3 spreads in 58 % of the (seed, parameter) pairs, against WLS's 100 %
within 3 std; Fv2 came out 2.04 for 1.2 at a median 9 spreads). The MLP therefore has no
``std_``: ``guardid identify`` shows the spread as "~ spread", params.yaml stores it as
``output_spread``, and nothing that needs a standard deviation (the verdict, the reference
method, validate) uses it.

Normalisation (fixed at ``fit`` from the fit data, stored, reused by ``update``):

* inputs: each state column standardised, x_n = (x - x_mean_) / x_std_ (a constant column
  keeps std 1), so the tanh units start in their linear range whatever the units of q, q',
  q'' (rad, rad/s, rad/s^2);
* outputs: theta_net = theta_scale_ * o, o the raw linear output, with
  theta_scale_[j] = rms(y) / rms(A[:, :, j]) (rms over all rows; 1 for a zero column). The
  network thus fits y / rms(y) with regressor columns of unit rms: the loss surface, the
  learning rate and the initialisation are dimensionless and the same for every robot and
  unit system (a Jacobi preconditioning of the regressor; plain gradient descent on the raw
  columns would crawl along the small ones).

Training: gradient descent on F = 1 / (2 B) sum_k ||A_k theta_net(x_k) - y_k||^2 (+ the
weight decay below) in those normalised units, B samples per step: shuffled mini-batches
(``batch_size`` samples, the default 64, seeded shuffle, a last shorter batch per epoch) or
full batch (``batch_size=None``: one step per epoch on all samples). ``momentum`` = 0 is the
paper's plain backpropagation (eqs. 17-21: w -= lr dF/dw); > 0 (default 0.9) adds heavy-ball
momentum (v = momentum v - lr dF/dw; w += v), which needs far fewer steps on ill-conditioned
regressors. Training stops after ``epochs`` epochs (None: enough epochs for
:data:`AUTO_STEPS` steps), when the mean squared torque error (raw units, (unit of y)^2, over
all rows, checked after each epoch) reaches ``target`` (the paper's "target value"), or when
it diverges (non-finite loss: ``diverged_``, theta_ is then NaN).

Converged (``converged_``): the target was reached (``target_reached_``), or the training
loss has levelled off (``plateaued_``): the best mean squared torque error of the last
:data:`PLATEAU_FRACTION` of the epochs is less than :data:`PLATEAU_REL` below the best
before them. A network stopped by its epoch budget while its loss still falls is not
converged: more training would change its output.

Weight decay (not in the paper; ``weight_decay=0`` gives the paper's plain loss): the
penalty (weight_decay / 2) ||W2||^2 on the output weights only pulls the network towards a
constant output, i.e. towards a single parameter vector, which is what the physics says. With
few rows (the guard pipeline's ~250 decimated rows for 12 base parameters) the plain loss
lets the output wander along the regressor's null space: on a 60 s guard capture the mean
estimate ended tens of LS standard deviations from LS (d_tau of the mean 30-37 % against LS's
1.1 %); the default 0.1 brought it within ~5 LS standard deviations (d_tau 1.14 %). On seed
001's 20001 rows both settings land within 0.3 % of the truth.

Initialisation (seeded by ``seed``): W1 ~ N(0, 1 / n_in), b1 = 0, W2 ~ N(0, init_scale^2 /
n_hidden), b2 = theta0 / theta_scale_ (zeros when ``theta0`` is None). A small W2 starts the
network near a constant output, from where gradient descent finds the constant solution the
data can see before it spends effort on state-dependent corrections.

The mini-batch epochs run in C when a compiler is at hand
(:mod:`guardid.estimators.native_loops`: the same steps to round-off, ~5x faster;
``GUARDID_NATIVE=0``: numpy).

Online: ``update(A_k, y_k, x_k)`` takes one plain gradient step (learning rate ``lr``, with
momentum if set) on that one sample, with the normalisation of the last ``fit`` (a ``fit``
is required first). ``theta_`` then becomes the network's output at x_k (its current
estimate at the newest state); ``output_spread_`` is left from the last ``fit``.
"""

from __future__ import annotations

import numpy as np

from . import native_loops
from ._base import Estimator, as_blocks, as_sample

_WEIGHTS = ("W1", "b1", "W2", "b2")
AUTO_STEPS = 5000
"""Gradient steps of the default training budget (``epochs=None``) [-]: enough for the
mean estimate to settle on the guard robot's base regressor (cond(A) ~ 150, ~250 rows) and
on seed 001's planar arm (20001 rows: 16 epochs of 64-sample batches)."""
PLATEAU_FRACTION = 0.25
"""The share of the epochs (at least 2) whose best loss is compared with the best before [-]."""
PLATEAU_REL = 0.01
"""Converged on a plateau when that best improved on the best before by less than this [-]."""


def _rms(a: np.ndarray, axis) -> np.ndarray:
    return np.sqrt(np.mean(np.square(a), axis=axis))


class MLP(Estimator):
    """Seed 001's multilayer network estimator: state -> tanh layer -> linear theta.

    Parameters: ``n_hidden`` tanh units (the paper's 20); ``lr`` learning rate
    (dimensionless: the step on the normalised problem, see the module docstring; without
    momentum, stable below about 2 / (n_out p)); ``epochs`` maximum number of passes over the
    data (None: :data:`AUTO_STEPS` steps' worth); ``target`` stop when the mean squared torque
    error reaches it [(unit of y)^2] (0: never stop early); ``batch_size`` samples per step
    (None: full batch); ``momentum`` in [0, 1) (0: plain backpropagation); ``init_scale``
    spread of the initial output weights [-]; ``theta0`` (p,) initial output bias in the
    units of theta (None: zeros); ``seed`` of the initialisation and of the mini-batch
    shuffle; ``weight_decay`` L2 penalty on the output weights [-] (0: the paper's loss).

    ``fit(A, y, X)`` needs the states: ``X`` (N, k) one row per sample, normally (q, q',
    q'') of the n joints, k = 3n [rad, rad/s, rad/s^2] (any k works; X is standardised).

    Attributes after ``fit``: ``theta_`` (p,) mean network output over the fit samples
    (units of theta); ``output_spread_`` (p,) its standard deviation over the samples (not
    an uncertainty of ``theta_``, see the module docstring); ``weights_`` dict W1 (k, h),
    b1 (h,), W2 (h, p), b2 (p,) (normalised units); ``x_mean_``, ``x_std_`` (k,) input
    normalisation; ``theta_scale_`` (p,) output scaling [unit of theta]; ``y_scale_``
    rms(y) [unit of y]; ``loss_`` final mean squared torque error [(unit of y)^2];
    ``loss_history_`` (n_epochs_,) that error after each epoch; ``theta_history_``,
    ``spread_history_`` (n_epochs_, p) mean and spread of the output after each epoch;
    ``n_epochs_`` epochs run; ``converged_`` (target reached or loss levelled off, module
    docstring), ``target_reached_``, ``plateaued_``; ``diverged_``; ``n_samples_`` N.
    ``history_`` is None (batch estimator).
    """

    def __init__(
        self,
        n_hidden: int = 20,
        lr: float = 0.02,
        epochs: int | None = None,
        target: float = 0.0,
        batch_size: int | None = 64,
        momentum: float = 0.9,
        init_scale: float = 0.01,
        theta0=None,
        seed: int = 0,
        weight_decay: float = 0.1,
    ):
        if not 0.0 <= momentum < 1.0:
            raise ValueError("momentum must be in [0, 1)")
        if n_hidden < 1 or (epochs is not None and epochs < 0) or lr <= 0 or weight_decay < 0:
            raise ValueError("n_hidden >= 1, epochs >= 0, lr > 0, weight_decay >= 0 required")
        self.n_hidden = int(n_hidden)
        self.lr = float(lr)
        self.epochs = None if epochs is None else int(epochs)
        self.target = float(target)
        self.batch_size = None if batch_size is None else int(batch_size)
        self.momentum = float(momentum)
        self.init_scale = float(init_scale)
        self.theta0 = theta0
        self.seed = seed
        self.weight_decay = float(weight_decay)

    # -- normalised network ----------------------------------------------------------------
    def _forward(self, Xn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Hidden activations H (B, h) and raw outputs O (B, p) for normalised inputs."""
        w = self.weights_
        H = np.tanh(Xn @ w["W1"] + w["b1"])
        return H, H @ w["W2"] + w["b2"]

    def _loss_grad(self, Xn, An, yn) -> tuple[float, dict]:
        """Normalised loss F = 1/(2B) sum ||An o - yn||^2 and its gradient (backprop)."""
        w = self.weights_
        H, O = self._forward(Xn)
        E = np.einsum("bij,bj->bi", An, O) - yn  # torque error (B, n_out)
        B = Xn.shape[0]
        G = np.einsum("bij,bi->bj", An, E) / B  # dF/do = A^T e (eqs. 24-27)
        dZ = (G @ w["W2"].T) * (1.0 - H * H)  # back through tanh (eq. 28-30)
        wd = self.weight_decay
        grads = {
            "W2": H.T @ G + wd * w["W2"],
            "b2": G.sum(axis=0),
            "W1": Xn.T @ dZ,
            "b1": dZ.sum(axis=0),
        }
        pen = 0.5 * wd * float(np.sum(w["W2"] ** 2)) if wd else 0.0
        return 0.5 * float(np.sum(E * E)) / B + pen, grads

    def loss_grad(self, A, y, X) -> tuple[float, dict]:
        """Loss and backprop gradient for the current weights on (A, y, X).

        Uses the normalisation of the last ``fit`` (for tests: the gradient check). The loss is
        F = 1/(2N) sum_k ||A_k theta_net(x_k) - y_k||^2 / rms(y)^2 + (weight_decay / 2)
        ||W2||^2 [-]; the gradient is a dict of arrays shaped like ``weights_``.
        """
        Xn, An, yn = self._normalise(A, y, X)
        return self._loss_grad(Xn, An, yn)

    def _normalise(self, A, y, X):
        A3, y2 = as_blocks(A, y)
        X = np.asarray(X, dtype=float).reshape(A3.shape[0], -1)
        Xn = (X - self.x_mean_) / self.x_std_
        An = A3 * (self.theta_scale_ / self.y_scale_)
        return Xn, An, y2 / self.y_scale_

    def theta_net(self, X) -> np.ndarray:
        """The network's parameter estimate at each state: (N, p) [units of theta]."""
        Xn = (np.atleast_2d(np.asarray(X, dtype=float)) - self.x_mean_) / self.x_std_
        return self._forward(Xn)[1] * self.theta_scale_

    def predict(self, A, X=None) -> np.ndarray:
        """A theta_ (mean estimate), or per sample A_k theta_net(x_k) when ``X`` is given."""
        if X is None:
            return super().predict(A)
        A3, _ = as_blocks(A, np.zeros(np.shape(A)[:-1]))
        out = np.einsum("nij,nj->ni", A3, self.theta_net(np.reshape(X, (A3.shape[0], -1))))
        return out if np.ndim(A) == 3 else out[:, 0]

    # -- training ---------------------------------------------------------------------------
    def _init(self, A3, y2, X) -> None:
        N, _, p = A3.shape
        k = X.shape[1]
        self.x_mean_ = X.mean(axis=0)
        sd = X.std(axis=0)
        self.x_std_ = np.where(sd > 0, sd, 1.0)
        ys = float(_rms(y2, None))
        self.y_scale_ = ys if ys > 0 else 1.0
        col = _rms(A3.reshape(-1, p), 0)
        self.theta_scale_ = np.where(col > 0, self.y_scale_ / np.where(col > 0, col, 1.0), 1.0)
        rng = np.random.default_rng(self.seed)
        h = self.n_hidden
        b2 = np.zeros(p) if self.theta0 is None else np.asarray(self.theta0, float).copy()
        self.weights_ = {
            "W1": rng.normal(0.0, 1.0 / np.sqrt(k), (k, h)),
            "b1": np.zeros(h),
            "W2": rng.normal(0.0, self.init_scale / np.sqrt(h), (h, p)),
            "b2": b2 / self.theta_scale_,
        }
        self._vel = {n: np.zeros_like(v) for n, v in self.weights_.items()}
        self._rng = rng

    def _pack(self) -> tuple[np.ndarray, np.ndarray]:
        """The weights and their velocities each as one flat array (W1, b1, W2, b2 in that
        order, C order), the dicts' entries becoming views of them: what the C epoch
        (:func:`guardid.estimators.native_loops.mlp_epoch`) updates in place."""
        flats = []
        for d in (self.weights_, self._vel):
            flat = np.concatenate([d[n].ravel() for n in _WEIGHTS])
            at = 0
            for n in _WEIGHTS:
                d[n] = flat[at : at + d[n].size].reshape(d[n].shape)
                at += d[n].size
            flats.append(flat)
        return flats[0], flats[1]

    def _step(self, grads: dict) -> None:
        mu, lr = self.momentum, self.lr
        for n in _WEIGHTS:
            if mu:
                v = self._vel[n]
                v *= mu
                v -= lr * grads[n]
                self.weights_[n] += v
            else:
                self.weights_[n] -= lr * grads[n]

    def fit(self, A, y, X=None):
        """Train on A (N, n_out, p) / y (N, n_out) (or stacked (M, p) / (M,)) and X (N, k).

        X holds the network's inputs, one row per sample: (q, q', q'') of the n joints
        (k = 3n, [rad, rad/s, rad/s^2]) for seed 001's network. Required.
        """
        if X is None:
            raise ValueError("MLP needs the states: fit(A, y, X=states), X (N, 3n) = (q, q', q'')")
        A3, y2 = as_blocks(A, y)
        N, _, p = A3.shape
        X = np.asarray(X, dtype=float)
        if X.ndim == 1:
            X = X[:, None]
        if X.ndim != 2 or X.shape[0] != N:
            raise ValueError(f"X {X.shape}: expected ({N}, k), one row of states per sample")
        self._init(A3, y2, X)
        Xn, An, yn = self._normalise(A3, y2, X)
        ys2 = self.y_scale_**2
        B = N if self.batch_size is None else max(1, min(self.batch_size, N))
        epochs = self.epochs
        if epochs is None:  # a budget of AUTO_STEPS gradient steps, whatever N
            epochs = -(-AUTO_STEPS // -(-N // B))
        loss_h, mean_h, spread_h = [], [], []
        self.target_reached_ = self.diverged_ = False
        lib = native_loops.kernel() if B < N else None
        if lib is not None:
            flat, vel = self._pack()
        with np.errstate(over="ignore", invalid="ignore"):
            for _ in range(epochs):
                if B == N:
                    self._step(self._loss_grad(Xn, An, yn)[1])
                elif lib is not None:  # the loop below, in C
                    perm = self._rng.permutation(N)
                    mu, lr, wd, h = self.momentum, self.lr, self.weight_decay, self.n_hidden
                    native_loops.mlp_epoch(lib, Xn, An, yn, perm, B, lr, mu, wd, flat, vel, h)
                else:
                    perm = self._rng.permutation(N)
                    for s in range(0, N, B):
                        idx = perm[s : s + B]
                        self._step(self._loss_grad(Xn[idx], An[idx], yn[idx])[1])
                O = self._forward(Xn)[1]
                E = np.einsum("nij,nj->ni", An, O) - yn
                mse = float(np.mean(E * E)) * ys2  # raw (unit of y)^2 per row
                th = O * self.theta_scale_
                loss_h.append(mse)
                mean_h.append(th.mean(axis=0))
                spread_h.append(th.std(axis=0))
                if not np.isfinite(mse):
                    self.diverged_ = True
                    break
                if mse <= self.target:
                    self.target_reached_ = True
                    break
        self.n_epochs_ = len(loss_h)
        self.loss_history_ = np.array(loss_h)
        self.theta_history_ = np.array(mean_h).reshape(-1, p)
        self.spread_history_ = np.array(spread_h).reshape(-1, p)
        self.plateaued_ = not self.diverged_ and loss_plateau(self.loss_history_)
        self.converged_ = not self.diverged_ and (self.target_reached_ or self.plateaued_)
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            th = self._forward(Xn)[1] * self.theta_scale_
            self.theta_ = th.mean(axis=0)
            self.output_spread_ = th.std(axis=0)
            E = y2 - np.einsum("nij,nj->ni", A3, th)
            self.loss_ = float(np.mean(E * E))
        self.n_samples_ = N
        return self

    def update(self, A_k, y_k, x_k=None):
        """One gradient step on one sample A_k (n_out, p), y_k (n_out,), state x_k (k,).

        Uses the normalisation of the last ``fit`` (required first) and the learning rate /
        momentum of the constructor. ``theta_`` becomes theta_net(x_k) [units of theta].
        """
        if not hasattr(self, "weights_"):
            raise RuntimeError("MLP.update needs a prior fit(A, y, X) (it fixes the scaling)")
        if x_k is None:
            raise ValueError("MLP.update needs the state: update(A_k, y_k, x_k)")
        A_k, y_k = as_sample(A_k, y_k)
        Xn, An, yn = self._normalise(A_k[None], y_k[None], np.reshape(x_k, (1, -1)))
        self._step(self._loss_grad(Xn, An, yn)[1])
        self.theta_ = self._forward(Xn)[1][0] * self.theta_scale_
        self.n_samples_ += 1
        return self


def plateau_window(n_epochs: int) -> int:
    """Epochs at the end of training compared with the ones before: :data:`PLATEAU_FRACTION`
    of ``n_epochs``, at least 2."""
    return max(2, int(round(PLATEAU_FRACTION * n_epochs)))


def last_improvement(loss) -> float:
    """1 - (best loss of the last :func:`plateau_window` epochs) / (best before them) [-]:
    how much the loss history (n_epochs,) still fell at the end; NaN with fewer than 4
    epochs or a non-finite loss."""
    loss = np.asarray(loss, dtype=float)
    if len(loss) < 4 or not np.all(np.isfinite(loss)):
        return float("nan")
    q = plateau_window(len(loss))
    before = loss[:-q].min()
    return float(1.0 - loss[-q:].min() / before) if before > 0 else 0.0


def loss_plateau(loss) -> bool:
    """True when the loss history has levelled off: :func:`last_improvement` below
    :data:`PLATEAU_REL` (False when it is NaN)."""
    return bool(last_improvement(loss) < PLATEAU_REL)
