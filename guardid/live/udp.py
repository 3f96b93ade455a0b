"""``guardid capture --stream udp://HOST:PORT``: every log row, as it is written, sent as
one JSON datagram (:mod:`guardid.live.rows`) to PlotJuggler's UDP server (or anything
that reads JSON over UDP).

The stream never slows or breaks the capture: the socket is non-blocking, and a datagram
that cannot be sent at once (socket buffer full, network down, a value JSON cannot carry)
is counted in :attr:`UdpStream.dropped` and skipped. UDP does not say whether a datagram
arrived; only the sender's failures are counted. The URL is checked, and its host name
resolved, before anything moves (:func:`parse_stream_url`).
"""

from __future__ import annotations

import json
import socket
from dataclasses import dataclass
from urllib.parse import urlsplit

from guardid.errors import ConfigError
from guardid.live.rows import RowLayout
from guardid.log.csvlog import column_names

PLOTJUGGLER_PORT = 9870
"""PlotJuggler's UDP server's default port."""

_GIVE = f"give udp://HOST:PORT (PlotJuggler on this machine: udp://127.0.0.1:{PLOTJUGGLER_PORT})"


@dataclass(frozen=True)
class StreamTarget:
    """Where ``--stream`` sends: the URL as given, the socket family and the resolved
    address (a ``sockaddr`` tuple)."""

    url: str
    family: int
    address: tuple


def parse_stream_url(url: str, option: str = "--stream") -> StreamTarget:
    """The :class:`StreamTarget` of ``udp://HOST:PORT`` (HOST a name, an IPv4 address or
    an IPv6 address in brackets); a :class:`ConfigError` naming ``option`` for anything
    else, a port outside 1-65535 or a host name that does not resolve."""
    text = (url or "").strip()
    if not text:
        raise ConfigError(f"{option} '': empty; {_GIVE}")
    try:
        parts = urlsplit(text)
        port = parts.port
    except ValueError:
        raise ConfigError(f"{option} {url}: the port must be a number 1-65535; {_GIVE}") from None
    if parts.scheme.lower() != "udp":
        raise ConfigError(f"{option} {url}: not a udp:// URL; {_GIVE}")
    if not parts.hostname:
        raise ConfigError(f"{option} {url}: no host; {_GIVE}")
    if port is None or not 1 <= port <= 65535:
        raise ConfigError(f"{option} {url}: no port (1-65535); {_GIVE}")
    if parts.path not in ("", "/") or parts.query or parts.fragment or parts.username:
        raise ConfigError(f"{option} {url}: only a host and a port are understood; {_GIVE}")
    try:
        family, _, _, _, address = socket.getaddrinfo(parts.hostname, port, 0, socket.SOCK_DGRAM)[0]
    except (socket.gaierror, UnicodeError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        raise ConfigError(f"{option} {url}: cannot resolve {parts.hostname}: {why}") from None
    return StreamTarget(text, family, address)


class UdpStream:
    """Send log rows of a robot with joints ``joint_names`` to ``target``, one JSON object
    per datagram. :attr:`sent` counts datagrams handed to the network, :attr:`dropped`
    those that could not be (:attr:`first_error` says why the first one was not)."""

    def __init__(self, target: StreamTarget, joint_names) -> None:
        self.target = target
        self.layout = RowLayout.for_columns(column_names(joint_names), joint_names)
        self.sent = 0
        self.dropped = 0
        self.first_error: str | None = None
        try:
            self._sock = socket.socket(target.family, socket.SOCK_DGRAM)
            self._sock.setblocking(False)
        except OSError as exc:
            raise ConfigError(f"--stream {target.url}: cannot open a UDP socket: {exc}") from None

    def send_row(self, tick, time_s, counts, q, v, i, sp, status) -> None:
        """Send one row; the arguments are :meth:`guardid.log.LogWriter.write_row`'s.
        Never raises: a row that cannot be sent at once is counted as dropped."""
        values = [tick, time_s, *counts, *q, *v, *i, *sp, status]
        try:
            message = self.layout.message(values)
            data = json.dumps(message, separators=(",", ":"), allow_nan=False).encode()
            self._send(data)
        except (OSError, ValueError) as exc:
            self.dropped += 1
            if self.first_error is None:
                self.first_error = str(exc) or type(exc).__name__
        else:
            self.sent += 1

    def _send(self, data: bytes) -> None:
        """The one place datagrams leave (tests inject send failures here)."""
        self._sock.sendto(data, self.target.address)

    def summary(self) -> str:
        """One line: rows sent and dropped, and why the first was dropped."""
        line = f"stream: {self.sent} rows sent to {self.target.url}, {self.dropped} dropped"
        if self.first_error is not None:
            line += f" (first: {self.first_error})"
        return line

    def close(self) -> None:
        """Close the socket (safe to call twice)."""
        self._sock.close()
