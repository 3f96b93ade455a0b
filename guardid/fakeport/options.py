"""The ``sim://`` URL grammar and its validation.

``sim://<robot name or YAML path>?seed=1&pacing=lockstep|realtime|<factor>&noise=1|0
&payload_time=30&payload_mass=1.0&payload_com=0.12,0.02,0&drop=1e-4&flip=1e-5
&latency_ms=16&disconnect_s=40&reconnect_s=3&firmware=py|c|avr&mcu=atmega328p|atmega2560
&upstream=0|1&phase=0|1&start=COUNTS&supply=FRACTION&ripple=FRACTION&params=PARAMS.yaml
&method=NAME&bootloader=optiboot|stk500v2&wiring=encoder_reversed:tilt,cpr:pan=96,...``

``bootloader`` (with ``firmware=avr``): the Arduino boot loader image runs from every reset
before the firmware (optiboot on the ATmega328P, stk500v2 on the ATmega2560, the default
``mcu`` for it); the host's DTR pulse resets the MCU, as on a board's USB port.

``wiring``: the robot's wiring faults (:mod:`guardid.plant.wiring`), for ``guardid doctor``.

What a real robot's repeated runs vary, drawn from ``seed`` (each from its own stream, so the
sensor noise draws stay those of the same seed without them):

* ``phase=1``: each joint starts at a random point within its first encoder count;
* ``start=C``: each joint starts at a random point within +-C encoder counts of zero
  (real-valued, so the encoder phase too; clipped into the joint's limits; not with phase=1;
  C at most :data:`START_MAX_COUNTS`);
* ``supply=F``: the supply voltage of this run is the robot's nominal one times (1 + u), u
  uniform in [-F, F] (a bench supply's setting, a battery's charge);
* ``ripple=F``: and varies from tick to tick by a factor (1 + F z), z standard normal, the
  same for every motor (other loads on the supply).

``params=PARAMS.yaml`` runs a twin instead of the robot YAML's rigid body: the base
parameters of one set of a params file (``method=``, default its first) or of a reference
values file, with their friction (:mod:`guardid.twin`); not with a payload.

The PID closes on counts and the sensors' noise does not enter the loop, so without
``supply`` or ``ripple`` the simulated robot is deterministic apart from its start, which
the loop forgets: seeds then share most of their motion and quantisation error. The motor
voltage that ``supply``/``ripple`` change is what the voltage sensor measures, and the
current follows it: the identification's equation holds exactly as without them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from urllib.parse import parse_qsl

from guardid.errors import LinkError
from guardid.fakeport.faults import FaultConfig
from guardid.plant.wiring import WiringFault, parse_wiring


class SimUrlError(LinkError, ValueError):
    """A ``sim://`` URL or fake-port option is invalid (names the option): bad input, exit 2."""

    exit_code = 2


@dataclass(frozen=True)
class SimOptions:
    """Parsed options; times in s, mass in kg, lengths in m, rates are probabilities."""

    robot: str = "guard"
    seed: int = 0
    pacing: float | None = None  # None = lock-step; otherwise real-time speed factor
    noise: bool = True
    payload_time: float | None = None  # [s] simulated time the payload is attached
    payload_mass: float = 0.0  # [kg]
    payload_com: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [m]
    firmware: str = "py"
    mcu: str = "atmega328p"  # firmware=avr: the simulated microcontroller
    bootloader: str | None = None  # firmware=avr: optiboot | stk500v2 runs from each reset
    phase: bool = False  # start each joint at a seeded random point within one encoder count
    start: float = 0.0  # [counts] start each joint at a seeded point within +-start counts
    supply: float = 0.0  # per-run supply voltage within +-supply of nominal (fraction)
    ripple: float = 0.0  # per-tick supply ripple, std as a fraction of the supply
    faults: FaultConfig = field(default_factory=FaultConfig)
    params: str | None = None  # params.yaml / reference values file: run the twin
    method: str | None = None  # the params file's method (default: its first)
    twin: object = None  # the loaded guardid.twin.Twin (set when the device is made)
    wiring: tuple[WiringFault, ...] = ()  # guardid.plant.wiring faults

    @property
    def lockstep(self) -> bool:
        """True for lock-step pacing."""
        return self.pacing is None


def _float(lo: float | None = None, lo_open: bool = False, hi: float | None = None):
    def conv(text: str) -> float:
        value = float(text)
        if not math.isfinite(value):
            raise ValueError("must be finite")
        if lo is not None and (value < lo or (lo_open and value == lo)):
            raise ValueError(f"must be {'>' if lo_open else '>='} {lo:g}")
        if hi is not None and value > hi:
            raise ValueError(f"must be <= {hi:g}")
        return value

    return conv


def _bool(text: str) -> bool:
    if text not in ("0", "1"):
        raise ValueError("must be 0 or 1")
    return text == "1"


def _pacing(text: str) -> float | None:
    if text == "lockstep":
        return None
    if text == "realtime":
        return 1.0
    try:
        return _float(0.0, lo_open=True)(text)
    except ValueError:
        raise ValueError("must be lockstep, realtime or a speed factor > 0") from None


def _text(text: str) -> str:
    if not text:
        raise ValueError("must not be empty")
    return text


