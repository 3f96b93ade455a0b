"""How a ``sim://`` port gets its device: a pluggable factory (the firmware emulator)."""

from __future__ import annotations

import os
from collections.abc import Callable

from guardid.fakeport.device import Device, EchoDevice
from guardid.fakeport.options import SimOptions, SimUrlError

DeviceFactory = Callable[[str, SimOptions], Device]

#: Environment variable selecting a built-in test device by name (e.g. ``echo``).
DEVICE_ENV = "GUARDID_FAKEPORT_DEVICE"

NAMED_DEVICES: dict[str, DeviceFactory] = {
    "echo": lambda robot, options: EchoDevice(),
}

_factory: DeviceFactory | None = None


def register_device_factory(factory: DeviceFactory | None) -> DeviceFactory | None:
    """Install ``factory(robot, options) -> Device`` (None removes it); return the old one."""
    global _factory
    old, _factory = _factory, factory
    return old


def make_device(robot: str, options: SimOptions, name: str | None = None) -> Device:
    """Build the device for ``robot``.

    Order: a built-in named device (``name`` or ``$GUARDID_FAKEPORT_DEVICE``), then the
    registered factory, else the firmware on the simulated plant: the Python emulator
    (``firmware=py``), the C core built as a shared library (``firmware=c``) or the AVR
    port's binary in simavr (``firmware=avr``, ``mcu=atmega328p|atmega2560``).
    """
    name = name or os.environ.get(DEVICE_ENV) or None
    if name is not None:
        if name not in NAMED_DEVICES:
            known = ", ".join(sorted(NAMED_DEVICES))
            raise SimUrlError(f"device {name!r}: unknown test device (known: {known})")
        return NAMED_DEVICES[name](robot, options)
    if _factory is not None:
        return _factory(robot, options)
    if options.params is not None and options.twin is None:
        options = with_twin(robot, options)
    if options.firmware == "c":
        from guardid.firmware.c_core import FirmwareBuildError, make_sim_device_c

        try:
            return make_sim_device_c(robot, options)
        except FirmwareBuildError as exc:
            raise SimUrlError(str(exc)) from None
    if options.firmware == "avr":
        from guardid.firmware.avr_sim.device import AvrSimError, make_sim_device_avr
        from guardid.firmware.c_core import FirmwareBuildError

        try:
            return make_sim_device_avr(robot, options)
        except (FirmwareBuildError, AvrSimError) as exc:
            raise SimUrlError(str(exc)) from None
    if options.firmware != "py":
        raise SimUrlError(f"firmware={options.firmware}: unknown firmware (known: py, c, avr)")
    from guardid.firmware import make_sim_device

    return make_sim_device(robot, options)


def with_twin(robot: str, options: SimOptions) -> SimOptions:
    """``options`` with the :class:`guardid.twin.Twin` of ``options.params`` loaded (its
    errors as one-line SimUrlError naming params=)."""
    from dataclasses import replace

    from guardid.errors import GuardidError
    from guardid.robot import load_robot
    from guardid.twin import load_twin

    try:
        twin = load_twin(options.params, load_robot(robot), options.method,
                         option=f"params={options.params}")  # fmt: skip
    except SimUrlError:
        raise
    except GuardidError as exc:
        message = str(exc).removeprefix(f"{options.params}: ")
        if not message.startswith("params="):
            message = f"params={options.params}: {message}"
        raise SimUrlError(message) from None
    return replace(options, twin=twin)
