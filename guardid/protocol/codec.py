"""Message classes built from ``messages.yaml`` at import time, frame encoder and decoder.

Wire frame: ``cobs(version u8 | msg_id u8 | seq u16 | payload | crc32 u32) + b"\\x00"``,
all little-endian; CRC-32 is ``zlib.crc32`` over header + payload.
Decoded values are the raw integers of the wire (see each field's ``scale``/``unit``).
"""

from __future__ import annotations

import struct
import zlib
from array import array
from collections import namedtuple
from collections.abc import Callable
from itertools import chain
from operator import itemgetter
from typing import NamedTuple

from cobs import cobs

from . import fastcodec
from .spec import CRC_LEN, HEADER_LEN, MessageSpec, load_spec

SPEC = load_spec()
PROTOCOL_VERSION = SPEC.version  #: the message set (INFO protocol_version)
MIN_PROTOCOL_VERSION = SPEC.min_version  #: oldest firmware protocol version a host talks to
FRAME_VERSION = SPEC.frame_version  #: the frame header's version byte
MAX_JOINTS = SPEC.max_joints
MIN_RAW = HEADER_LEN + CRC_LEN  #: shortest decoded frame, bytes
MAX_RAW = MIN_RAW + SPEC.max_payload  #: longest decoded frame, bytes
MAX_ENCODED = MAX_RAW + MAX_RAW // 254 + 1  #: longest COBS-encoded frame (no delimiter)
CRC_RESIDUE = 0x2144DF1C  #: zlib.crc32(raw) of any frame whose CRC is right


class Frame(NamedTuple):
    """A valid decoded frame: message id, sequence number (u16) and the message."""

    msg_id: int
    seq: int
    msg: tuple


def _class_name(name: str) -> str:
    return "".join(p.capitalize() for p in name.split("_"))


def _make_class(spec: MessageSpec) -> type:
    base = namedtuple(_class_name(spec.name), [f.name for f in spec.fields])
    doc = (
        spec.doc
        + " Fields (raw integers): "
        + ", ".join(
            f"{f.name} [{f.type}{'[n]' if f.per_joint else ''}"
            + (f" x {f.scale:g} {f.unit}" if f.unit else "")
            + "]"
            for f in spec.fields
        )
    )
    return type(
        base.__name__,
        (base,),
        {"__slots__": (), "__doc__": doc, "MSG_ID": spec.msg_id, "SPEC": spec},
    )


#: message classes by name (``MESSAGES["TELEMETRY"]``) and by id.
MESSAGES = {m.name: _make_class(m) for m in SPEC.messages}
BY_ID = {cls.MSG_ID: cls for cls in MESSAGES.values()}


def _field_getter(indexers: list) -> Callable[[tuple], tuple]:
    """``getter(unpacked) -> field values``: one C call picking the fixed fields and slicing
    the per-joint arrays out of a frame's unpacked struct tuple (no per-frame Python loop)."""
    if not indexers:
        return lambda vals: ()
    if len(indexers) == 1:
        (one,) = indexers
        return lambda vals: (vals[one],)
    return itemgetter(*indexers)


_BODY: dict[tuple[int, int], struct.Struct] = {}
#: (msg_id, raw length) -> (full struct, class, field getter): ``getter(struct.unpack(raw))``
#: is the tuple of the message's field values (per-joint arrays as tuples)
DECODERS: dict[tuple[int, int], tuple[struct.Struct, type, Callable[[tuple], tuple]]] = {}
for _m in SPEC.messages:
    for _n in range(1, MAX_JOINTS + 1) if _m.per_joint else (0,):
        _full = _m.struct_for(_n)
        _BODY[(_m.msg_id, _n)] = struct.Struct(_full.format[:-1])
        _k = len(_m.fixed)
        _ix: list = list(range(3, 3 + _k))
        _ix += [slice(3 + _k + j * _n, 3 + _k + (j + 1) * _n) for j in range(len(_m.per_joint))]
        DECODERS[(_m.msg_id, _full.size)] = (_full, MESSAGES[_m.name], _field_getter(_ix))


