"""Load and validate the message definition (``messages.yaml``) into plain spec objects.

The packaged copy ``guardid/protocol/messages.yaml`` is written by
``firmware_proto/gen_header.py`` from ``firmware_proto/messages.yaml``; both are identical.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import yaml

#: struct format character and size in bytes of each wire integer type.
INT_TYPES = {
    "u8": ("B", 1),
    "i8": ("b", 1),
    "u16": ("H", 2),
    "i16": ("h", 2),
    "u32": ("I", 4),
    "i32": ("i", 4),
}
HEADER_LEN = 4  #: version u8, msg_id u8, seq u16
CRC_LEN = 4  #: CRC-32 (zlib) little-endian, over header + payload
PACKAGED_YAML = Path(__file__).with_name("messages.yaml")


@dataclass(frozen=True)
class FieldSpec:
    """One field: wire type, SI unit and scale (SI value = raw * scale)."""

    name: str
    type: str
    per_joint: bool = False
    unit: str = ""
    scale: float = 1.0
    enum: str | None = None
    bits: str | None = None

    @property
    def fmt(self) -> str:
        return INT_TYPES[self.type][0]

    @property
    def size(self) -> int:
        return INT_TYPES[self.type][1]

    @property
    def lo(self) -> int:
        """Smallest raw value."""
        return -(1 << (8 * self.size - 1)) if self.type[0] == "i" else 0

    @property
    def hi(self) -> int:
        """Largest raw value."""
        n = 8 * self.size
        return (1 << (n - 1)) - 1 if self.type[0] == "i" else (1 << n) - 1


@dataclass(frozen=True)
class MessageSpec:
    """One message: id, fields (fixed ones first, then per-joint arrays) and layout."""

    name: str
    msg_id: int
    doc: str
    fields: tuple[FieldSpec, ...]

    @property
    def fixed(self) -> tuple[FieldSpec, ...]:
        return tuple(f for f in self.fields if not f.per_joint)

    @property
    def per_joint(self) -> tuple[FieldSpec, ...]:
        return tuple(f for f in self.fields if f.per_joint)

    @property
    def fixed_size(self) -> int:
        """Payload bytes of the fixed fields."""
        return sum(f.size for f in self.fixed)

    @property
    def joint_size(self) -> int:
        """Payload bytes added per joint (0 if the message has no per-joint field)."""
        return sum(f.size for f in self.per_joint)

    @property
    def to_host(self) -> bool:
        """True for microcontroller -> host messages (id bit 7 set)."""
        return bool(self.msg_id & 0x80)

    def payload_size(self, n_joints: int = 0) -> int:
        """Payload length in bytes for ``n_joints`` (ignored without per-joint fields)."""
        return self.fixed_size + (n_joints * self.joint_size if self.per_joint else 0)

    def struct_for(self, n_joints: int) -> struct.Struct:
        """Precompiled little-endian struct of header + payload + CRC."""
        fmt = "<BBH" + "".join(f.fmt for f in self.fixed)
        if self.per_joint:
            fmt += "".join(f"{n_joints}{f.fmt}" for f in self.per_joint)
        return struct.Struct(fmt + "I")


@dataclass(frozen=True)
class ProtocolSpec:
    """The whole protocol: version, joint limit, enums and messages."""

    version: int
    max_joints: int
    tick_period_us: int
    enums: dict
    messages: tuple[MessageSpec, ...]
    frame_version: int = 1  #: the header's version byte (frame layout)
    min_version: int = 1  #: oldest protocol version (INFO) a host can talk to

    tick_period_us: int
    enums: dict
    messages: tuple[MessageSpec, ...]

    def by_name(self, name: str) -> MessageSpec:
        return next(m for m in self.messages if m.name == name)

    @property
    def max_payload(self) -> int:
        return max(m.payload_size(self.max_joints) for m in self.messages)


def _check(cond: bool, what: str) -> None:
    if not cond:
        raise ValueError(f"messages.yaml: {what}")


def parse_spec(doc: dict) -> ProtocolSpec:
    """Validate a loaded YAML document and build the :class:`ProtocolSpec`."""
    msgs = []
    seen: set[int] = set()
    for m in doc["messages"]:
        mid = int(m["id"])
        _check(0 < mid < 256 and mid not in seen, f"{m['name']}: bad or duplicate id {mid}")
        seen.add(mid)
        fields = tuple(
            FieldSpec(
                name=f["name"],
                type=f["type"],
                per_joint=bool(f.get("per_joint", False)),
                unit=str(f.get("unit", "")),
                scale=float(f.get("scale", 1.0)),
                enum=f.get("enum"),
                bits=f.get("bits"),
            )
            for f in m.get("fields") or []
        )
        for f in fields:
            _check(f.type in INT_TYPES, f"{m['name']}.{f.name}: unknown type {f.type}")
        pj = [f.per_joint for f in fields]
        _check(pj == sorted(pj), f"{m['name']}: per-joint fields must come last")
        msgs.append(MessageSpec(m["name"], mid, " ".join(str(m.get("doc", "")).split()), fields))
    return ProtocolSpec(
        version=int(doc["protocol_version"]),
        max_joints=int(doc["max_joints"]),
        tick_period_us=int(doc["tick_period_us"]),
        enums=dict(doc.get("enums") or {}),
        messages=tuple(msgs),
        frame_version=int(doc.get("frame_version", doc["protocol_version"])),
        min_version=int(doc.get("min_protocol_version", doc["protocol_version"])),
    )


def load_spec(path: str | Path = PACKAGED_YAML) -> ProtocolSpec:
    """Read ``messages.yaml`` (the packaged copy by default)."""
    with open(path, encoding="utf-8") as fh:
        return parse_spec(yaml.safe_load(fh))
