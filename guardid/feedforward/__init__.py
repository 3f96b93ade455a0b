"""Model-based feedforward: the motor voltage a trajectory needs, from an identified model.

``capture --feedforward params.yaml`` streams it with each setpoint (SETPOINT_FF, protocol
version 2) and the firmware adds it to its PID output before the limits
(firmware_proto/README.md). :class:`FeedforwardModel` turns the trajectory's exact q, q',
q'' into joint torques (base regressor times the identified base parameters: rigid body,
rotor inertia, friction), the torques into motor currents (i = tau / (N eta Kt), the
drive of the robot description) and the currents into voltages (V = R i + Ke N q', R and
Ke as identified); :func:`check_supply` refuses a trajectory that needs more than a
motor's supply before anything moves.
"""

from guardid.feedforward.model import (
    FeedforwardModel,
    check_supply,
    feedforward_mv,
    load_feedforward,
    supply_share,
)

__all__ = ["FeedforwardModel", "check_supply", "feedforward_mv", "load_feedforward", "supply_share"]
