"""The AVR port's ELF in simavr, on the simulated plant, as a fake-port device (``firmware=avr``).

Per tick (``advance``) the Python side reads the PWM duty (OCR0A/OCR0B) and DIR pins the MCU
holds, steps the plant one period with that motor voltage, and hands the shim the plant's
motion (position and speed at both ends, in encoder counts) and period-mean current and
voltage. The shim (``firmware_proto/simavr/avr_sim.c``) puts the quadrature edges on the
encoder pins at the cycles the shaft crosses each count, feeds every ADC conversion through
the board's analog front end (``board.h``: mid-scale 512 codes = 0, +-512 codes = the YAML
sensor range) with noise, clocks host bytes into the UART at its baud rate, and runs the MCU
for one period: the only Python/C crossing is once per tick.

Timing model: the plant's period k starts ``output_latency_s`` after the MCU's Timer1 tick
interrupt k (the tick's work must have set the PWM by then; a late tick is counted) and
holds that period's outputs; Timer1 latches the encoder counts and ADC sums at its own
instants, inside the plant's periods. Noise: the YAML's sigma is the noise of the period
mean (as the plant and the emulators report it); each of the ~36 conversions per channel and
tick gets sigma * sqrt(36), so the firmware's mean carries the YAML's sigma.
"""

from __future__ import annotations

import ctypes
import math

from guardid.errors import GuardidError
from guardid.firmware.avr_sim.build import (
    F_CPU,
    bootloader_hex,
    build_elf,
    build_shim,
    ram_symbols,
    read_ihex,
)
from guardid.firmware.avr_sim.robot_header import ADC_CHANNELS, ADC_CONVERSION_CYCLES
from guardid.firmware.emulator import bind_robot

AVCC_MV = 5000
BAUD = F_CPU / (8 * 17)  #: 115200 requested, U2X with UBRR 16: 117647 bit/s (board_init)
OUTPUT_LATENCY_S = 0.003  #: plant period starts this long after the tick interrupt
BOOT_LIMIT_S = 1.0
BOOT_ANSWER_S = 0.002  #: [s] a booting MCU runs this long after a host's bytes are in
STAT_NAMES = (
    "cycle", "ticks", "work_n", "work_max", "work_sum", "late_outputs", "tx_hwm",
    "edges0", "edges1", "count_err_max", "count_err_ticks", "tx_bytes", "rx_bytes",
    "tx_overflow", "edge_overflow", "pwm_rise0", "pwm_rise1", "pwm_last_high0",
    "pwm_last_high1", "estop_cycle", "work_max_tick", "late_ticks", "late_first", "resets",
)  # fmt: skip
VECTORS = {  #: interrupt vector numbers of the port's ISRs per MCU
    "atmega328p": {"PCINT0 (e-stop)": 3, "PCINT2 (encoders)": 5, "TIMER1_COMPA (tick)": 11,
                   "USART_RX": 18, "USART_UDRE": 19, "ADC": 21},
    "atmega2560": {"PCINT0 (e-stop)": 9, "PCINT2 (encoders)": 11, "TIMER1_COMPA (tick)": 17,
                   "USART0_RX": 25, "USART0_UDRE": 26, "ADC": 29},
}  # fmt: skip
MCU_INDEX = {"atmega328p": 0, "atmega2560": 1}
_INIT_ERRORS = {-1: "bad shim configuration", -2: "unknown MCU",
                -3: "ELF or boot loader unreadable", -7: "too many simulated MCUs"}  # fmt: skip
RESET = -6  #: as_run_tick: the MCU was reset (boot loader, firmware set-up follow)

_lib = None


class AvrSimError(GuardidError):
    """The simulated MCU stopped (crash, no tick interrupt, too many encoder edges)."""


