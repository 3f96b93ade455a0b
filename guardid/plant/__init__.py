"""Simulated plant: gear motors, rigid-body dynamics, stick/slip friction, sensors, payload.

``Plant(robot, seed=..., payload=[PayloadChange(...)], noise=True).step(volts)`` advances
one sample period with the voltages held (zero-order hold) and returns a
:class:`SensorSample` (encoder counts, period-mean voltage and current as the ADC reports
them, and the true values). The physics, the stiction model and the integrator are
documented in :mod:`guardid.plant.plant`; sensors in :mod:`guardid.plant.sensors`.
"""

from guardid.plant.joints import PlantError
from guardid.plant.payload import PayloadChange
from guardid.plant.plant import DEFAULT_SUBSTEPS, Plant, PlantState, SensorSample, make_plant
from guardid.plant.variation import SupplyVariation, start_pose_q0

__all__ = [
    "DEFAULT_SUBSTEPS",
    "PayloadChange",
    "Plant",
    "PlantError",
    "PlantState",
    "SensorSample",
    "SupplyVariation",
    "make_plant",
    "start_pose_q0",
]
