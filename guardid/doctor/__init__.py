"""``guardid doctor``: bring-up checks of a robot on the bench (wiring, sensors, link,
watchdog, e-stop) from short, limit-checked voltage pulses; a verdict and a fix per check."""

from guardid.doctor.bench import run_checks
from guardid.doctor.checks import FAIL, OK, UNKNOWN, WARN, Check
from guardid.doctor.link_checks import latency_check

__all__ = ["FAIL", "OK", "UNKNOWN", "WARN", "Check", "latency_check", "run_checks"]
