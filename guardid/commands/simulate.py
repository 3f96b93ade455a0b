"""``guardid simulate``: closed-loop run of the simulated plant, true and sensed signals to CSV."""

from __future__ import annotations

import math
import time

import click

from guardid.commands.outputs import force_option, output_option
from guardid.errors import GuardidError

_WEIGHTS = (0.5, 0.3, 0.2)  # share of the amplitude per sine
_FREQS = (0.3, 0.8, 1.7)  # rad/s, scaled per joint so the peak speed stays in its limit


class SimulateError(GuardidError):
    """Invalid ``simulate`` options or an unwritable output file."""


class SumOfSines:
    """Smooth reference per joint: centre + sum_k a_k sin(w_k t) [rad], inside the limits."""

    def __init__(self, description):
        self.terms = []
        for j, joint in enumerate(description.joints):
            pos = joint.limits.position if joint.limits is not None else None
            centre, amp = ((pos[0] + pos[1]) / 2, 0.35 * (pos[1] - pos[0])) if pos else (0.0, 1.0)
            scale = 1.0 / (1.0 + 0.25 * j)
            peak = amp * sum(a * w * scale for a, w in zip(_WEIGHTS, _FREQS, strict=True))
            vmax = joint.limits.velocity if joint.limits is not None else math.inf
            if peak > 0.6 * vmax:
                scale *= 0.6 * vmax / peak
            self.terms.append(
                (centre, [(amp * a, w * scale) for a, w in zip(_WEIGHTS, _FREQS, strict=True)])
            )

    def __call__(self, t: float) -> list[float]:
        """Setpoint [rad] per joint at time ``t`` [s]."""
        return [c + sum(a * math.sin(w * t) for a, w in sines) for c, sines in self.terms]


class Pid:
    """Plain discrete PID on the sensed angle: V = kp e + ki sum(e T) + kd de/T, clipped."""

    def __init__(self, gains, period: float, limit: float):
        self.kp, self.ki, self.kd = gains.kp, gains.ki, gains.kd
        self.period, self.limit = period, limit
        self.integral, self.prev = 0.0, None

    def __call__(self, error: float) -> float:
        """Output [V] for ``error`` [rad]; the integral is frozen while saturated."""
        d = 0.0 if self.prev is None else (error - self.prev) / self.period
        self.prev = error
        out = self.kp * error + self.ki * (self.integral + error * self.period) + self.kd * d
        if abs(out) < self.limit:
            self.integral += error * self.period
        return max(-self.limit, min(self.limit, out))


ROW_BYTES_BASE, ROW_BYTES_PER_JOINT = 34, 8 * 16
"""A simulate row's size at most [bytes]: tick and time, then per joint eight values (true q,
qd, current, counts, sensed q, voltage, current, setpoint) of at most 16 characters with
their comma (``%.9g``)."""


def run(robot: str, duration: float, seed: int, payload, noise: bool = True, twin=None):
    """Simulate; yield (sample, setpoint) per tick. Raises GuardidError subclasses.
    ``twin``: a :class:`guardid.twin.Twin` run instead of the description's rigid body."""
    import numpy as np

    from guardid.plant import Plant, PlantError
    from guardid.robot import load_robot

    description = load_robot(robot) if isinstance(robot, str) else robot
    joints = getattr(description, "joints", None)
    if not joints or any(j.drive is None or j.pid is None for j in joints):
        raise PlantError(f"{description.name}: simulate needs a drive and PID gains per joint")
    ref = SumOfSines(description)
    if twin is not None:
        plant = Plant(twin.description, model=twin.model, substeps=twin.substeps, seed=seed,
                      noise=noise, q0=ref(0.0))  # fmt: skip
    else:
        plant = Plant(description, seed=seed, noise=noise, payload=payload, q0=ref(0.0))
    pids = [Pid(j.pid, plant.dt, j.drive.supply_voltage) for j in joints]
    volts = [0.0] * len(joints)
    for _ in range(int(round(duration / plant.dt))):
        with np.errstate(all="ignore"):  # a diverging plant is reported below, in one line
            sample = plant.step(volts)
        if not all(math.isfinite(x) for x in (*sample.q, *sample.qd)):
            raise PlantError(
                f"{description.source or description.name}: the simulation diverged at "
                f"t = {sample.time:.3f} s (joint state not finite); check the masses, "
                "inertias and drives"
            )
        setpoint = ref(sample.time)
        volts = [pid(r - q) for pid, r, q in zip(pids, setpoint, sample.q_sensed, strict=True)]
        yield description, sample, setpoint


def _columns(n: int) -> list[str]:
    names = ["tick", "time_s"]
    for sig in ("q_true", "qd_true", "current_true", "counts", "q_sensed", "v_sensed",
                "i_sensed", "setpoint"):  # fmt: skip
        names += [f"{sig}_{j + 1}" for j in range(n)]
    return names


