"""Sums of sinusoids and Schroeder-phased multisines (seed 000 eq. 26).

Sum of sines, per joint j with components k:

    q_j(t) = c_j + sum_k A_jk sin(2 pi f_jk t + phi_jk)     [rad; A rad, f Hz, phi rad]

Schroeder multisine: the same with equal amplitudes A_j per component and Schroeder's
low-crest-factor phases phi_k = -pi k (k - 1) / K, k = 1..K (K components of the joint).
Seed 000 eq. 26 is the K = 3 case, u = (1/2)[sin 2t + sin(2t - 2pi/3) + sin(5t - 2pi)]
(phases 0, -2pi/3, -2pi; frequencies 2, 2, 5 rad/s as printed, see
:meth:`SchroederMultisine.seed000_eq26`). ``signal`` says how the values are meant:
``position`` (joint positions [rad], as the guard robot's setpoints) or ``input`` (an input
signal such as seed 000's flexible-link torque u [N m]; positions() then returns u(t) and
velocities()/accelerations() its time derivatives). Neither kind starts at rest: the
capture that plays one should ramp in.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from guardid.excitation.trajectory import Fields, Trajectory, floats, time_array

SIGNALS = ("position", "input")


class SumOfSines(Trajectory):
    """Per joint amplitudes [rad], frequencies [Hz], phases [rad] (lists), offsets c [rad]."""

    kind = "sines"

    def __init__(self, amplitudes, frequencies, phases, offsets, periods=1, joint_names=None):
        self.amplitudes = [np.array(r, dtype=float).reshape(-1) for r in amplitudes]
        self.frequencies = [np.array(r, dtype=float).reshape(-1) for r in frequencies]
        self.phases = [np.array(r, dtype=float).reshape(-1) for r in phases]
        self.offsets = np.array(offsets, dtype=float).reshape(-1)
        n = self.offsets.size
        if not len(self.amplitudes) == len(self.frequencies) == len(self.phases) == n:
            raise ValueError("amplitudes, frequencies, phases and offsets need one row per joint")
        for amp, freq, ph in zip(self.amplitudes, self.frequencies, self.phases, strict=True):
            if not amp.size == freq.size == ph.size:
                raise ValueError("amplitudes, frequencies and phases rows differ in length")
        self.periods = int(periods)
        self.joint_names = list(joint_names) if joint_names is not None else None
        self._period = common_period(np.concatenate(self.frequencies))

    @property
    def n_joints(self) -> int:
        return self.offsets.size

    @property
    def period(self) -> float:
        return self._period

    def _eval(self, t, order: int) -> np.ndarray:
        t = time_array(t)
        out = np.zeros((t.size, self.n_joints))
        for j in range(self.n_joints):
            w = 2 * np.pi * self.frequencies[j]
            phase = np.outer(t, w) + self.phases[j]
            amp = self.amplitudes[j] * w**order
            # d^k/dt^k sin(x) = sin(x + k pi/2)
            out[:, j] = np.sin(phase + order * np.pi / 2) @ amp
        return out

    def positions(self, t) -> np.ndarray:
        return self.offsets + self._eval(t, 0)

    def velocities(self, t) -> np.ndarray:
        return self._eval(t, 1)

    def accelerations(self, t) -> np.ndarray:
        return self._eval(t, 2)

    @property
    def centre(self) -> np.ndarray:
        """Offsets c (n,) [rad] that :meth:`scaled` scales the motion about."""
        return self.offsets.copy()

    def scaled(self, factors) -> SumOfSines:
        """Copy with each joint's amplitudes scaled by factors (n,)."""
        s = np.broadcast_to(np.asarray(factors, dtype=float), self.offsets.shape)
        amps = [a * k for a, k in zip(self.amplitudes, s, strict=True)]
        return SumOfSines(
            amps, self.frequencies, self.phases, self.offsets, self.periods, self.joint_names
        )

    def to_dict(self) -> dict:
        data = {"kind": self.kind}
        if self.joint_names is not None:
            data["joints"] = list(self.joint_names)
        data.update(
            periods=self.periods,
            offsets=floats(self.offsets),
            amplitudes=[floats(r) for r in self.amplitudes],
            frequencies=[floats(r) for r in self.frequencies],
            phases=[floats(r) for r in self.phases],
        )
        return data

    @classmethod
    def from_dict(cls, data: dict, source: str = "<trajectory>") -> SumOfSines:
        keys = ("joints", "periods", "offsets", "amplitudes", "frequencies", "phases")
        f = Fields(data, source, keys)
        offsets = f.vector("offsets")
        n = offsets.size
        amps = f.rows("amplitudes", n)
        lengths = [r.size for r in amps]
        freqs = _positive_rows(f, "frequencies", n, lengths)
        phases = f.rows("phases", n, lengths)
        names = f.names(n)
        return cls(amps, freqs, phases, offsets, f.integer("periods", default=1), names)


