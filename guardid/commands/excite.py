"""``guardid excite``: write an excitation trajectory YAML for a robot and report its figures.

Prints the condition number of the base regressor over one period (optimised and the
starting guess's for a Fourier series), each joint's use of its limits on a 1 ms grid, the
share of time each joint is slow (the stiction rows identification will drop) and whether
the trajectory starts at rest.
"""

from __future__ import annotations

import math
import time

import click
import numpy as np

from guardid.commands._status import Status
from guardid.commands._types import POSITIVE
from guardid.commands.outputs import force_option, output_option
from guardid.conditioning.bandwidth import MAX_NYQUIST_FRACTION
from guardid.excitation import (
    ExcitationError,
    JointLimits,
    limit_usage,
    optimise_fourier,
    regressor_cond,
)
from guardid.excitation.limits import SLOW_FRACTION, fixed
from guardid.excitation.presets import (
    highest_frequency,
    robot_schroeder,
    robot_sines,
    seeded_fourier,
)

SAMPLES = 300  # cond grid: samples per period


@click.command("excite")
@click.option("--robot", default="guard", show_default=True, help="shipped robot name or YAML path")
@click.option(
    "--kind",
    type=click.Choice(["fourier", "schroeder", "sines"]),
    default="fourier",
    show_default=True,
    help="trajectory kind (only fourier is optimised)",
)
@click.option(
    "--harmonics",
    type=click.IntRange(min=1),
    default=5,
    show_default=True,
    help="harmonics H per joint",
)
@click.option(
    "--base-freq",
    type=POSITIVE,
    default=0.1,
    show_default=True,
    help="base frequency f [Hz]; the period is 1/f",
)
@click.option("--seed", type=int, default=0, show_default=True, help="random seed")
@click.option(
    "--starts",
    type=click.IntRange(min=1),
    default=4,
    show_default=True,
    help="seeded starting guesses to optimise from",
)
@click.option(
    "--margin",
    type=click.FloatRange(0, 0.5),
    default=0.05,
    show_default=True,
    help="safety margin on the limits (fraction)",
)
@click.option(
    "--start",
    "start_deg",
    default=None,
    help="start pose, comma-separated degrees per joint (default all 0)",
)
@click.option("--no-optimise", is_flag=True, help="write the starting guess as it is")
@click.option(
    "-v",
    "--verbose",
    is_flag=True,
    help="print every optimiser iteration to stderr (on a terminal a live line shows it anyway)",
)
@output_option("Trajectory YAML")
@force_option("an existing OUTPUT")
def excite(
    robot, kind, harmonics, base_freq, seed, starts, margin, start_deg, no_optimise, verbose,
    output, force,
):  # fmt: skip
    """Write an excitation trajectory YAML; print its condition number and limit use.

    Fourier series per joint optimised for cond of the base regressor under the joint limits
    (seed 001 eqs 34-38), or a Schroeder multisine / sum of sines scaled onto the limits.
    """
    from guardid.commands.outputs import check_output, replacing, robot_file
    from guardid.dynamics import build_model
    from guardid.robot import ChainDescription, load_robot

    t0 = time.perf_counter()
    check_output(output, [("--robot", robot_file(robot))], force=force)
    desc = load_robot(robot)
    if not isinstance(desc, ChainDescription):
        raise ExcitationError(f"{robot}: excite needs a serial-chain robot description")
    _check_band(kind, harmonics, base_freq, desc)
    model = build_model(desc)
    start = _start_pose(start_deg, desc)
    JointLimits.of(desc, margin).check_pose(start)
    status = Status()
    progress = (lambda line: click.echo(line, err=True)) if verbose else status.show

    note = ""
    if kind == "fourier":
        if harmonics < 2:
            raise ExcitationError("--harmonics: a Fourier series at rest needs at least 2")
        if no_optimise:
            traj = seeded_fourier(model, desc, harmonics, base_freq, start, seed, margin)
            cond = regressor_cond(model, traj, SAMPLES)
            note = "starting guess, not optimised"
        else:
            res = optimise_fourier(
                model,
                desc,
                harmonics,
                base_freq,
                start,
                seed,
                starts,
                SAMPLES,
                margin,
                progress=progress,
            )
            status.clear()
            traj, cond = res.trajectory, res.cond
            guesses = ", ".join(f"{c:.0f}" for c in res.guess_conds)
            note = (
                f"optimised; starting guess {res.start_cond:.1f}; "
                f"{res.starts} seeded guesses {guesses}; {res.iterations} SLSQP iterations"
            )
    else:
        make = robot_schroeder if kind == "schroeder" else robot_sines
        traj = make(desc, harmonics, base_freq, start, margin)
        cond = regressor_cond(model, traj, SAMPLES)
        note = "scaled onto the limits; only fourier trajectories are optimised"

    usage = limit_usage(traj, desc)
    slow = [SLOW_FRACTION * j.limits.velocity for j in desc.joints]
    cond_fast = regressor_cond(model, traj, SAMPLES, slow_limits=slow)
    info = {
        "robot": desc.name,
        "created_by": "guardid excite",
        "seed": seed,
        "margin": margin,
        "cond": cond,
        "cond_samples": SAMPLES,
    }
    with replacing(output) as tmp:
        traj.save(tmp, info=info)

    echo = click.echo
    echo(
        f"{kind} excitation for {desc.name}: {harmonics} harmonics, base frequency "
        f"{base_freq:g} Hz (period {traj.period:.2f} s), seed {seed}, margin "
        f"{100 * margin:g} %"
    )
    echo(f"condition number: {cond:.1f} ({note})")
    echo(
        f"  base regressor: {len(model.base.names)} base parameters, {SAMPLES} samples per "
        "period, Coulomb columns Fc*sign(qd) included"
    )
    for u in usage:
        echo(u.describe())
    shares = ", ".join(f"{u.name} {100 * u.slow_fraction:.1f} %" for u in usage)
    echo(
        f"slow time (|qd| < {100 * SLOW_FRACTION:g} % of the velocity limit): {shares}; "
        f"cond without those rows {cond_fast:.1f}"
    )
    echo(_rest_line(traj))
    if not all(u.within for u in usage):
        echo("WARNING: a limit is exceeded (see above)")
    echo(f"wrote {output} ({time.perf_counter() - t0:.1f} s)")


