"""Wiring faults of a real robot's first hour, for the simulator (``sim://...&wiring=...``).

One option lists them, comma-separated, each ``kind:joint`` or ``kind:joint=value``:

* ``encoder_reversed:J`` -- the encoder's A and B wires swapped: J's counts run backwards;
* ``motor_reversed:J`` -- the motor's leads swapped: the motor turns against the voltage the
  board applies; the board's voltage and current sensors sit before the leads, so they
  still read the board's sign;
* ``current_offset:J=A`` -- J's current sensor reads A amperes more than flows (a zero
  that is off: a reference voltage, an uncalibrated Hall sensor);
* ``current_drift:J=R`` -- and its zero moves by R amperes per second of the robot's time
  from power-up (a Hall sensor warming up; in the sensor, before its ADC, so the readings
  stay on the ADC's levels, unlike the offset's);
* ``current_gain:J=G`` -- and G times the current (a sensor of another sensitivity than the
  YAML's; negative: mounted the other way round);
* ``cpr:J=C`` -- J's encoder gives C counts per motor revolution where the YAML says its
  ``counts_per_rev`` (another disc, x1/x2 decoding);
* ``stuck:J`` -- J's encoder counts nothing (unplugged, no supply): the joint turns, the
  counts stay.

The faults sit between the plant and the firmware (:class:`WiredPlant`), so the Python
emulator, the C core and the AVR binary in simavr all see the same wiring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from guardid.plant.joints import PlantError

KINDS = {
    "encoder_reversed": False,
    "motor_reversed": False,
    "current_offset": True,
    "current_drift": True,
    "current_gain": True,
    "cpr": True,
    "stuck": False,
}
"""Fault kinds, and whether each takes ``=value``."""
MAX_CURRENT_OFFSET_A = 10.0  #: largest |current_offset| [A]
MAX_CURRENT_GAIN = 10.0  #: largest |current_gain| [-]
MAX_CURRENT_DRIFT_A_PER_S = 0.1  #: largest |current_drift| [A/s]


@dataclass(frozen=True)
class WiringFault:
    """One fault: ``kind`` (a key of :data:`KINDS`) on joint ``joint``, its ``value``
    (A for current_offset, A/s for current_drift, - for current_gain, counts per motor rev
    for cpr; else None)."""

    kind: str
    joint: str
    value: float | None = None

    def __str__(self) -> str:
        value = "" if self.value is None else f"={self.value:g}"
        return f"{self.kind}:{self.joint}{value}"


def _value(kind: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{kind}: value {text!r} is not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{kind}: value must be finite")
    if kind == "cpr" and (value != int(value) or value < 1):
        raise ValueError("cpr: counts per motor revolution must be a whole number >= 1")
    if kind == "current_gain" and (value == 0 or abs(value) > MAX_CURRENT_GAIN):
        raise ValueError(f"current_gain: must be nonzero, |gain| <= {MAX_CURRENT_GAIN:g}")
    if kind == "current_offset" and abs(value) > MAX_CURRENT_OFFSET_A:
        raise ValueError(f"current_offset: |offset| must be <= {MAX_CURRENT_OFFSET_A:g} A")
    if kind == "current_drift" and abs(value) > MAX_CURRENT_DRIFT_A_PER_S:
        raise ValueError(f"current_drift: |drift| must be <= {MAX_CURRENT_DRIFT_A_PER_S:g} A/s")
    return value


def parse_wiring(text: str) -> tuple[WiringFault, ...]:
    """Faults of ``kind:joint[=value],...`` (ValueError saying what is wrong); joint names
    are checked against the robot by :func:`wire`."""
    faults: list[WiringFault] = []
    for item in text.split(","):
        item = item.strip()
        kind, colon, rest = item.partition(":")
        if not colon or not rest:
            raise ValueError(
                f"{item!r}: expected kind:joint or kind:joint=value (kinds: {', '.join(KINDS)})"
            )
        if kind not in KINDS:
            raise ValueError(f"{kind!r}: unknown fault (known: {', '.join(KINDS)})")
        joint, eq, text_value = rest.partition("=")
        if KINDS[kind] and not eq:
            raise ValueError(f"{item!r}: {kind} needs a value ({kind}:joint=value)")
        if not KINDS[kind] and eq:
            raise ValueError(f"{item!r}: {kind} takes no value")
        value = _value(kind, text_value) if eq else None
        if any(f.kind == kind and f.joint == joint for f in faults):
            raise ValueError(f"{kind}:{joint}: given twice")
        faults.append(WiringFault(kind, joint, value))
    return tuple(faults)


@dataclass(frozen=True)
class JointWiring:
    """What the wiring does to one joint: encoder sign and count ratio, motor sign,
    current sensor offset [A], its drift [A/s] and gain, a stuck encoder."""

    encoder_sign: int = 1
    count_ratio: float = 1.0  # encoder counts per YAML count
    motor_sign: int = 1
    current_offset: float = 0.0  # [A]
    current_drift: float = 0.0  # [A/s] of the robot's time
    current_gain: float = 1.0
    stuck: bool = False

    @property
    def clean(self) -> bool:
        return self == JointWiring()

    @property
    def encoder_clean(self) -> bool:
        return self.encoder_sign == 1 and self.count_ratio == 1.0 and not self.stuck


def joint_wiring(description, faults) -> list[JointWiring]:
    """Per joint of ``description``, the :class:`JointWiring` of ``faults``
    (:class:`PlantError` naming the option for a joint the robot lacks)."""
    names = [j.name for j in description.joints]
    per: list[dict] = [{} for _ in names]
    for f in faults:
        if f.joint not in names:
            raise PlantError(
                f"wiring={f}: robot {description.name} has no joint {f.joint!r} "
                f"(joints: {', '.join(names)})"
            )
        k = names.index(f.joint)
        if f.kind == "encoder_reversed":
            per[k]["encoder_sign"] = -1
        elif f.kind == "motor_reversed":
            per[k]["motor_sign"] = -1
        elif f.kind == "current_offset":
            per[k]["current_offset"] = f.value
        elif f.kind == "current_drift":
            per[k]["current_drift"] = f.value
        elif f.kind == "current_gain":
            per[k]["current_gain"] = f.value
        elif f.kind == "cpr":
            per[k]["count_ratio"] = f.value / description.joints[k].encoder.counts_per_rev
        elif f.kind == "stuck":
            per[k]["stuck"] = True
    return [JointWiring(**p) for p in per]


class WiredPlant:
    """A plant seen through faulty wiring: what :meth:`step` takes is the board's motor
    voltage [V], what it returns is what the board's encoder inputs and sensors get.

    ``q``/``qd`` of the samples and :attr:`state` are the joint as the encoder sees it (the
    AVR binary in simavr drives its encoder pins from them); every other attribute is the
    plant's."""

    def __init__(self, plant, wiring: list[JointWiring]) -> None:
        self.plant = plant
        self.wiring = wiring
        self._per_rad = [jc.counts_per_rad for jc in plant.joints]
        q0 = plant.state.q
        self._stuck_q = [
            w.encoder_sign * w.count_ratio * q for w, q in zip(wiring, q0, strict=True)
        ]

    def __getattr__(self, name: str):
        return getattr(self.plant, name)

    def _encoder_q(self, q, qd) -> tuple[list[float], list[float]]:
        """Joint angle [rad] and speed [rad/s] as the encoder sees them."""
        qe, qde = [], []
        for j, (w, x, v) in enumerate(zip(self.wiring, q, qd, strict=True)):
            if w.stuck:
                qe.append(self._stuck_q[j])
                qde.append(0.0)
            else:
                qe.append(w.encoder_sign * w.count_ratio * x)
                qde.append(w.encoder_sign * w.count_ratio * v)
        return qe, qde

    @property
    def state(self):
        s = self.plant.state
        q, qd = self._encoder_q(s.q, s.qd)
        return s._replace(q=tuple(q), qd=tuple(qd))

    def step(self, u):
        """One period under the board's voltages ``u`` [V]; the sample as the board sees it."""
        wiring = self.wiring
        s = self.plant.step([w.motor_sign * x for w, x in zip(wiring, u, strict=True)])
        q, qd = self._encoder_q(s.q, s.qd)
        counts = []
        for j, w in enumerate(wiring):
            if w.encoder_clean:
                counts.append(s.counts[j])
            elif w.stuck:
                counts.append(math.floor(q[j] * self._per_rad[j]))
            elif w.count_ratio == 1.0:
                counts.append(-s.counts[j])
            else:
                counts.append(math.floor(q[j] * self._per_rad[j]))
        q_sensed = [c / p if p else x for c, p, x in zip(counts, self._per_rad, q, strict=True)]

        def volts(v):
            return tuple(w.motor_sign * x for w, x in zip(wiring, v, strict=True))

        def amps(i):
            return tuple(
                w.current_gain * w.motor_sign * x + w.current_offset
                for w, x in zip(wiring, i, strict=True)
            )

        return s._replace(
            counts=tuple(counts), q_sensed=tuple(q_sensed), voltage=volts(s.voltage),
            current=amps(s.current), voltage_true=volts(s.voltage_true),
            current_true=amps(s.current_true), q=tuple(q), qd=tuple(qd),
        )  # fmt: skip

    def step_sensors(self, u) -> tuple[list, list, list]:
        """:meth:`step`'s encoder counts, voltage [V] and current [A], as lists."""
        s = self.step(u)
        return list(s.counts), list(s.voltage), list(s.current)


def wire(plant, description, faults):
    """``plant`` behind the wiring ``faults`` (the plant itself when there are none). A
    drifting sensor zero is set in the plant's sensor (before its ADC), scaled so that the
    board reads it as given whatever the sensor's gain and the motor leads' sign."""
    if not faults:
        return plant
    wiring = joint_wiring(description, faults)
    for j, w in enumerate(wiring):
        if w.current_drift:
            plant.current_drift_a_per_s[j] = w.current_drift / (w.current_gain * w.motor_sign)
    return WiredPlant(plant, wiring)