class SchroederMultisine(SumOfSines):
    """Equal-amplitude sines with Schroeder phases; amplitude (n,) per component per joint."""

    kind = "schroeder"

    def __init__(
        self, amplitude, frequencies, offsets, signal="position", periods=1, joint_names=None
    ):
        if signal not in SIGNALS:
            raise ValueError(f"signal must be one of {SIGNALS}, got {signal!r}")
        self.amplitude = np.array(amplitude, dtype=float).reshape(-1)
        self.signal = signal
        freqs = [np.array(r, dtype=float).reshape(-1) for r in frequencies]
        amps = [np.full(r.size, a) for a, r in zip(self.amplitude, freqs, strict=True)]
        phases = [schroeder_phases(r.size) for r in freqs]
        super().__init__(amps, freqs, phases, offsets, periods, joint_names)

    @classmethod
    def seed000_eq26(cls) -> SchroederMultisine:
        """Seed 000 eq. 26 as printed: u = 0.5 [sin 2t + sin(2t - 2pi/3) + sin(5t - 2pi)]."""
        w = np.array([2.0, 2.0, 5.0])  # rad/s, as printed in the paper
        return cls([0.5], [w / (2 * np.pi)], [0.0], signal="input")

    def scaled(self, factors) -> SchroederMultisine:
        """Copy with each joint's amplitude scaled by factors (n,)."""
        s = np.broadcast_to(np.asarray(factors, dtype=float), self.amplitude.shape)
        return SchroederMultisine(
            self.amplitude * s,
            self.frequencies,
            self.offsets,
            self.signal,
            self.periods,
            self.joint_names,
        )

    def to_dict(self) -> dict:
        data = {"kind": self.kind}
        if self.joint_names is not None:
            data["joints"] = list(self.joint_names)
        data.update(
            signal=self.signal,
            periods=self.periods,
            offsets=floats(self.offsets),
            amplitude=floats(self.amplitude),
            frequencies=[floats(r) for r in self.frequencies],
        )
        return data

    @classmethod
    def from_dict(cls, data: dict, source: str = "<trajectory>") -> SchroederMultisine:
        keys = ("joints", "signal", "periods", "offsets", "amplitude", "frequencies")
        f = Fields(data, source, keys)
        offsets = f.vector("offsets")
        n = offsets.size
        amplitude = f.vector("amplitude", n)
        freqs = _positive_rows(f, "frequencies", n)
        signal = f.raw("signal", "position")
        if signal not in SIGNALS:
            f.fail("signal", f"expected one of {', '.join(SIGNALS)}, got {signal!r}")
        periods = f.integer("periods", default=1)
        return cls(amplitude, freqs, offsets, signal, periods, f.names(n))


def schroeder_phases(k: int) -> np.ndarray:
    """Schroeder phases phi_k = -pi k (k - 1) / K [rad] for k = 1..K."""
    idx = np.arange(1, k + 1)
    return -np.pi * idx * (idx - 1) / k


def common_period(freqs, max_ratio_denominator: int = 1000) -> float:
    """Smallest common period [s] of frequencies [Hz] with rational ratios, else math.inf."""
    freqs = np.abs(np.asarray(freqs, dtype=float))
    freqs = freqs[freqs > 0]
    if freqs.size == 0:
        return math.inf
    f_min = freqs.min()
    denominators = []
    for f in freqs:
        ratio = Fraction(float(f / f_min)).limit_denominator(max_ratio_denominator)
        if abs(float(ratio) - f / f_min) > 1e-9 * f / f_min:
            return math.inf
        denominators.append(ratio.denominator)
    # all f = f_min * p_i / q_i; the fundamental is f_min / lcm(q_i) (times a gcd, ignored)
    fundamental = f_min / math.lcm(*denominators)
    nums = [round(f / fundamental) for f in freqs]
    return float(1.0 / (fundamental * math.gcd(*nums)))  # a Python float: YAML writes it


def _positive_rows(f: Fields, key: str, n: int, lengths=None) -> list[np.ndarray]:
    rows = f.rows(key, n, lengths)
    for i, row in enumerate(rows):
        if np.any(row <= 0):
            f.fail(f"{key}[{i}]", "frequencies [Hz] must be > 0")
    return rows
