"""The portable C firmware core (``firmware_proto/core``) in the loop, as a fake-port device.

The core and its software-in-the-loop hardware layer (``core/gf_sil.c``) are compiled with
the host C compiler into a shared library, once per source version, in a cache directory
outside the repository (``$GUARDID_CACHE_DIR``, else ``$XDG_CACHE_HOME/guardid`` or
``~/.cache/guardid``; the file name carries a hash of the sources, flags and compiler).

Binding to the simulated plant: per tick the Python side reads the motor voltages the core
set through its HAL (``set_output``), steps the plant with them, and hands the plant's
sample (encoder counts, period-mean voltage [mV] and current [mA]) to the core's tick,
which reads it through its HAL (``read_counts``, ``read_adc``). Bytes flow through the
core's UART callbacks into a buffer this wrapper drains. The arithmetic inside is the
firmware's (integers only), so the telemetry equals the Python emulator's byte for byte.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
from pathlib import Path

from guardid import native
from guardid.firmware.emulator import FIRMWARE_ID, FirmwareEmulator, bind_robot, require_simulable
from guardid.firmware.pid import mv_from_volts
from guardid.native import NativeBuildError, cache_dir, find_compiler

FIRMWARE_DIR = Path(__file__).resolve().parents[2] / "firmware_proto"
SOURCES = ("guard_proto.c", "core/guard_fw.c", "core/gf_sil.c")
HEADERS = ("guard_proto.h", "guard_proto_msgs.h", "core/guard_fw.h")
CFLAGS = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2", "-shared", "-fPIC")
MAX_JOINTS = 4
_STATE_LEN = 11

_lib = None


class FirmwareBuildError(NativeBuildError):
    """The C firmware core cannot be built or loaded (no compiler, sources missing)."""


def library_path(cc: str) -> Path:
    """The cached library for the current sources, flags and compiler."""
    digest = hashlib.sha256()
    for name in (*SOURCES, *HEADERS):
        path = FIRMWARE_DIR / name
        if not path.is_file():
            raise FirmwareBuildError(f"firmware=c: {path} missing (is guardid installed from git?)")
        digest.update(name.encode() + b"\0" + path.read_bytes())
    digest.update(" ".join((os.path.realpath(cc), *CFLAGS)).encode())
    return cache_dir() / f"libguard_fw-{digest.hexdigest()[:16]}.so"


def build_library() -> Path:
    """Compile the core if the cache has no library for these sources; return its path."""
    cc = find_compiler()
    if cc is None:
        raise FirmwareBuildError(
            "firmware=c: no C compiler found (install gcc or set CC), or use firmware=py"
        )
    cmd = [cc, *CFLAGS, f"-I{FIRMWARE_DIR}", f"-I{FIRMWARE_DIR / 'core'}"]
    cmd += [str(FIRMWARE_DIR / s) for s in SOURCES]
    return build_cached(library_path(cc), lambda out: [*cmd, "-o", out],
                        "firmware=c: building the C core")  # fmt: skip


def build_cached(lib: Path, command, what: str) -> Path:
    """:func:`guardid.native.build_cached`, failing with a FirmwareBuildError."""
    return native.build_cached(lib, command, what, FirmwareBuildError)


def load_library():
    """The ctypes handle of the core (built on first use)."""
    global _lib
    if _lib is not None:
        return _lib
    lib = ctypes.CDLL(str(build_library()))
    vp, sz, i64p = ctypes.c_void_p, ctypes.c_size_t, ctypes.POINTER(ctypes.c_int64)
    i32p = ctypes.POINTER(ctypes.c_int32)
    sigs = {
        "gf_sil_size": (sz, []),
        "gf_sil_init": (ctypes.c_int, [vp, i64p, sz]),
        "gf_sil_receive": (sz, [vp, ctypes.c_char_p, sz]),
        "gf_sil_outputs": (None, [vp, i32p]),
        "gf_sil_tick": (None, [vp, i32p, i32p, i32p]),
        "gf_sil_estop": (None, [vp]),
        "gf_sil_take": (sz, [vp, ctypes.c_char_p, sz]),
        "gf_sil_pending": (sz, [vp]),
        "gf_sil_overflows": (ctypes.c_uint32, [vp]),
        "gf_sil_state": (None, [vp, i64p]),
        "gf_sil_set_tick": (None, [vp, ctypes.c_uint32]),
        "gf_sil_pid_step": (ctypes.c_int32, [i64p] + [ctypes.c_int32] * 3),
        "gf_sil_gains": (
            None,
            [ctypes.c_int32] * 3 + [ctypes.c_uint32, ctypes.c_uint32, i64p],
        ),
        "gf_sil_pwm": (ctypes.c_int32, [ctypes.c_int32, ctypes.c_int32, ctypes.c_uint8]),
    }
    for name, (restype, argtypes) in sigs.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    _lib = lib
    return lib


def _clamp_i32(value: int) -> int:
    return max(-(2**31), min(2**31 - 1, int(value)))


class CFirmware:
    """The C firmware core on a plant with ``step(voltages_V) -> sample``.

    Same constructor and :class:`guardid.fakeport.device.Device` interface as
    :class:`guardid.firmware.FirmwareEmulator`. ``firmware_id`` is reported in INFO (the
    emulators' id by default, so both give identical bytes).
    """

    runs_ahead = True  #: host frames handled between ticks (guardid.fakeport.device)

    def __init__(self, description, plant, firmware_id: int = FIRMWARE_ID) -> None:
        joints = description.joints
        bind_robot(self, description, plant)
        if not 1 <= len(joints) <= MAX_JOINTS:
            raise ValueError(f"{description.name}: the C core drives 1..{MAX_JOINTS} joints")
        self.lib = load_library()
        cfg = [self.n, 0, self.tick_us, firmware_id]
        for joint, cpr in zip(joints, self.cpr, strict=True):
            limits = FirmwareEmulator._count_limits(joint, cpr)
            gains = (0, 0, 0)
            if joint.pid is not None:
                gains = tuple(
                    int(round(g * 1e6)) for g in (joint.pid.kp, joint.pid.ki, joint.pid.kd)
                )
            cfg += [cpr, mv_from_volts(joint.drive.supply_voltage), joint.drive.pwm_bits]
            cfg += [0, 0, 0] if limits is None else [1, *(_clamp_i32(x) for x in limits)]
            cfg += list(gains)
        if any(abs(g) >= 2**31 for g in cfg[-3:]):
            raise ValueError(f"{description.name}: PID gains out of the protocol's int32 range")
        words = self.lib.gf_sil_size() // 8 + 1
        self._mem = (ctypes.c_int64 * words)()  # 8-byte aligned instance storage
        self._h = ctypes.cast(self._mem, ctypes.c_void_p)
        arr = (ctypes.c_int64 * len(cfg))(*cfg)
        if self.lib.gf_sil_init(self._h, arr, len(cfg)) != 0:
            raise ValueError(
                f"{description.name}: the C core rejects this robot (counts per rev >= 1, "
                "supply 0..32.767 V, pwm_bits 1..16, limits lo <= hi)"
            )
        self._i32 = ctypes.c_int32 * self.n
        self._state = (ctypes.c_int64 * _STATE_LEN)()
        self._buf = ctypes.create_string_buffer(4096)
        self._out = bytearray()

    # ------------------------------------------------------------------ Device
    def receive(self, data: bytes) -> None:
        """Bytes from the host, handled as the MCU's UART receive loop would."""
        data = bytes(data)
        while data:
            used = self.lib.gf_sil_receive(self._h, data, len(data))
            self._drain()
            data = data[used:]

    def advance(self) -> None:
        """One sample period: the plant under the core's outputs, then the core's tick."""
        applied = self._i32()
        self.lib.gf_sil_outputs(self._h, applied)
        sample = self.plant.step([mv * 1e-3 for mv in applied])
        counts = self._i32(*(_clamp_i32(c) for c in sample.counts))
        mv = self._i32(*(_clamp_i32(mv_from_volts(v)) for v in sample.voltage))
        ma = self._i32(*(_clamp_i32(mv_from_volts(i)) for i in sample.current))
        self.lib.gf_sil_tick(self._h, counts, mv, ma)
        self._drain()

    def take_output(self) -> bytes:
        """Bytes the core transmitted since the previous call."""
        self._drain()
        out = bytes(self._out)
        self._out.clear()
        return out

    def wants_time(self) -> bool:
        """Time matters while streaming or moving (the watchdog runs)."""
        return bool(self.state()["wants_time"])

    def close(self) -> None:
        """Nothing to release (the instance memory goes with this object)."""

    # ------------------------------------------------------------------ extras
    def estop_input(self) -> None:
        """The hardware e-stop input fires."""
        self.lib.gf_sil_estop(self._h)
        self._drain()

    @property
    def applied_mv(self) -> list[int]:
        """Motor voltages [mV] in force over the next period."""
        applied = self._i32()
        self.lib.gf_sil_outputs(self._h, applied)
        return list(applied)

    def state(self) -> dict:
        """The core's state (tick, mode, status, flags, queue length, receiver counters)."""
        self.lib.gf_sil_state(self._h, self._state)
        names = ("tick", "mode", "status", "streaming", "estop", "watchdog_tripped")
        names += ("wants_time", "watchdog_ms", "queued", "rx_frames", "rx_errors")
        return dict(zip(names, self._state, strict=True))

    @property
    def tick(self) -> int:
        """The core's u32 tick counter."""
        return int(self.state()["tick"])

    def set_tick(self, tick: int) -> None:
        """Tests: continue counting from ``tick`` (e.g. just before the u32 wrap)."""
        self.lib.gf_sil_set_tick(self._h, tick & 0xFFFFFFFF)

    def _drain(self) -> None:
        while self.lib.gf_sil_pending(self._h):
            n = self.lib.gf_sil_take(self._h, self._buf, len(self._buf))
            self._out += self._buf.raw[:n]
        if self.lib.gf_sil_overflows(self._h):
            raise RuntimeError("C core: transmit buffer overflow (wrapper bug)")


def c_pid_gains_q16(kp_uv, ki_uv, kd_uv, counts_per_rev, tick_us) -> tuple[int, int, int]:
    """The C core's :func:`guardid.firmware.pid.pid_gains_q16`."""
    lib = load_library()
    out = (ctypes.c_int64 * 3)()
    lib.gf_sil_gains(kp_uv, ki_uv, kd_uv, counts_per_rev, tick_us, out)
    return tuple(out)


class CPid:
    """The C core's PID step on raw state (for comparing with :class:`FixedPid`)."""

    def __init__(self, limit_mv: int) -> None:
        self.lib = load_library()
        self._s = (ctypes.c_int64 * 7)(0, 0, 0, 0, 0, limit_mv, 0)

    def set_gains(self, gains_q16) -> None:
        self._s[0], self._s[1], self._s[2] = gains_q16

    def step(self, setpoint: int, position: int, feedforward_mv: int = 0) -> int:
        return self.lib.gf_sil_pid_step(self._s, setpoint, position, feedforward_mv)

    @property
    def integral(self) -> int:
        return self._s[3]

    @property
    def saturated(self) -> bool:
        return bool(self._s[6])


def c_pwm(mv: int, supply_mv: int, pwm_bits: int) -> int:
    """The C core's PWM quantisation [mV]."""
    return load_library().gf_sil_pwm(mv, supply_mv, pwm_bits)


def make_sim_device_c(robot: str, options) -> CFirmware:
    """Device factory for ``sim://...&firmware=c``: the robot's YAML, a seeded plant, the C core."""
    from guardid.plant import make_plant
    from guardid.robot import load_robot

    description = load_robot(robot)
    require_simulable(description)
    plant = make_plant(description, options)
    return CFirmware(description, plant)


__all__ = [
    "CFirmware",
    "CPid",
    "FirmwareBuildError",
    "build_library",
    "c_pid_gains_q16",
    "c_pwm",
    "make_sim_device_c",
]