def load_shim():
    """The ctypes handle of the simavr shim (built on first use)."""
    global _lib
    if _lib is not None:
        return _lib
    lib = ctypes.CDLL(str(build_shim()))
    vp, sz, dp = ctypes.c_void_p, ctypes.c_size_t, ctypes.POINTER(ctypes.c_double)
    i64p, i32p = ctypes.POINTER(ctypes.c_int64), ctypes.POINTER(ctypes.c_int32)
    sigs = {
        "as_size": (sz, []),
        "as_init": (
            ctypes.c_int,
            [vp, ctypes.c_char_p, ctypes.c_char_p, sz, ctypes.c_double, ctypes.c_int, dp, sz],
        ),  # fmt: skip
        "as_close": (None, [vp]),
        "as_boot": (ctypes.c_int, [vp, ctypes.c_double]),
        "as_boot_step": (ctypes.c_int, [vp, ctypes.c_double]),
        "as_reset": (None, [vp, ctypes.c_int]),
        "as_read_flash": (ctypes.c_int, [vp, ctypes.c_uint, ctypes.c_char_p, sz]),
        "as_run_tick": (ctypes.c_int, [vp, dp]),
        "as_outputs": (None, [vp, i32p]),
        "as_rx_push": (sz, [vp, ctypes.c_char_p, sz]),
        "as_rx_pending": (sz, [vp]),
        "as_tx_take": (sz, [vp, ctypes.c_char_p, sz]),
        "as_estop": (None, [vp, ctypes.c_int]),
        "as_stats": (None, [vp, i64p, i64p]),
        "as_stat_count": (ctypes.c_int, []),
        "as_read_ram": (None, [vp, ctypes.c_uint, ctypes.c_char_p, sz]),
        "as_pin_counts": (None, [vp, i32p]),
    }
    for name, (restype, argtypes) in sigs.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    if lib.as_stat_count() != len(STAT_NAMES):
        raise AvrSimError("firmware=avr: shim and wrapper disagree on the statistics")
    _lib = lib
    return lib


