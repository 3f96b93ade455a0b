"""Frozen dataclasses describing a robot (all quantities SI: m, rad, kg, s, N m, V, A)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

STANDARD_NAMES = ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")
"""Per-link standard inertial parameter names (suffix = 1-based link index)."""


@dataclass(frozen=True)
class DH:
    """One standard Denavit-Hartenberg row: a [m], alpha [rad], d [m], theta [rad].

    For a revolute joint ``theta`` is the offset added to q; for a prismatic joint ``d`` is.
    """

    a: float
    alpha: float
    d: float
    theta: float


@dataclass(frozen=True)
class Limits:
    """Joint limits: position (lo, hi) [rad | m] or None (unlimited), velocity, acceleration."""

    position: tuple[float, float] | None
    velocity: float
    acceleration: float


@dataclass(frozen=True)
class Drive:
    """DC gear motor. Joint torque = N*eta*kt*i; reflected inertia = N^2*rotor_inertia."""

    gear_ratio: float
    efficiency: float
    resistance: float  # ohm
    inductance: float  # H
    kt: float  # N m / A
    ke: float  # V s / rad (motor side)
    rotor_inertia: float  # kg m^2 (motor side)
    supply_voltage: float  # V
    pwm_bits: int

    @property
    def reflected_inertia(self) -> float:
        """Rotor inertia seen at the joint, N^2 J_rotor [kg m^2]."""
        return self.gear_ratio**2 * self.rotor_inertia


@dataclass(frozen=True)
class Rotor:
    """Mechanical-only motor rotor behind a gearbox (YAML ``rotor``), for a joint whose
    effort is a joint torque (``drive: null``): no electrical model.

    gear_ratio N [-] > 0, inertia J [kg m^2] (motor side); reflected inertia N^2 J.
    ``coupling`` 0: the rotor spins at N q_j' (adds N^2 J to M[j, j] only); +1 / -1: the
    rotor sits on the previous link and spins at that link's angular velocity about the
    joint axis +- N q_j', i.e. at v . q' with v_k = +-1 for the earlier revolute joints (all
    axes parallel) and v_j = +-N: it adds J v v^T to M (the rotor-coupling terms).
    """

    gear_ratio: float
    inertia: float  # kg m^2 (motor side)
    coupling: int = 0

    @property
    def reflected_inertia(self) -> float:
        """Rotor inertia seen at the joint, N^2 J [kg m^2]."""
        return self.gear_ratio**2 * self.inertia


FRICTION_MODELS = ("sign", "tanh", "atan", "stribeck")


@dataclass(frozen=True)
class Friction:
    """Joint friction: tau_f = viscous*qd + coulomb*s(qd) + offset [N m or N]
    (+ stribeck*exp(-(qd/stribeck_velocity)^2)*s(qd) with the Stribeck model).

    ``model`` picks the Coulomb shape s: ``sign`` (sign(qd), default), ``tanh``
    (tanh(qd / velocity_scale)), ``atan`` (atan(qd / velocity_scale), saturating at
    pi/2 x coulomb, as in the DFKI lab's model), ``stribeck`` (tanh shape plus the
    Stribeck term, a static friction excess ``stribeck`` [N m or N] that fades over
    ``stribeck_velocity`` [rad/s or m/s]). ``velocity_scale`` [rad/s or m/s] is required by
    every model but ``sign``. The smooth models hold through zero velocity, so
    identification keeps those rows (the sign model drops them).
    ``offset_modelled`` False (YAML ``offset: null``) declares the offset absent: it is 0
    and identification does not estimate it (its column is dropped from the fit).
    """

    viscous: float
    coulomb: float
    offset: float = 0.0
    offset_modelled: bool = True
    model: str = "sign"
    velocity_scale: float | None = None
    stribeck: float = 0.0
    stribeck_velocity: float | None = None

    def shape(self, qd) -> np.ndarray:
        """The Coulomb term's shape s(qd) [-] (qd in rad/s or m/s)."""
        qd = np.asarray(qd, dtype=float)
        if self.model == "sign":
            return np.sign(qd)
        if self.model == "atan":
            return np.arctan(qd / self.velocity_scale)
        return np.tanh(qd / self.velocity_scale)

    def stribeck_shape(self, qd) -> np.ndarray:
        """exp(-(qd / stribeck_velocity)^2) s(qd) [-] (zero unless the Stribeck model)."""
        qd = np.asarray(qd, dtype=float)
        if self.model != "stribeck":
            return np.zeros_like(qd)
        return np.exp(-((qd / self.stribeck_velocity) ** 2)) * self.shape(qd)


