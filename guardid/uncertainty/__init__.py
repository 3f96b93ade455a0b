"""The encoder quantisation's share of the uncertainty, measured from the run itself
(``guardid identify --quantisation-bootstrap K``; docs/quantisation_bootstrap.md).

The encoder's whole counts act through the closed loop (the firmware's PID closes on
counts): their error is a deterministic function of the motion, the PID and the encoder's
resolution, so it does not shrink with the log's length and the residuals (white) do not
show it. A parametric bootstrap sizes it: the closed loop is simulated with the identified
parameters and the log's setpoints (:mod:`guardid.uncertainty.replicas`), K times from start
poses a fraction of a count apart, each replica is conditioned and fitted exactly as the
log was, and the replicas' errors against the parameters they were simulated with give the
quantisation's bias and covariance (:mod:`guardid.uncertainty.bootstrap`).

Data path: runs -> replicas (closedloop.simulate) -> identify -> statistics.
"""

from guardid.uncertainty.bootstrap import (
    BootstrapOptions,
    QuantisationBootstrap,
    quantisation_bootstrap,
)
from guardid.uncertainty.replicas import replica_run, simulated_values

__all__ = [
    "BootstrapOptions",
    "QuantisationBootstrap",
    "quantisation_bootstrap",
    "replica_run",
    "simulated_values",
]