@click.command()
@click.option("--robot", default="guard", show_default=True, help="Shipped name or YAML path.")
@click.option("--duration", type=float, default=30.0, show_default=True, help="Seconds.")
@click.option("--seed", type=int, default=0, show_default=True, help="Sensor-noise seed.")
@click.option("--payload-time", type=float, default=None, help="Attach a payload at [s].")
@click.option("--payload-mass", type=float, default=None, help="Payload mass [kg].")
@click.option("--payload-com", default="0.12,0.02,0", show_default=True,
              help="Payload centre of mass in the last link frame [m], x,y,z.")  # fmt: skip
@click.option("--no-noise", is_flag=True, help="Quantisation only, no sensor noise.")
@click.option("--params", "params_path", default=None, type=click.Path(dir_okay=False),
              help="Run the robot as identified (a twin): the base parameters and friction of "
              "a params.yaml from guardid identify (or a reference values file) instead of the "
              "robot YAML's rigid body; motors, sensors and PID gains stay the YAML's. Not with "
              "a payload.")  # fmt: skip
@click.option(
    "--method",
    default=None,
    help="With --params: the params file's method to run [default: its first].",
)
@output_option("CSV file")
@force_option("an existing OUTPUT")
def simulate(
    robot, duration, seed, payload_time, payload_mass, payload_com, no_noise, params_path,
    method, output, force,
):  # fmt: skip
    """Closed-loop PID run of the simulated robot; write true and sensed signals to CSV.

    Row k is tick k (t = k T): true q [rad], qd [rad/s] at t, true mean current [A] over
    the period ending at t, encoder counts, q_sensed [rad], sensed mean voltage [V] and
    current [A], and the setpoint [rad] the PID used at t.
    """
    from guardid.commands.outputs import check_output, check_room, replacing, robot_file
    from guardid.plant import PayloadChange

    inputs = [("--robot", robot_file(robot))] + ([("--params", params_path)] if params_path else [])
    check_output(output, inputs, force=force)
    if method is not None and params_path is None:
        raise SimulateError("--method goes with --params")
    if params_path is not None and payload_time is not None:
        raise SimulateError("--params: not with a payload (a twin's rigid body is its base "
                            "parameters; a payload changes the full ones)")  # fmt: skip
    if not (duration > 0 and math.isfinite(duration)):
        raise SimulateError(f"--duration must be > 0 s, got {duration}")
    payload = ()
    if (payload_time is None) != (payload_mass is None):
        raise SimulateError("--payload-time and --payload-mass go together")
    if payload_time is not None:
        try:
            com = tuple(float(x) for x in payload_com.split(","))
        except ValueError:
            com = ()
        if len(com) != 3:
            raise SimulateError(f"--payload-com must be x,y,z in m, got {payload_com!r}")
        if not all(math.isfinite(x) for x in (payload_time, payload_mass, *com)):
            raise SimulateError(
                f"--payload-time, --payload-mass and --payload-com must be finite, got "
                f"{payload_time}, {payload_mass}, {payload_com!r}"
            )
        if payload_mass < 0 or payload_time < 0:
            raise SimulateError("--payload-time and --payload-mass must be >= 0")
        payload = (PayloadChange(payload_time, payload_mass, com),)
    from guardid.robot import load_robot

    description = load_robot(robot)
    twin = None
    if params_path is not None:
        from guardid.twin import load_twin

        twin = load_twin(params_path, description, method, option="--params")
    if round(duration / description.sample_period) < 1:
        raise SimulateError(
            f"--duration {duration:g} s: shorter than one tick ({description.sample_period:g} s)"
        )
    n_j = len(getattr(description, "joints", ()) or ())
    check_room(
        output, duration, description.sample_period, ROW_BYTES_BASE + ROW_BYTES_PER_JOINT * n_j
    )
    head = [f"# robot: {description.name}", f"# seed: {seed}",
            f"# sample_period_s: {description.sample_period}",
            "# units: rad, rad/s, A, V; row k = tick k (t = k T), currents/voltages are means"
            " over (k-1)T..kT, setpoint = the PID's reference at tick k"]  # fmt: skip
    if twin is not None:
        head.append(f"# twin: {twin.label}")
    if payload:
        head.append(f"# payload: time_s={payload_time} mass_kg={payload_mass} com_m={payload_com}")
    wall = time.perf_counter()
    sq_err, n = None, 0
    # row by row into the output's temporary file: memory stays flat however long the run
    with replacing(output) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write("\n".join([*head, ",".join(_columns(n_j))]) + "\n")
        for _, s, sp in run(description, duration, seed, payload, noise=not no_noise, twin=twin):
            cols = [*s.q, *s.qd, *s.current_true, *s.counts, *s.q_sensed, *s.voltage, *s.current]
            fh.write(f"{s.tick},{s.time:.6f}," + ",".join(f"{x:.9g}" for x in (*cols, *sp)) + "\n")
            err = [r - q for r, q in zip(sp, s.q, strict=True)]
            sq_err = [a + e * e for a, e in zip(sq_err or [0.0] * len(err), err, strict=True)]
            n += 1
    wall = time.perf_counter() - wall
    rms = ", ".join(f"{math.sqrt(x / n):.4f}" for x in sq_err)
    click.echo(f"simulate: {description.name} {n} ticks ({duration:g} s) seed {seed} -> {output};"
               f" rms tracking error [{rms}] rad; {duration / wall:.0f}x real time")  # fmt: skip