def _check_band(kind, harmonics, base_freq, desc) -> None:
    """Refuse a trajectory whose highest frequency [Hz] the robot's sampling cannot carry:
    it must stay below the largest low-pass cut-off identification can use, 0.4 x the
    Nyquist frequency of the description's sample period (guardid.conditioning.bandwidth),
    and the highest harmonic's order below the Nyquist order of the SAMPLES-per-period grid
    on which the condition number is computed."""
    top = highest_frequency(kind, len(desc.joints), harmonics, base_freq)
    per_period = round(top / base_freq)  # the highest harmonic's order
    if 2 * per_period >= SAMPLES:
        raise ExcitationError(
            f"--harmonics {harmonics}: harmonic order {per_period} needs more than the "
            f"{SAMPLES} samples per period of the condition-number grid (at most "
            f"{(SAMPLES - 1) // 2})"
        )
    limit = MAX_NYQUIST_FRACTION * 0.5 / desc.sample_period
    if top > limit:
        raise ExcitationError(
            f"--base-freq {base_freq:g} Hz with --harmonics {harmonics}: highest frequency "
            f"{top:g} Hz, above {limit:.3g} Hz (0.4 x the Nyquist frequency of {desc.name}'s "
            f"{desc.sample_period:g} s sample period)"
        )


def _start_pose(text, desc) -> np.ndarray:
    n = len(desc.joints)
    if text is None:
        return np.zeros(n)
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        raise ExcitationError(f"--start: expected {n} comma-separated numbers [deg]") from None
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise ExcitationError(f"--start: expected {n} comma-separated numbers [deg]")
    return np.radians(values)


def _rest_line(traj) -> str:
    q, qd, qdd = (x[0] for x in traj.states(0.0))
    pose = ", ".join(map(fixed, np.degrees(q)))
    if np.allclose(qd, 0.0, atol=1e-12) and np.allclose(qdd, 0.0, atol=1e-12):
        return f"starts and ends (after each whole period) at rest at ({pose}) deg"
    vel = ", ".join(map(fixed, np.degrees(qd)))
    return f"not at rest at t = 0: q = ({pose}) deg, qd = ({vel}) deg/s; ramp in before playing"
