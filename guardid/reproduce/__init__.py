"""Reproductions of the seed papers' experiments (``guardid reproduce``).

One module per experiment, each with ``NAME``, ``run(seed) -> Report`` and
``plot(report, out_dir) -> list of paths``; :mod:`guardid.reproduce.common` holds the shared
integrator, metrics and the printer, :mod:`guardid.reproduce.flexsim` the flexible-link
simulation shared by the three seed 000 experiments.
"""

from __future__ import annotations

from guardid.reproduce import seed000_fast, seed000_slow, seed000_step, seed001_table1

EXPERIMENTS = {m.NAME: m for m in (seed000_step, seed000_slow, seed000_fast, seed001_table1)}
"""Experiment name -> module."""

__all__ = ["EXPERIMENTS"]