def _seed(text: str) -> int:
    value = int(text)
    if value < 0:
        raise ValueError("must be >= 0")
    return value


def _com(text: str) -> tuple[float, float, float]:
    parts = [_float()(p) for p in text.split(",")]
    if len(parts) != 3:
        raise ValueError("must be three comma-separated numbers x,y,z [m]")
    return (parts[0], parts[1], parts[2])


def _firmware(text: str) -> str:
    if text not in ("py", "c", "avr"):
        raise ValueError("must be py, c or avr")
    return text


def _mcu(text: str) -> str:
    if text not in ("atmega328p", "atmega2560"):
        raise ValueError("must be atmega328p or atmega2560")
    return text


BOOTLOADER_MCU = {"optiboot": "atmega328p", "stk500v2": "atmega2560"}


def _bootloader(text: str) -> str:
    if text not in BOOTLOADER_MCU:
        raise ValueError("must be optiboot (atmega328p) or stk500v2 (atmega2560)")
    return text


START_MAX_COUNTS = 2.0**30
"""Largest ``start`` [counts]: the telemetry carries positions as 32-bit signed counts, and
an unlimited joint started beyond that range could not be reported (half the range, so the
motion has room)."""

_PARSERS: dict[str, Callable[[str], object]] = {
    "seed": _seed,
    "pacing": _pacing,
    "noise": _bool,
    "payload_time": _float(0.0),
    "payload_mass": _float(0.0),
    "payload_com": _com,
    "drop": _float(0.0, hi=1.0),
    "flip": _float(0.0, hi=1.0),
    "latency_ms": _float(0.0),
    "disconnect_s": _float(0.0, lo_open=True),
    "reconnect_s": _float(0.0, lo_open=True),
    "firmware": _firmware,
    "mcu": _mcu,
    "bootloader": _bootloader,
    "upstream": _bool,
    "phase": _bool,
    "start": _float(0.0, hi=START_MAX_COUNTS),
    "supply": _float(0.0, hi=0.5),
    "ripple": _float(0.0, hi=0.2),
    "params": _text,
    "method": _text,
    "wiring": parse_wiring,
}
OPTION_NAMES = tuple(_PARSERS)


def parse_options(
    robot: str, raw: Mapping[str, str], label: Callable[[str], str] = str
) -> SimOptions:
    """Validate raw option strings; ``label`` renders an option name in error messages."""
    values: dict[str, object] = {}
    for name, text in raw.items():
        if name not in _PARSERS:
            known = ", ".join(OPTION_NAMES)
            raise SimUrlError(f"{label(name)}: unknown option (known: {known})")
        try:
            values[name] = _PARSERS[name](text)
        except ValueError as exc:
            raise SimUrlError(f"{label(name)}={text!r}: {exc}") from None
    latency = values.pop("latency_ms", 0.0)
    faults = FaultConfig(
        drop=values.pop("drop", 0.0),
        flip=values.pop("flip", 0.0),
        latency_s=latency / 1000.0,
        disconnect_s=values.pop("disconnect_s", None),
        reconnect_s=values.pop("reconnect_s", None),
        upstream=values.pop("upstream", False),
    )
    if faults.reconnect_s is not None and faults.disconnect_s is None:
        raise SimUrlError(f"{label('reconnect_s')}: only with disconnect_s (the link's outage)")
    if "mcu" in values and values.get("firmware") != "avr":
        raise SimUrlError(f"{label('mcu')}: only with firmware=avr")
    if "method" in values and "params" not in values:
        raise SimUrlError(f"{label('method')}: only with {label('params')}")
    if "params" in values and "payload_time" in values:
        raise SimUrlError(f"{label('payload_time')}: not with {label('params')} (a twin's body is "
                          "its base parameters; a payload changes the full ones)")  # fmt: skip
    if "bootloader" in values:
        boot = values["bootloader"]
        if values.get("firmware") != "avr":
            raise SimUrlError(f"{label('bootloader')}: only with firmware=avr")
        mcu = values.setdefault("mcu", BOOTLOADER_MCU[boot])
        if mcu != BOOTLOADER_MCU[boot]:
            raise SimUrlError(
                f"{label('bootloader')}={boot}: runs on {BOOTLOADER_MCU[boot]}, not {mcu}"
            )
    if values.get("start") and values.get("phase"):
        raise SimUrlError(f"{label('start')}: not with phase=1 (start includes the encoder phase)")
    return SimOptions(robot=robot or "guard", faults=faults, **values)


def parse_sim_url(url: str) -> SimOptions:
    """Parse ``sim://robot?opt=value&...``; raise :class:`SimUrlError` naming the option."""
    scheme, sep, rest = url.partition("://")
    if not sep or scheme.lower() != "sim":
        raise SimUrlError(f"{url!r}: expected a URL of the form sim://<robot>?<options>")
    robot, _, query = rest.partition("?")
    raw: dict[str, str] = {}
    for name, text in parse_qsl(query, keep_blank_values=True, strict_parsing=False):
        if name in raw:
            raise SimUrlError(f"{name}: given twice in {url!r}")
        raw[name] = text
    return parse_options(robot, raw)