def n_joints_of(msg: tuple) -> int:
    """Joint count of a message (length of its per-joint arrays; 0 if it has none)."""
    spec = msg.SPEC
    if not spec.per_joint:
        return 0
    lens = {len(getattr(msg, f.name)) for f in spec.per_joint}
    if len(lens) != 1 or not 1 <= (n := lens.pop()) <= MAX_JOINTS:
        raise ValueError(f"{spec.name}: per-joint arrays must share one length in 1..{MAX_JOINTS}")
    return n


#: msg_id -> number of fixed fields; the per-joint arrays follow them (checked here, since
#: the wire layout and the hot path below rely on it)
_N_FIXED: dict[int, int] = {}
for _m in SPEC.messages:
    _flags = [f.per_joint for f in _m.fields]
    if _flags != sorted(_flags):
        raise ValueError(f"{_m.name}: per-joint fields must follow the fixed fields")
    _N_FIXED[_m.msg_id] = _flags.count(False)


def encode_raw(msg: tuple, seq: int, version: int = FRAME_VERSION) -> bytes:
    """Header + payload + CRC of ``msg`` (before COBS), ``seq`` taken modulo 2**16."""
    spec = msg.SPEC
    k = _N_FIXED[spec.msg_id]
    if k == len(msg):
        n, vals = 0, msg
    else:
        arrays = msg[k:]
        n = len(arrays[0])
        for arr in arrays:
            if len(arr) != n or not 1 <= n <= MAX_JOINTS:
                raise ValueError(
                    f"{spec.name}: per-joint arrays must share one length in 1..{MAX_JOINTS}"
                )
        vals = msg[:k] + tuple(chain.from_iterable(arrays))
    try:
        body = _BODY[(spec.msg_id, n)].pack(version, spec.msg_id, seq & 0xFFFF, *vals)
    except struct.error as exc:
        raise ValueError(f"{spec.name}: {exc}") from None
    return body + zlib.crc32(body).to_bytes(4, "little")


def encode(msg: tuple, seq: int) -> bytes:
    """Complete wire frame of ``msg``: COBS-encoded, terminated by the 0x00 delimiter."""
    return cobs.encode(encode_raw(msg, seq)) + b"\x00"


def decode_raw(raw: bytes) -> Frame | str:
    """Decode one COBS-decoded frame; returns a :class:`Frame` or the error kind
    (``"short"``, ``"crc"``, ``"version"``, ``"unknown_id"``, ``"length"``)."""
    if len(raw) < MIN_RAW:
        return "short"
    if zlib.crc32(raw) != CRC_RESIDUE:
        return "crc"
    if raw[0] != FRAME_VERSION:
        return "version"
    dec = DECODERS.get((raw[1], len(raw)))
    if dec is None:
        return "length" if raw[1] in BY_ID else "unknown_id"
    vals = dec[0].unpack(raw)
    return Frame(raw[1], vals[2], tuple.__new__(dec[1], dec[2](vals)))


def decode(frame: bytes) -> Frame | str:
    """Decode one wire frame (with or without its trailing delimiter)."""
    try:
        raw = cobs.decode(frame[:-1] if frame.endswith(b"\x00") else frame)
    except cobs.DecodeError:
        return "cobs"
    return decode_raw(raw)


