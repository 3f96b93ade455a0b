"""Option types shared by the commands."""

from __future__ import annotations

import math

import click


class PositiveFinite(click.ParamType):
    """A finite number > 0 (click's FloatRange lets NaN and inf through)."""

    name = "float"

    def convert(self, value, param, ctx):
        x = value if isinstance(value, float) else click.FLOAT.convert(value, param, ctx)
        if not (math.isfinite(x) and x > 0):
            self.fail(f"{value!r} is not a finite number > 0", param, ctx)
        return x


POSITIVE = PositiveFinite()
