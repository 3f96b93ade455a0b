"""Per-joint constants of the simulated plant, extracted once from a robot description."""

from __future__ import annotations

import math
from dataclasses import dataclass

from guardid.errors import GuardidError


class PlantError(GuardidError):
    """The robot description cannot be simulated by the plant (one-line message)."""


@dataclass(frozen=True)
class JointConst:
    """Everything the inner loop needs about one joint (SI units).

    driven: has a DC gear motor (else ideal torque input [N m]).
    kt: joint torque per amp N*eta*Kt [N m/A]; ke: back-EMF per joint speed Ke*N [V s/rad];
    r [ohm]; tau_e = L/R [s]; supply [V]; pwm_bits.
    fv [N m s/rad], fc [N m], fo [N m]: viscous, Coulomb (= static level), offset friction.
    lo, hi: position limits [rad] (+-inf if none). counts_per_rad: encoder counts per joint
    radian (0 = no encoder); quadrature: direction-sensing encoder.
    current_sensor / voltage_sensor: (range, bits, noise) or None.
    """

    name: str
    driven: bool
    kt: float
    ke: float
    r: float
    tau_e: float
    supply: float
    pwm_bits: int
    fv: float
    fc: float
    fo: float
    lo: float
    hi: float
    counts_per_rad: float
    quadrature: bool
    current_sensor: tuple | None
    voltage_sensor: tuple | None


def _sensor(s):
    return None if s is None else (float(s.range), int(s.adc_bits), float(s.noise))


def joint_constants(description, friction: bool, limits: bool) -> list[JointConst]:
    """JointConst per joint of a ChainDescription (``friction``/``limits`` False drop them)."""
    out = []
    for j in description.joints:
        if j.type != "revolute":
            raise PlantError(f"{description.name}: joint {j.name}: plant supports revolute only")
        d, f, e = j.drive, j.friction, j.encoder
        pos = j.limits.position if (limits and j.limits is not None) else None
        out.append(
            JointConst(
                name=j.name,
                driven=d is not None,
                kt=d.gear_ratio * d.efficiency * d.kt if d else 0.0,
                ke=d.ke * d.gear_ratio if d else 0.0,
                r=d.resistance if d else 1.0,
                tau_e=d.inductance / d.resistance if d else 0.0,
                supply=d.supply_voltage if d else 0.0,
                pwm_bits=d.pwm_bits if d else 0,
                fv=f.viscous if (f and friction) else 0.0,
                fc=f.coulomb if (f and friction) else 0.0,
                fo=f.offset if (f and friction) else 0.0,
                lo=pos[0] if pos else -math.inf,
                hi=pos[1] if pos else math.inf,
                counts_per_rad=j.counts_per_rad or 0.0,
                quadrature=bool(e.quadrature) if e else True,
                current_sensor=_sensor(j.current_sensor),
                voltage_sensor=_sensor(j.voltage_sensor),
            )
        )
    return out
