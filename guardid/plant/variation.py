"""What a real robot's repeated runs vary, for the simulator: the start pose and the
supply voltage, each drawn from the run's seed on a stream of its own (so the sensor noise
of a seed is the same with or without them).

The firmware's PID closes on encoder counts and the sensors' noise does not enter the loop,
so a simulated closed-loop run is deterministic apart from its start, and the loop forgets
its start within seconds (stiction keeps a fraction of a count of it): seeds that differ
only in start pose and sensor noise share most of their motion and quantisation error. A
supply voltage that differs per run (a bench supply's setting, a battery's charge) and per
tick (other loads on the supply) changes the motion as on a real robot. The voltage the
motors see is what the voltage sensor measures and the current follows it, so the rigid
body's equation holds exactly as without them.
"""

from __future__ import annotations

import random
from typing import NamedTuple

from guardid.plant.joints import joint_constants


class SupplyVariation(NamedTuple):
    """How the motors' supply voltage differs from the robot's nominal one: per run by a
    factor 1 + u, u uniform in [-``spread``, ``spread``]; per tick by a further factor
    1 + ``ripple`` z, z standard normal, the same for every motor (fractions)."""

    spread: float = 0.0
    ripple: float = 0.0

    @property
    def active(self) -> bool:
        return self.spread > 0.0 or self.ripple > 0.0

    def factors(self, seed: int):
        """Endless iterator of per-tick supply factors drawn from ``seed`` (its own stream)."""
        rng = random.Random(f"supply-{seed}")
        run = 1.0 + rng.uniform(-self.spread, self.spread)
        while True:
            yield run * (1.0 + self.ripple * rng.gauss(0.0, 1.0)) if self.ripple else run


def start_pose_q0(description, seed: int, counts: float) -> list[float]:
    """Start angles [rad]: each joint at a random point within +-``counts`` encoder counts
    of zero (uniform, real-valued: whole counts and the phase within one), drawn from
    ``seed`` (its own stream) and clipped into the joint's position limits."""
    rng = random.Random(f"start-pose-{seed}")
    q0 = []
    for jc in joint_constants(description, friction=True, limits=True):
        x = rng.uniform(-counts, counts) / jc.counts_per_rad if jc.counts_per_rad else 0.0
        q0.append(min(max(x, jc.lo), jc.hi))
    return q0