@dataclass(frozen=True)
class Encoder:
    """Incremental encoder on the motor shaft: counts per motor revolution (after decoding)."""

    counts_per_rev: int
    quadrature: bool


@dataclass(frozen=True)
class Sensor:
    """ADC-sampled sensor: symmetric range +-range, adc_bits, noise (1 sigma), same unit."""

    range: float
    adc_bits: int
    noise: float


@dataclass(frozen=True)
class PID:
    """PID gains on the joint position error: kp [V/rad], ki [V/(rad s)], kd [V s/rad]."""

    kp: float
    ki: float
    kd: float


@dataclass(frozen=True)
class JointDescription:
    """One joint of a serial chain and everything attached to it (drive, sensors, gains)."""

    name: str
    type: str  # 'revolute' | 'prismatic'
    dh: DH
    limits: Limits
    drive: Drive | None = None
    friction: Friction | None = None
    encoder: Encoder | None = None
    current_sensor: Sensor | None = None
    voltage_sensor: Sensor | None = None
    pid: PID | None = None
    rotor: Rotor | None = None

    @property
    def counts_per_joint_rev(self) -> float | None:
        """Encoder counts per joint revolution [counts]: the encoder's counts per motor
        revolution x the drive's gear ratio (1 without a drive); on a prismatic joint per
        2 pi joint units (m). None without an encoder."""
        if self.encoder is None:
            return None
        ratio = self.drive.gear_ratio if self.drive is not None else 1.0
        return self.encoder.counts_per_rev * ratio

    @property
    def counts_per_rad(self) -> float | None:
        """Encoder counts per joint radian (per metre on a prismatic joint) [counts/rad]:
        :attr:`counts_per_joint_rev` / 2 pi. None without an encoder."""
        per_rev = self.counts_per_joint_rev
        return None if per_rev is None else per_rev / (2 * math.pi)

    @property
    def reflected_inertia(self) -> float | None:
        """N^2 J_rotor [kg m^2] of the drive or the mechanical-only rotor; None if neither."""
        if self.drive is not None:
            return self.drive.reflected_inertia
        return None if self.rotor is None else self.rotor.reflected_inertia


@dataclass(frozen=True)
class LinkDescription:
    """Rigid link: mass [kg], com (3,) [m] and inertia (3, 3) [kg m^2] about the COM.

    Both are expressed in the link's own standard-DH frame (frame j at the distal end of
    link j). ``known_zero`` lists standard parameter names ('XY', 'MY', ...) assumed zero.
    """

    name: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    known_zero: tuple[str, ...] = ()

    def standard_parameters(self) -> np.ndarray:
        """The 10 standard parameters XX XY XZ YY YZ ZZ MX MY MZ M about the frame origin."""
        c = self.com
        m = self.mass
        i_o = self.inertia + m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
        return np.array(
            [i_o[0, 0], i_o[0, 1], i_o[0, 2], i_o[1, 1], i_o[1, 2], i_o[2, 2], *(m * c), m]
        )


@dataclass(frozen=True)
class ChainDescription:
    """A serial chain of revolute/prismatic joints (model: serial_chain)."""

    name: str
    joints: tuple[JointDescription, ...]
    links: tuple[LinkDescription, ...]
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))
    sample_period: float = 0.015
    source: str = ""
    model: str = "serial_chain"

    @property
    def n_dof(self) -> int:
        """Number of joints."""
        return len(self.joints)


@dataclass(frozen=True)
class ParameterRange:
    """Nominal value and admissible interval [lo, hi] of one identified parameter."""

    nominal: float
    lo: float
    hi: float


@dataclass(frozen=True)
class FlexibleLinkDescription:
    """Seed 000's flexible link (DESIGN.md section 4), model: flexible_link.

    Physical values m [kg], l1, l2 [m], k [N m/rad]; identified parameters
    alpha = m l2^2, gamma = m l1 l2, k; hub_inertia J_h [kg m^2] is known and added to M11.
    """

    name: str
    mass: float
    l1: float
    l2: float
    stiffness: float
    hub_inertia: float
    parameters: dict[str, ParameterRange]
    initial_state: np.ndarray
    sample_period: float = 0.0005
    joint_names: tuple[str, str] = ("hub", "flex")
    source: str = ""
    model: str = "flexible_link"

    @property
    def n_dof(self) -> int:
        """Number of generalised coordinates (hub angle x1, flex angle x2)."""
        return 2
