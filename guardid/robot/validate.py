"""Small helpers that check YAML values and raise one-line ConfigErrors naming file and key."""

from __future__ import annotations

import math

from guardid.errors import ConfigError

MAX_MAGNITUDE = 1e15
"""Largest magnitude of any number in a robot description (a Young's modulus is ~2e11 Pa):
beyond it products in the dynamics overflow (a link mass of 1e308 kg gave numpy warnings)."""


class Checker:
    """Validation context for one file: every error reads ``<file>: <key path>: <problem>``."""

    def __init__(self, filename: str):
        self.filename = filename

    def fail(self, path: str, message: str) -> None:
        """Raise the ConfigError for ``path``."""
        raise ConfigError(f"{self.filename}: {path or '<top>'}: {message}")

    def mapping(
        self, value, path: str, required: tuple[str, ...], optional: tuple[str, ...] = ()
    ) -> dict:
        """Check that ``value`` is a mapping with exactly the allowed keys; return it."""
        if not isinstance(value, dict):
            self.fail(path, f"expected a mapping, got {_show(value)}")
        allowed = set(required) | set(optional)
        for key in value:
            if key not in allowed:
                hint = ", ".join(sorted(allowed))
                self.fail(_join(path, str(key)), f"unknown key (allowed: {hint})")
        for key in required:
            if key not in value:
                self.fail(_join(path, key), "missing required key")
        return value

    def number(self, value, path: str, *, positive=False, nonneg=False, lo=None, hi=None):
        """Check a finite real number (bools rejected) with optional bounds; return float."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(path, f"expected a number, got {_show(value)}")
        x = float(value)
        if not math.isfinite(x):
            self.fail(path, f"expected a finite number, got {value!r}")
        if abs(x) > MAX_MAGNITUDE:
            self.fail(path, f"{x:g} is beyond any robot (magnitude at most {MAX_MAGNITUDE:g})")
        if positive and x <= 0:
            self.fail(path, f"must be > 0, got {x:g}")
        if nonneg and x < 0:
            self.fail(path, f"must be >= 0, got {x:g}")
        if lo is not None and x <= lo:
            self.fail(path, f"must be > {lo:g}, got {x:g}")
        if hi is not None and x > hi:
            self.fail(path, f"must be <= {hi:g}, got {x:g}")
        return x

    def integer(self, value, path: str, *, minimum: int = 1) -> int:
        """Check an integer >= minimum; return it."""
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(path, f"expected an integer, got {_show(value)}")
        if value < minimum:
            self.fail(path, f"must be >= {minimum}, got {value}")
        return int(value)

    def string(self, value, path: str, choices: tuple[str, ...] | None = None) -> str:
        """Check a string, optionally one of ``choices``; return it."""
        if not isinstance(value, str):
            self.fail(path, f"expected a string, got {_show(value)}")
        if choices is not None and value not in choices:
            self.fail(path, f"expected one of {', '.join(choices)}, got {value!r}")
        return value

    def boolean(self, value, path: str) -> bool:
        """Check a YAML boolean; return it."""
        if not isinstance(value, bool):
            self.fail(path, f"expected true or false, got {_show(value)}")
        return value

    def sequence(self, value, path: str, length: int | None = None) -> list:
        """Check a list (of the given length); return it."""
        if not isinstance(value, list):
            self.fail(path, f"expected a list, got {_show(value)}")
        if length is not None and len(value) != length:
            self.fail(path, f"expected a list of {length} items, got {len(value)}")
        return value

    def vector(self, value, path: str, length: int) -> list[float]:
        """Check a list of ``length`` numbers; return floats."""
        items = self.sequence(value, path, length)
        return [self.number(v, f"{path}[{i}]") for i, v in enumerate(items)]


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _show(value) -> str:
    if value is None:
        return "null"
    if isinstance(value, (dict, list)):
        return f"a {type(value).__name__}"
    return repr(value)
