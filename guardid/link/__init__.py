"""Host side of the serial link: opening ports, the protocol session, setpoint streaming."""

from guardid.link.port import open_port
from guardid.link.session import RetryPolicy, Session, Telemetry

__all__ = ["RetryPolicy", "Session", "Telemetry", "open_port"]