class Encoder:
    """Stamps outgoing messages with this direction's sequence number (u16, wraps)."""

    def __init__(self, first_seq: int = 0) -> None:
        self.seq = first_seq & 0xFFFF

    def encode(self, msg: tuple) -> bytes:
        """Wire frame of ``msg`` with the next sequence number."""
        out = encode(msg, self.seq)
        self.seq = (self.seq + 1) & 0xFFFF
        return out

    def packer(self, cls: type, n_joints: int = 0) -> Callable[..., bytes]:
        """``frame(*values) -> bytes``: the wire frame of message class ``cls`` (n_joints
        long per-joint arrays) from its field values flattened in wire order (the fixed
        fields, then each array's entries), numbered by this encoder. The same bytes as
        :meth:`encode` of the message, without building it (streaming hot paths);
        :class:`ValueError` for a value out of its field's range."""
        spec = cls.SPEC
        n = n_joints if spec.per_joint else 0
        if spec.per_joint and not 1 <= n <= MAX_JOINTS:
            raise ValueError(f"{spec.name}: n_joints must be in 1..{MAX_JOINTS}, got {n_joints}")
        pack, mid, version = _BODY[(spec.msg_id, n)].pack, spec.msg_id, FRAME_VERSION
        crc32, cobs_encode = zlib.crc32, cobs.encode

        def python_frame(seq: int, values: tuple) -> bytes:
            try:
                raw = pack(version, mid, seq, *values)
            except struct.error as exc:
                raise ValueError(f"{spec.name}: {exc}") from None
            return cobs_encode(raw + crc32(raw).to_bytes(4, "little")) + b"\x00"

        fast = fastcodec.module()
        if fast is None:

            def frame(*values) -> bytes:
                seq = self.seq
                out = python_frame(seq, values)
                self.seq = (seq + 1) & 0xFFFF
                return out

            return frame
        # the C codec: values in their fields' ranges, else the Python path says why
        cfg, encode = _fast_config(spec, n), fast.encode

        def frame(*values) -> bytes:
            seq = self.seq
            out = encode(cfg, seq, values) or python_frame(seq, values)
            self.seq = (seq + 1) & 0xFFFF
            return out

        return frame

    def rows_packer(self, cls: type, n_joints: int) -> Callable[..., bytes]:
        """``frames(tick, flags, rows, start, count) -> bytes``: the wire frames of ``count``
        messages of ``cls`` (a streamed SETPOINT or SETPOINT_FF: tick, flags, then per-joint
        values) for ticks ``tick``, ``tick + 1``, ... (mod 2**32), the values after the
        flags being ``rows[start + i]`` (ints in wire order), numbered by this encoder: the
        bytes of :meth:`packer` frame after frame, in one call of the C codec when built.
        :class:`ValueError` for a value out of range (the frames before it numbered)."""
        pack = self.packer(cls, n_joints)
        fast = fastcodec.module()
        spec = cls.SPEC
        if fast is not None:
            cfg, encode_rows = _fast_config(spec, n_joints), fast.encode_rows

        def frames(tick: int, flags: int, rows, start: int, count: int) -> bytes:
            if fast is not None:
                out = encode_rows(cfg, self.seq, tick, flags, rows, start, count)
                if out is not None:
                    self.seq = (self.seq + count) & 0xFFFF
                    return out
            return b"".join([pack((tick + i) & 0xFFFFFFFF, flags, *rows[start + i])
                             for i in range(count)])  # fmt: skip

        return frames


def _fast_config(spec: MessageSpec, n_joints: int) -> bytes:
    """The C codec's description of a message's frames: id, joint count, value count n,
    the n smallest and the n largest values (int64s)."""
    fields = list(spec.fixed) + [f for f in spec.per_joint for _ in range(n_joints)]
    lo, hi = [f.lo for f in fields], [f.hi for f in fields]
    return array("q", [spec.msg_id, n_joints, len(fields), *lo, *hi]).tobytes()


def to_si(msg: tuple) -> dict:
    """Field values of ``msg`` in SI units (raw * scale; arrays become tuples of floats)."""
    out = {}
    for f, v in zip(msg.SPEC.fields, msg, strict=True):
        if f.scale == 1.0:
            out[f.name] = v
        else:
            out[f.name] = tuple(x * f.scale for x in v) if f.per_joint else v * f.scale
    return out
