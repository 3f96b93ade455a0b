"""The feedforward voltage of a trajectory (package docstring)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from guardid.dynamics import build_model
from guardid.errors import ConfigError

CHECK_STEP_S = 0.5e-3
"""Grid on which one period of the trajectory is checked against the supply [s]."""


@dataclass(frozen=True)
class FeedforwardModel:
    """A robot model for feedforward: ``description`` (its base regressor and drives),
    base parameter values ``theta`` (b,) [SI], and per joint the motor's resistance
    ``resistance_ohm`` (n,) [ohm] and back-EMF constant ``ke_v_s_per_rad`` (n,) [V s/rad,
    motor side]; ``label`` says where the values come from."""

    description: object
    theta: np.ndarray
    resistance_ohm: np.ndarray
    ke_v_s_per_rad: np.ndarray
    label: str
    model: object = field(default=None, repr=False, compare=False)  #: the ChainModel

    def __post_init__(self) -> None:
        if self.model is None:
            object.__setattr__(self, "model", build_model(self.description))

    @classmethod
    def from_description(cls, description, label: str = "") -> FeedforwardModel:
        """The robot description's own values (the true ones on ``sim://``)."""
        model = build_model(description)
        drives = [j.drive for j in description.joints]
        return cls(
            description,
            np.asarray(model.base.values(model.params), dtype=float),
            np.array([d.resistance for d in drives]),
            np.array([d.ke for d in drives]),
            label or f"robot {description.name}",
            model,
        )

    def torque(self, q, qd, qdd) -> np.ndarray:
        """Joint torques (N, n) [N m] of the states (N, n) [rad, rad/s, rad/s^2]."""
        return self.model.base_regressor(q, qd, qdd) @ self.theta

    def voltage(self, q, qd, qdd) -> np.ndarray:
        """Motor voltages (N, n) [V]: V = R i + Ke N q', i = tau / (N eta Kt)."""
        drives = self.description.joints
        gear = np.array([j.drive.gear_ratio for j in drives])
        gain = np.array([j.drive.gear_ratio * j.drive.efficiency * j.drive.kt for j in drives])
        current = self.torque(q, qd, qdd) / gain
        return self.resistance_ohm * current + self.ke_v_s_per_rad * gear * np.asarray(qd)

    def trajectory_voltage(self, trajectory, t_s) -> np.ndarray:
        """Voltages (N, n) [V] the trajectory needs at the times ``t_s`` (N,) [s]."""
        return self.voltage(*trajectory.states(np.asarray(t_s, dtype=float)))


def feedforward_mv(model: FeedforwardModel, trajectory, period_s: float, start: int, stop: int):
    """(stop - start, n) int feedforward [mV] for ticks ``start .. stop-1``: the voltage at
    the middle of the period over which the firmware holds tick k's output, t = (k + 1/2) T."""
    t = (np.arange(start, stop) + 0.5) * period_s
    return np.rint(model.trajectory_voltage(trajectory, t) * 1000.0).astype(np.int64)


def supply_share(model: FeedforwardModel, trajectory) -> tuple[float, int, float, float]:
    """(largest |V| / supply [-], its joint, its voltage [V], its time [s]) of the
    trajectory's feedforward over one period (the trajectory is periodic)."""
    t = np.arange(0.0, trajectory.period, CHECK_STEP_S)
    volts = model.trajectory_voltage(trajectory, t)
    supply = np.array([j.drive.supply_voltage for j in model.description.joints])
    share = np.abs(volts) / supply
    k, j = np.unravel_index(np.argmax(share), share.shape)
    return float(share[k, j]), int(j), float(volts[k, j]), float(t[k])


def check_supply(model: FeedforwardModel, trajectory, source: str) -> float:
    """ConfigError (one line, naming the joint, the voltage, the time and the supply) unless
    the trajectory's feedforward stays within every motor's supply voltage over one period
    (the trajectory is periodic); returns the largest share of a supply it needs [-]."""
    share, j, volts, t = supply_share(model, trajectory)
    if share > 1.0:
        joint = model.description.joints[j]
        raise ConfigError(
            f"{source}: joint {joint.name} needs {volts:+.2f} V at t = {t:.3f} s of the "
            f"trajectory, beyond its {joint.drive.supply_voltage:g} V supply (feedforward "
            f"from {model.label}); slow the trajectory down (guardid excite); nothing moved"
        )
    return share


def load_feedforward(path: str, description) -> FeedforwardModel:
    """The feedforward model of a params file written by ``guardid identify``: the base
    parameters of its reference method (WLS, else LS, else the first with a std), its motors'
    R and Ke (the robot description's where it has none). ConfigError (one line) when it does
    not fit ``description``."""
    from guardid.identify.report import read_params
    from guardid.identify.untrusted import REFERENCE_METHODS
    from guardid.identify.validation import params_sets

    data = read_params(path)
    if data["robot"] != description.name:
        raise ConfigError(
            f"--feedforward {path}: robot: {data['robot']}, but the capture is on "
            f"{description.name}"
        )
    sets = {s.label.rsplit(":", 1)[1].lower(): s for s in params_sets(path, data, description)}
    if not sets:
        raise ConfigError(f"--feedforward {path}: methods: empty (rerun guardid identify)")
    method = next((m for m in REFERENCE_METHODS if m in sets), next(iter(sets)))
    model = build_model(description)
    theta = np.array([sets[method].values[n] for n in model.base.names])
    if not np.all(np.isfinite(theta)):
        raise ConfigError(f"--feedforward {path}: methods.{method}.values: not all finite")
    nominal = FeedforwardModel.from_description(description)
    r, ke = nominal.resistance_ohm.copy(), nominal.ke_v_s_per_rad.copy()
    names = [j.name for j in description.joints]
    for m, entry in enumerate(data.get("motors") or []):
        if isinstance(entry, dict) and entry.get("joint") in names:
            k = names.index(entry["joint"])
            r[k] = _positive(entry, "resistance_ohm", r[k], f"{path}: motors[{m}]")
            ke[k] = _positive(entry, "ke_v_s_per_rad", ke[k], f"{path}: motors[{m}]")
    return FeedforwardModel(description, theta, r, ke, f"{path} ({method.upper()})", model)


def _positive(entry: dict, key: str, default: float, where: str) -> float:
    """``entry[key]`` as a finite positive float (``default`` when absent); ConfigError."""
    value = entry.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise ConfigError(f"--feedforward {where}.{key}: {value!r} is not a positive number")
    if not np.isfinite(value):
        raise ConfigError(f"--feedforward {where}.{key}: {value!r} is not finite")
    return float(value)