class AvrFirmware:
    """The AVR port's binary on a plant with ``step(voltages_V) -> sample``.

    Same :class:`guardid.fakeport.device.Device` interface as the other firmwares.
    ``mcu``: ``atmega328p`` or ``atmega2560``; ``seed``/``noise``: the ADC noise;
    ``extra_cflags``: appended to the firmware build (tests build broken ports with it).
    ``bootloader``: ``optiboot`` (ATmega328P) or ``stk500v2`` (ATmega2560), the Arduino
    boot loader image run from every reset before the firmware (:meth:`reset` is the host's
    DTR pulse; the plant holds still while the MCU boots); None: the firmware alone.
    ``plant_factory``: makes the plant as at the start, for :meth:`reset`'s power cycle.
    """

    def __init__(self, description, plant, *, mcu: str = "atmega328p", seed: int = 0,
                 noise: bool = True, extra_cflags: str = "",
                 output_latency_s: float = OUTPUT_LATENCY_S,
                 bootloader: str | None = None, plant_factory=None) -> None:  # fmt: skip
        bind_robot(self, description, plant)
        self.plant_factory = plant_factory
        self.mcu = mcu
        self.bootloader = bootloader
        boot_base, boot = 0, b""
        if bootloader is not None:
            boot_base, boot = read_ihex(bootloader_hex(bootloader, mcu))
        self.elf = build_elf(mcu, extra_cflags)
        self.lib = load_shim()
        syms = ram_symbols(self.elf, ("enc_count", "tx_head", "tx_tail"))
        self.period_cycles = round(self.tick_period_s * F_CPU)
        self.latency_cycles = round(output_latency_s * F_CPU)
        self.counts_per_rad = [jc.counts_per_rad for jc in plant.joints]
        q0, qd0 = plant.state.q, plant.state.qd
        per_channel = self.period_cycles / (ADC_CONVERSION_CYCLES * ADC_CHANNELS)
        cfg = [F_CPU, self.period_cycles, self.latency_cycles, AVCC_MV, BAUD, seed, int(noise)]
        cfg += [syms.get(k, 0) for k in ("enc_count", "tx_head", "tx_tail")]
        self.supply_mv = []
        for joint, cpr, q in zip(description.joints, self.counts_per_rad, q0, strict=True):
            ims, vms = joint.current_sensor, joint.voltage_sensor
            self.supply_mv.append(joint.drive.supply_voltage * 1e3)
            cfg += [joint.drive.supply_voltage * 1e3, ims.range * 1e3, vms.range * 1e3]
            cfg += [
                ims.noise * 1e3 * math.sqrt(per_channel),
                vms.noise * 1e3 * math.sqrt(per_channel),
            ]
            cfg += [math.floor(q * cpr)]
        words = self.lib.as_size() // 8 + 1
        self._mem = (ctypes.c_int64 * words)()
        self._h = ctypes.cast(self._mem, ctypes.c_void_p)
        arr = (ctypes.c_double * len(cfg))(*cfg)
        elf = str(self.elf).encode()
        rc = self.lib.as_init(
            self._h, elf, boot, len(boot), boot_base, MCU_INDEX[mcu], arr, len(cfg)
        )
        if rc != 0:
            raise AvrSimError(f"firmware=avr: {_INIT_ERRORS.get(rc, rc)} ({self.elf})")
        self._open = True
        self._buf = ctypes.create_string_buffer(16384)
        self.booting = bootloader is not None  # the boot loader runs first, tick by tick
        if not self.booting:
            self._check(self.lib.as_boot(self._h, BOOT_LIMIT_S * F_CPU), "booting")
        self._out = bytearray(self._take())  # INFO at reset: the host's first bytes
        self._x = [q * c for q, c in zip(q0, self.counts_per_rad, strict=True)]
        self._v = [v * c for v, c in zip(qd0, self.counts_per_rad, strict=True)]
        self._plant_in = (ctypes.c_double * 12)()
        self._outs = (ctypes.c_int32 * 4)()

    # ------------------------------------------------------------------ Device
    def receive(self, data: bytes) -> None:
        """Bytes from the host: queued on the MCU's RX line at the UART's baud rate. While
        the MCU boots (no plant yet) it runs on until they are in and answered
        (:data:`BOOT_ANSWER_S` more), as a boot loader answers a programmer at once."""
        data = bytes(data)
        if self.booting:
            self.lib.as_rx_push(self._h, data, len(data))
            cycles = (len(data) + 1) * F_CPU * 10 / BAUD + BOOT_ANSWER_S * F_CPU
            rc = self.lib.as_boot_step(self._h, cycles)
            self._check(min(rc, 0), "booting")
            self.booting = rc == 0
            return
        while data:
            used = self.lib.as_rx_push(self._h, data, len(data))
            data = data[used:]
            if data:  # the line is busy for longer than the queue: let the MCU take some
                self.advance()

    def advance(self) -> None:
        """One plant period under the MCU's outputs, the MCU running alongside; while it
        boots (boot loader, firmware set-up) one period of the MCU alone."""
        if self.booting:
            rc = self.lib.as_boot_step(self._h, self.period_cycles)
            self._check(min(rc, 0), "booting")
            self.booting = rc == 0
            return
        volts = self.applied_volts()
        sample = self.plant.step(volts)
        p = self._plant_in
        for j, cpr in enumerate(self.counts_per_rad):
            x1, v1 = sample.q[j] * cpr, sample.qd[j] * cpr
            ma, mv = sample.current_true[j] * 1e3, sample.voltage_true[j] * 1e3
            p[6 * j : 6 * j + 6] = [self._x[j], self._v[j], x1, v1, ma, mv]
            self._x[j], self._v[j] = x1, v1
        rc = self.lib.as_run_tick(self._h, p)
        if rc == RESET:  # the firmware's watchdog or a boot loader restarted the MCU
            self.booting = True
            return
        self._check(rc, f"tick {self.plant.tick}")

    def take_output(self) -> bytes:
        """Bytes the MCU transmitted since the previous call (first: its INFO at reset)."""
        out = bytes(self._out) + self._take()
        self._out.clear()
        return out

    def wants_time(self) -> bool:
        """A microcontroller's time always runs (watchdog, ADC, timers)."""
        return True

    def close(self) -> None:
        """Release the simulated MCU."""
        if getattr(self, "_open", False):
            self.lib.as_close(self._h)
            self._open = False

    def __del__(self) -> None:
        self.close()

    # ------------------------------------------------------------------ extras
    def reset(self, power_cycle: bool = False) -> None:
        """The host's DTR pulse: an external reset (the boot loader runs first if there is
        one; the flash keeps what was written); bytes on their way to the MCU are lost.
        ``power_cycle``: the robot is put back at its start too (plant, encoder pins,
        sensor noise stream as built), as for a fresh bench session."""
        if power_cycle:
            if self.plant_factory is None:
                raise AvrSimError("firmware=avr: a power cycle needs the plant's factory")
            self.plant = self.plant_factory()
            q0, qd0 = self.plant.state.q, self.plant.state.qd
            self._x = [q * c for q, c in zip(q0, self.counts_per_rad, strict=True)]
            self._v = [v * c for v, c in zip(qd0, self.counts_per_rad, strict=True)]
        self.lib.as_reset(self._h, int(power_cycle))
        self._out.clear()
        self._take()
        self.booting = True

    def read_flash(self, address: int, size: int) -> bytes:
        """``size`` bytes of the MCU's flash from byte ``address`` (what a boot loader wrote)."""
        buf = ctypes.create_string_buffer(size)
        if self.lib.as_read_flash(self._h, address, buf, size) != 0:
            raise AvrSimError(f"flash {address:#x}+{size}: outside the {self.mcu}'s flash")
        return buf.raw

    def applied_volts(self) -> list[float]:
        """Motor voltages [V] the pins command: DIR sign times duty/255 of the supply."""
        self.lib.as_outputs(self._h, self._outs)
        o = self._outs
        return [(-1.0 if o[2 * j + 1] else 1.0) * o[2 * j] / 255.0 * s * 1e-3
                for j, s in enumerate(self.supply_mv)]  # fmt: skip

    def estop_input(self, pressed: bool = True) -> None:
        """Pull the e-stop pin low (pressed) or release it."""
        self.lib.as_estop(self._h, int(bool(pressed)))

    def stats(self) -> dict:
        """What the shim observed: cycles, tick work, edges, UART, pins, per-vector ISR use."""
        st = (ctypes.c_int64 * len(STAT_NAMES))()
        vs = (ctypes.c_int64 * 256)()
        self.lib.as_stats(self._h, st, vs)
        out = dict(zip(STAT_NAMES, st, strict=True))
        keys = ("count", "cycles", "max_cycles", "max_latency")
        out["vectors"] = {
            name: dict(zip(keys, vs[4 * v : 4 * v + 4], strict=True))
            for name, v in VECTORS[self.mcu].items()
        }
        return out

    def read_ram(self, name: str, size: int) -> bytes:
        """``size`` bytes of the firmware's static variable ``name`` (from the ELF's symbols)."""
        addr = ram_symbols(self.elf, (name,))[name]
        buf = ctypes.create_string_buffer(size)
        self.lib.as_read_ram(self._h, addr, buf, size)
        return buf.raw

    def pin_counts(self) -> list[int]:
        """The encoder counts now on the A/B pins (relative to the start), per joint."""
        out = (ctypes.c_int32 * 2)()
        self.lib.as_pin_counts(self._h, out)
        return list(out)

    def _take(self) -> bytes:
        out = bytearray()
        while n := self.lib.as_tx_take(self._h, self._buf, len(self._buf)):
            out += self._buf.raw[:n]
        return bytes(out)

    def _check(self, rc: int, what: str) -> None:
        if rc != 0:
            why = {-1: "the MCU crashed", -4: "the tick interrupt stopped",
                   -5: "too many encoder edges in one period"}.get(rc, f"error {rc}")  # fmt: skip
            raise AvrSimError(f"firmware=avr ({self.mcu}): {why} while {what}")


def make_sim_device_avr(robot: str, options) -> AvrFirmware:
    """Device factory for ``sim://...&firmware=avr[&mcu=atmega2560]``."""
    from guardid.plant import make_plant
    from guardid.robot import load_robot

    description = load_robot(robot)
    plant = make_plant(description, options)
    return AvrFirmware(description, plant, mcu=getattr(options, "mcu", "atmega328p"),
                       seed=options.seed, noise=options.noise,
                       bootloader=getattr(options, "bootloader", None),
                       plant_factory=lambda: make_plant(description, options))  # fmt: skip
