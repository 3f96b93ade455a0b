"""Incremental frame parser: arbitrary byte chunks in, valid frames out, errors counted.

Segments are the bytes between 0x00 delimiters. Each non-empty segment is exactly one of:
a valid frame, or one counted error (first failing check wins, in this order): longer
than ``MAX_ENCODED`` (``overflows``), bad COBS (``cobs_errors``), shorter than header +
CRC (``short_frames``), CRC mismatch (``crc_errors``), wrong protocol version
(``bad_version``), unknown message id (``unknown_id``), payload length impossible for
the id (``bad_length``). Empty segments (repeated delimiters) are idle fill, not errors.
Nothing is ever raised out of :meth:`FrameParser.feed`.

With the protocol's C codec built (:mod:`guardid.protocol.fastcodec`), a chunk's leading
segments that are valid frames of the kind the parser took last, in sequence (a stream of
telemetry, a block of setpoints), are decoded in one call; the Python path goes on from the
first other segment, so the frames and the counters are the same either way.
"""

from __future__ import annotations

import zlib
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, fields

from cobs import cobs

from . import fastcodec
from .codec import (
    _N_FIXED,
    BY_ID,
    CRC_RESIDUE,
    DECODERS,
    FRAME_VERSION,
    MAX_ENCODED,
    MIN_RAW,
    Frame,
)

_cobs_decode, _CobsError, _crc32 = cobs.decode, cobs.DecodeError, zlib.crc32


@dataclass
class ParserStats:
    """Counters of a :class:`FrameParser` (all plain ints)."""

    bytes: int = 0  #: bytes fed
    frames: int = 0  #: valid frames yielded
    overflows: int = 0  #: segments longer than MAX_ENCODED, dropped unread
    cobs_errors: int = 0
    short_frames: int = 0
    crc_errors: int = 0
    bad_version: int = 0
    unknown_id: int = 0
    bad_length: int = 0
    seq_gaps: int = 0  #: frames missing according to the sequence numbers
    seq_backwards: int = 0  #: frames whose seq went back (duplicate, reorder or peer reset)

    @property
    def framing_errors(self) -> int:
        """Segments rejected before or after the CRC for a reason other than the CRC."""
        return (
            self.overflows
            + self.cobs_errors
            + self.short_frames
            + self.bad_version
            + self.unknown_id
            + self.bad_length
        )

    @property
    def errors(self) -> int:
        """All rejected segments (framing + CRC)."""
        return self.framing_errors + self.crc_errors

    def as_dict(self) -> dict[str, int]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


class FrameParser:
    """Feed byte chunks of one or both directions; sequence gaps are tracked per direction.

    The buffer never holds more than ``MAX_ENCODED`` bytes: a longer segment is counted
    once in ``stats.overflows`` and skipped up to the next delimiter.
    """

    def __init__(self) -> None:
        self.stats = ParserStats()
        self._buf = b""
        self._discard = False
        self._expect: list[int | None] = [None, None]  # host->mcu, mcu->host
        # (msg_id, raw length) -> (unpack, class, field getter, sink or None): DECODERS
        # with the routes of route() filled in, one lookup per frame
        self._table = {key: (st.unpack, cls, get, None) for key, (st, cls, get) in DECODERS.items()}
        fast = fastcodec.module()
        self._scan = None if fast is None else fast.scan
        self._kind: tuple[int, int] | None = None  # (msg_id, raw length) of the last frame
        self._extend: dict[int, Callable | None] = {}  # msg_id -> extend of a route's sink

    def route(self, msg_id: int, cls: type, sink: Callable[[tuple], object]) -> None:
        """Hand valid frames of ``msg_id`` to ``sink(msg)`` as they are parsed, ``msg``
        built as ``cls`` (a tuple class with the message's fields in order, e.g. a
        NamedTuple), instead of returning them from :meth:`feed` (streaming hot path: no
        :class:`Frame` per frame). They are counted and sequence-checked as the others."""
        for key, (st, _, get) in DECODERS.items():
            if key[0] == msg_id:
                self._table[key] = (st.unpack, cls, get, sink)
        owner = getattr(sink, "__self__", None)  # a list's or deque's append: extend, at once
        self._extend[msg_id] = owner.extend if type(owner) in (list, deque) else None

    def reset_sequence(self) -> None:
        """Forget the expected sequence numbers (e.g. after the peer was reset)."""
        self._expect = [None, None]

    def feed(self, chunk: bytes) -> list[Frame]:
        """Parse ``chunk``; return the frames it completed, in order."""
        st = self.stats
        st.bytes += len(chunk)
        if self._buf:
            chunk = self._buf + chunk
        if type(chunk) is not bytes:
            chunk = bytes(chunk)
        out: list[Frame] = []
        if self._kind is not None and self._scan is not None and not self._discard:
            chunk = self._feed_scanned(chunk, out)
        parts = chunk.split(b"\x00")
        tail = parts.pop()
        if self._discard:
            if not parts:
                return []
            parts[0] = b""
            self._discard = False
        if len(tail) > MAX_ENCODED:
            st.overflows += 1
            self._discard = True
            tail = b""
        self._buf = tail
        table = self._table
        expect = self._expect
        new = tuple.__new__
        routed = 0
        for seg in parts:
            if not seg:
                continue
            if len(seg) > MAX_ENCODED:
                st.overflows += 1
                continue
            try:
                raw = _cobs_decode(seg)
            except _CobsError:
                st.cobs_errors += 1
                continue
            n = len(raw)
            if n < MIN_RAW:
                st.short_frames += 1
                continue
            if _crc32(raw) != CRC_RESIDUE:
                st.crc_errors += 1
                continue
            if raw[0] != FRAME_VERSION:
                st.bad_version += 1
                continue
            mid = raw[1]
            entry = table.get((mid, n))
            if entry is None:
                if mid in BY_ID:
                    st.bad_length += 1
                else:
                    st.unknown_id += 1
                continue
            unpack, cls, get, sink = entry
            vals = unpack(raw)
            seq = vals[2]
            d = mid >> 7
            exp = expect[d]
            if exp is not None and seq != exp:
                gap = (seq - exp) & 0xFFFF
                if gap < 0x8000:
                    st.seq_gaps += gap
                else:
                    st.seq_backwards += 1
            expect[d] = (seq + 1) & 0xFFFF
            self._kind = (mid, n)
            if sink is not None:
                sink(new(cls, get(vals)))
                routed += 1
            else:
                out.append(new(Frame, (mid, seq, new(cls, get(vals)))))
        st.frames += len(out) + routed
        return out

    def _feed_scanned(self, chunk: bytes, out: list) -> bytes:
        """The leading frames of the last kind in ``chunk`` through the C codec, into
        ``out`` (counted by :meth:`feed`) or to their route; returns the rest of the chunk."""
        mid, n = self._kind
        _, cls, _, sink = self._table[(mid, n)]
        d = mid >> 7
        exp = self._expect[d]
        wrap = Frame if sink is None else None  # a routed sink takes messages (even if falsy)
        frames, used, nxt = self._scan(chunk, mid, n, -1 if exp is None else exp,
                                       _N_FIXED[mid], cls, wrap)  # fmt: skip
        if not frames:
            return chunk
        self._expect[d] = nxt
        if sink is None:
            out += frames
        else:
            extend = self._extend[mid]
            if extend is not None and sink.__name__ == "append":
                extend(frames)
            else:
                for msg in frames:
                    sink(msg)
            self.stats.frames += len(frames)
        return chunk[used:]
