"""Straight-line code generation for the rigid-body regressor of a serial chain.

A tiny constant-folding emitter records a Newton-Euler recursion (forward: link velocities
and accelerations; backward: each standard parameter's wrench carried down the chain) as
Python source. Values are floats (constants, folded at build time) or names of temporaries,
so zero terms vanish. The same source runs on floats (math) or on numpy arrays (one element
per sample), which gives both the vectorised regressor and the fast single-sample evaluators.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from guardid.robot.description import ChainDescription

Value = float | tuple  # a constant, or (k, name) meaning k * name


class Emitter:
    """Records assignments ``tK = <expr>`` with constant folding and common subexpressions.

    A symbolic value is (k, name): a scale factor k kept out of the emitted code, so that
    negations and constant factors cost nothing and x - x folds to 0. Operands of
    commutative operations are ordered so that a*b and b*a share one temporary.
    """

    def __init__(self) -> None:
        self.lines: list[str] = []
        self._cache: dict[str, str] = {}

    def lift(self, v) -> Value:
        """A Value from a float or an input variable name."""
        return (1.0, v) if isinstance(v, str) else float(v)

    def _new(self, expr: str) -> tuple:
        name = self._cache.get(expr)
        if name is None:
            name = f"t{len(self._cache)}"
            self._cache[expr] = name
            self.lines.append(f"{name} = {expr}")
        return (1.0, name)

    def add(self, a: Value, b: Value) -> Value:
        """a + b."""
        if isinstance(a, float) and isinstance(b, float):
            return a + b
        if isinstance(a, float):
            a, b = b, a
        if isinstance(b, float):
            if b == 0.0:
                return a
            ka, na = a
            r = b / ka
            expr = f"{na} + {r!r}" if r > 0 else f"{na} - {-r!r}"
            return self.mul(ka, self._new(expr))
        (ka, na), (kb, nb) = a, b
        if na == nb:
            k = ka + kb
            return 0.0 if k == 0.0 else (k, na)
        if nb < na:
            (ka, na), (kb, nb) = (kb, nb), (ka, na)
        r = kb / ka
        if abs(r) == 1.0:
            expr = f"{na} + {nb}" if r > 0 else f"{na} - {nb}"
        else:
            expr = f"{na} + {r!r} * {nb}" if r > 0 else f"{na} - {-r!r} * {nb}"
        return self.mul(ka, self._new(expr))

    def sub(self, a: Value, b: Value) -> Value:
        """a - b."""
        return self.add(a, self.neg(b))

    def neg(self, a: Value) -> Value:
        """-a."""
        return self.mul(-1.0, a)

    def mul(self, a: Value, b: Value) -> Value:
        """a * b."""
        if isinstance(a, float) and isinstance(b, float):
            return a * b
        if isinstance(b, float):
            a, b = b, a
        if isinstance(a, float):
            return 0.0 if a == 0.0 else (a * b[0], b[1])
        (ka, na), (kb, nb) = a, b
        lo, hi = sorted((na, nb))
        _, name = self._new(f"{lo} * {hi}")
        return (ka * kb, name)

    def call(self, func: str, a: Value) -> Value:
        """func(a) for a named function in the execution namespace (sin, cos)."""
        if isinstance(a, float):
            return float(getattr(math, func)(a))
        return self._new(f"{func}({fmt(a)})")

    def dot(self, u, v) -> Value:
        """Dot product of two 3-vectors."""
        return self.add(self.add(self.mul(u[0], v[0]), self.mul(u[1], v[1])), self.mul(u[2], v[2]))

    def cross(self, u, v) -> list[Value]:
        """Cross product u x v of two 3-vectors."""
        return [
            self.sub(self.mul(u[1], v[2]), self.mul(u[2], v[1])),
            self.sub(self.mul(u[2], v[0]), self.mul(u[0], v[2])),
            self.sub(self.mul(u[0], v[1]), self.mul(u[1], v[0])),
        ]

    def vadd(self, u, v) -> list[Value]:
        """u + v for 3-vectors."""
        return [self.add(a, b) for a, b in zip(u, v, strict=True)]

    def vscale(self, s: Value, u) -> list[Value]:
        """s * u for a scalar s and a 3-vector u."""
        return [self.mul(s, a) for a in u]


def fmt(v: Value) -> str:
    """Python source of a Value."""
    if isinstance(v, float):
        return f"({v!r})" if v < 0 else repr(v)
    k, name = v
    if k == 1.0:
        return name
    if k == -1.0:
        return f"(-{name})"
    return f"({k!r} * {name})"


def _clean(x: float) -> float:
    """Round trigonometric constants such as cos(pi/2) = 6e-17 to exact zeros and ones."""
    for exact in (0.0, 1.0, -1.0):
        if abs(x - exact) < 1e-15:
            return exact
    return float(x)


class _Joint:
    """Per-joint geometry during generation: sin/cos of theta, DH constants."""

    def __init__(self, em: Emitter, joint, q: Value):
        dh = joint.dh
        self.revolute = joint.type == "revolute"
        self.sa, self.ca = _clean(math.sin(dh.alpha)), _clean(math.cos(dh.alpha))
        if self.revolute:
            theta = em.add(q, float(dh.theta))
            self.st, self.ct = em.call("sin", theta), em.call("cos", theta)
            d = float(dh.d)
        else:
            self.st, self.ct = _clean(math.sin(dh.theta)), _clean(math.cos(dh.theta))
            d = em.add(q, float(dh.d))
        self.z = [0.0, self.sa, self.ca]  # joint axis z_{j-1} in frame j
        self.p = [float(dh.a), em.mul(d, self.sa), em.mul(d, self.ca)]  # origin j-1 -> j, frame j

    def to_child(self, em: Emitter, v):
        """R_{j-1,j}^T v: a vector of frame j-1 expressed in frame j."""
        u0 = em.add(em.mul(self.ct, v[0]), em.mul(self.st, v[1]))
        u1 = em.sub(em.mul(self.ct, v[1]), em.mul(self.st, v[0]))
        return [
            u0,
            em.add(em.mul(self.ca, u1), em.mul(self.sa, v[2])),
            em.sub(em.mul(self.ca, v[2]), em.mul(self.sa, u1)),
        ]

    def to_parent(self, em: Emitter, v):
        """R_{j-1,j} v: a vector of frame j expressed in frame j-1."""
        w1 = em.sub(em.mul(self.ca, v[1]), em.mul(self.sa, v[2]))
        w2 = em.add(em.mul(self.sa, v[1]), em.mul(self.ca, v[2]))
        return [
            em.sub(em.mul(self.ct, v[0]), em.mul(self.st, w1)),
            em.add(em.mul(self.st, v[0]), em.mul(self.ct, w1)),
            w2,
        ]


_INERTIA_INDEX = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))  # XX XY XZ YY YZ ZZ


def rigid_regressor(em: Emitter, chain: ChainDescription, q, qd, qdd, gravity: bool):
    """Emit the rigid-body regressor; return Y[j][c] (n x 10n) of Values.

    q, qd, qdd are per-joint Values (names or constants); gravity=False drops g.
    """
    n = chain.n_dof
    q, qd, qdd = ([em.lift(v) for v in x] for x in (q, qd, qdd))
    joints = [_Joint(em, chain.joints[j], q[j]) for j in range(n)]
    g = [float(x) for x in chain.gravity] if gravity else [0.0, 0.0, 0.0]
    w: list[Value] = [0.0, 0.0, 0.0]
    wd: list[Value] = [0.0, 0.0, 0.0]
    acc: list[Value] = [-g[0], -g[1], -g[2]]
    kin = []
    for j, jt in enumerate(joints):
        w_c, wd_c, acc_c = jt.to_child(em, w), jt.to_child(em, wd), jt.to_child(em, acc)
        qdz = em.vscale(qd[j], jt.z)
        if jt.revolute:
            w = em.vadd(w_c, qdz)
            wd = em.vadd(em.vadd(wd_c, em.vscale(qdd[j], jt.z)), em.cross(w_c, qdz))
            acc = acc_c
        else:
            w, wd = w_c, wd_c
            coriolis = em.vscale(2.0, em.cross(w, qdz))
            acc = em.vadd(em.vadd(acc_c, em.vscale(qdd[j], jt.z)), coriolis)
        acc = em.vadd(acc, em.vadd(em.cross(wd, jt.p), em.cross(w, em.cross(w, jt.p))))
        kin.append((w, wd, acc))
    y = [[0.0] * (10 * n) for _ in range(n)]
    for k in range(n):
        w, wd, acc = kin[k]
        for c, (f, mom) in enumerate(_link_wrench_columns(em, w, wd, acc)):
            for j in range(k, -1, -1):
                jt = joints[j]
                mom = em.vadd(mom, em.cross(jt.p, f))  # about origin j-1, frame j
                y[j][10 * k + c] = em.dot(jt.z, mom if jt.revolute else f)
                if j > 0:
                    f, mom = jt.to_parent(em, f), jt.to_parent(em, mom)
    return y


def _link_wrench_columns(em: Emitter, w, wd, acc):
    """Wrench (force, moment about the frame origin) per unit of each standard parameter."""
    cols = []
    for r, c in _INERTIA_INDEX:
        e = [[0.0] * 3 for _ in range(3)]
        e[r][c] = e[c][r] = 1.0
        e_wd = [em.dot(row, wd) for row in e]
        e_w = [em.dot(row, w) for row in e]
        cols.append(([0.0, 0.0, 0.0], em.vadd(e_wd, em.cross(w, e_w))))
    for i in range(3):
        unit = [0.0, 0.0, 0.0]
        unit[i] = 1.0
        force = em.vadd(em.cross(wd, unit), em.cross(w, em.cross(w, unit)))
        cols.append((force, em.cross(unit, acc)))
    cols.append((list(acc), [0.0, 0.0, 0.0]))
    return cols


def compile_source(src: str, name: str, namespace: dict):
    """Exec generated source and return the function ``name``."""
    ns = dict(namespace)
    exec(_code(src, name), ns)  # noqa: S102
    return ns[name]


@functools.lru_cache(maxsize=64)
def _code(src: str, name: str):
    """The compiled code of ``src`` (a process builds the same few models again and again:
    every command loads its robot, and the test suite runs hundreds of commands)."""
    return compile(src, f"<guardid generated {name}>", "exec")


class _KJoint(NamedTuple):
    """What the generated code reads of a joint."""

    type: str
    dh: object


class _Kinematics(NamedTuple):
    """What the generated code reads of a chain (hashable: the key of the sources' cache)."""

    joints: tuple
    gravity: tuple

    @property
    def n_dof(self) -> int:
        return len(self.joints)

    @classmethod
    def of(cls, chain: ChainDescription) -> _Kinematics:
        joints = tuple(_KJoint(j.type, j.dh) for j in chain.joints)
        return cls(joints, tuple(float(g) for g in chain.gravity))


def vector_regressor_source(chain: ChainDescription) -> str:
    """Source of ``rigid_regressor(q, qd, qdd, out)`` on (N, n) arrays, out (N, n, 10n)."""
    return _vector_regressor_source(_Kinematics.of(chain))


@functools.lru_cache(maxsize=32)
def _vector_regressor_source(chain: _Kinematics) -> str:
    n = chain.n_dof
    em = Emitter()
    names = [[f"{v}{j}" for j in range(n)] for v in ("q", "qd", "qdd")]
    y = rigid_regressor(em, chain, *names, gravity=True)
    head = ["def rigid_regressor(q, qd, qdd, out):"]
    for v, arr in (("q", "q"), ("qd", "qd"), ("qdd", "qdd")):
        head += [f"    {v}{j} = {arr}[:, {j}]" for j in range(n)]
    body = [f"    {line}" for line in em.lines]
    for j in range(n):
        for c in range(10 * n):
            if y[j][c] != 0.0:
                body.append(f"    out[:, {j}, {c}] = {fmt(y[j][c])}")
    return "\n".join(head + body + ["    return out", ""])


def fast_sources(
    chain: ChainDescription, extra_inertia: list[int | None], extra_vectors=None
) -> str:
    """Source of ``mass_matrix_1(q, params=None)`` and ``bias_1(q, qd, params=None)``.

    ``extra_inertia[j]`` is the index in the parameter vector of joint j's reflected rotor
    inertia or None; it adds p[idx] u u^T to M with u = ``extra_vectors[j]`` (n,) (constant;
    default e_j: M[j, j] only). Friction is not part of either function.
    """
    vectors = None if extra_vectors is None else tuple(_floats(u) for u in extra_vectors)
    return _fast_sources(_Kinematics.of(chain), tuple(extra_inertia), vectors)


def _floats(u) -> tuple | None:
    return None if u is None else tuple(float(x) for x in u)


@functools.lru_cache(maxsize=32)
def _fast_sources(chain: _Kinematics, extra_inertia: tuple, extra_vectors: tuple | None) -> str:
    n = chain.n_dof
    qn = [f"q{j}" for j in range(n)]
    unpack_q = f"    {', '.join(qn)}, = q.tolist() if isinstance(q, ndarray) else q"
    unpack_p = (
        "    p = P0 if params is None else "
        "(params.tolist() if isinstance(params, ndarray) else params)"
    )
    em = Emitter()
    cols = []
    for i in range(n):
        qdd = [1.0 if j == i else 0.0 for j in range(n)]
        cols.append(rigid_regressor(em, chain, qn, [0.0] * n, qdd, gravity=False))
    entries = {}
    for j in range(n):
        for i in range(j + 1):
            terms = [(y, c) for c, y in enumerate(cols[i][j]) if y != 0.0]
            for k, idx in enumerate(extra_inertia):
                if idx is None:
                    continue
                u = extra_vectors[k] if extra_vectors is not None else None
                coef = float(u[j] * u[i]) if u is not None else float(i == j == k)
                if coef != 0.0:
                    terms.append((coef, idx))
            entries[j, i] = _sum_expr(terms)
    rows = ", ".join(
        "[" + ", ".join(entries[max(a, b), min(a, b)] for b in range(n)) + "]" for a in range(n)
    )
    mm = ["def mass_matrix_1(q, params=None):", unpack_q, unpack_p]
    mm += [f"    {line}" for line in em.lines] + [f"    return array([{rows}])", ""]
    em = Emitter()
    qdn = [f"qd{j}" for j in range(n)]
    y = rigid_regressor(em, chain, qn, qdn, [0.0] * n, gravity=True)
    taus = [_sum_expr([(v, c) for c, v in enumerate(y[j]) if v != 0.0]) for j in range(n)]
    bb = [
        "def bias_1(q, qd, params=None):",
        unpack_q,
        f"    {', '.join(qdn)}, = qd.tolist() if isinstance(qd, ndarray) else qd",
        unpack_p,
    ]
    bb += [f"    {line}" for line in em.lines] + [f"    return array([{', '.join(taus)}])", ""]
    return "\n".join(mm + bb)


def _sum_expr(terms) -> str:
    if not terms:
        return "0.0"
    parts = []
    for coef, idx in terms:
        parts.append(f"p[{idx}]" if coef == 1.0 else f"{fmt(coef)} * p[{idx}]")
    return " + ".join(parts)


NAMESPACE_VECTOR = {"sin": np.sin, "cos": np.cos}
NAMESPACE_SCALAR = {"sin": math.sin, "cos": math.cos, "array": np.array, "ndarray": np.ndarray}
