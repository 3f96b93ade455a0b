"""Wire protocol between the host and the guard robot's microcontroller.

Public API (all names importable from ``guardid.protocol``):

- ``SPEC``: :class:`ProtocolSpec` loaded from the packaged ``messages.yaml`` (identical copy
  of ``firmware_proto/messages.yaml``); ``PROTOCOL_VERSION`` (and the oldest a host talks
  to, ``MIN_PROTOCOL_VERSION``), ``MAX_JOINTS``.
- ``MESSAGES`` / ``BY_ID``: message classes (NamedTuples, field names from the YAML, raw
  integer values, per-joint fields as tuples of n_joints entries) by name / by id, also
  exported as attributes: ``Hello``, ``Ping``, ``SetMode``, ``SetPid``, ``Setpoint``,
  ``SetVoltage``, ``StartStream``, ``StopStream``, ``Estop``, ``ClearEstop``, ``SetWatchdog``,
  ``Info``, ``Pong``, ``Ack``, ``Nak``, ``Telemetry``, ``Fault``.
  Each class has ``MSG_ID`` and ``SPEC`` (fields with ``unit`` and ``scale``: SI = raw*scale).
- ``encode(msg, seq) -> bytes``: one wire frame incl. the 0x00 delimiter;
  ``Encoder().encode(msg)`` numbers frames itself (u16 wrapping sequence).
- ``decode(frame) -> Frame | str``: decode one frame, or the error kind as a string.
- ``FrameParser().feed(chunk) -> list[Frame]``: incremental parser for arbitrary chunks;
  ``parser.stats`` (:class:`ParserStats`) counts CRC/framing errors, overflows and
  sequence gaps (missing frames). ``Frame(msg_id, seq, msg)``.
- ``to_si(msg) -> dict``: field values scaled to SI units.
- ``ENUMS``: the YAML enums (modes, NAK error codes, fault codes, status/capability bits).
"""

from .codec import (
    BY_ID,
    MAX_ENCODED,
    MAX_JOINTS,
    MAX_RAW,
    MESSAGES,
    MIN_PROTOCOL_VERSION,
    PROTOCOL_VERSION,
    SPEC,
    Encoder,
    Frame,
    decode,
    encode,
    encode_raw,
    n_joints_of,
    to_si,
)
from .parser import FrameParser, ParserStats
from .spec import FieldSpec, MessageSpec, ProtocolSpec, load_spec

ENUMS = SPEC.enums
globals().update({cls.__name__: cls for cls in MESSAGES.values()})

__all__ = [
    "BY_ID",
    "ENUMS",
    "MAX_ENCODED",
    "MAX_JOINTS",
    "MAX_RAW",
    "MESSAGES",
    "MIN_PROTOCOL_VERSION",
    "PROTOCOL_VERSION",
    "SPEC",
    "Encoder",
    "FieldSpec",
    "Frame",
    "FrameParser",
    "MessageSpec",
    "ParserStats",
    "ProtocolSpec",
    "decode",
    "encode",
    "encode_raw",
    "load_spec",
    "n_joints_of",
    "to_si",
    *(cls.__name__ for cls in MESSAGES.values()),
]
