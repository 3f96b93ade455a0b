"""Glue between the commands and the pages: builds :class:`ReportInputs` from a run."""

from __future__ import annotations

import shlex
import sys

from guardid.report.html import (
    ReportInputs,
    ValidationRun,
    identification_report,
    validation_report,
)


def effort_units(description, torque_unit: str) -> tuple[str, ...]:
    """Each joint's effort unit: N m (revolute), N (prismatic), or A in current units."""
    if torque_unit != "N m":
        return tuple("A" for _ in description.joints)
    return tuple("N" if j.type == "prismatic" else "N m" for j in description.joints)


def command_line() -> str:
    """The command as typed, for the page's header."""
    return "guardid " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def identify_page(result, description, runs, logs, cond, A, y, tracker) -> str:
    """The ``identify --report`` page for ``result`` on ``runs`` (conditioned as ``cond``)."""
    inputs = ReportInputs(
        t_rows=cond.t[cond.mask],
        A=A,
        y=y,
        joint_names=tuple(j.name for j in description.joints),
        effort_units=effort_units(description, result.torque_unit),
        tracker=tracker,
        samples_read=int(sum(len(r.t) for r in runs)),
        sources=tuple(str(x) for x in logs),
        command=command_line(),
    )
    return identification_report(result, inputs, title=f"guardid: {description.name} identified")


def validate_page(description, names, sets, keep, current_units: bool, loaded=(),
                  replayed=None) -> str:  # fmt: skip
    """The ``validate --report`` page from what :func:`guardid.identify.validation.
    validate_runs` kept (its ``keep`` dict); with ``replayed`` (``validate --simulate``:
    (run, label) -> simulated angles, and ``scores``) of the runs ``loaded``, the measured
    and simulated angles too."""
    from guardid.identify.validation import joint_units

    joints = [j.name for j in description.joints]
    runs = []
    names = keep.get("names", names)  # a run split at a long gap: its segments
    for cond, name in zip(keep["conds"], names, strict=True):
        name = str(name)
        mine = {s.label: s for s in keep["scores"] if s.run == name}
        m = cond.mask
        first = next(iter(mine.values()))
        passive = tuple(j for j, p in zip(joints, first.passive, strict=True) if p)
        flags = first.rowless if first.rowless is not None else [False] * len(joints)
        rowless = tuple(j for j, r in zip(joints, flags, strict=True) if r)
        runs.append(
            ValidationRun(
                name=name,
                t_rows=cond.t[m],
                y=cond.tau[m],
                preds={s.label: keep["preds"][(name, s.label)] for s in sets},
                scores={k: (v.stacked, v.rms) for k, v in mine.items()},
                passive=passive,
                rowless=rowless,
            )  # fmt: skip
        )
    units = joint_units(description, current_units)
    extra = ()
    if replayed is not None:
        from guardid.report.replay import simulation_section

        extra = (simulation_section(loaded, [str(x) for x in names], replayed, joints),)
    return validation_report(
        runs, joints, units, command=command_line(), notes=[keep["head"]],
        title=f"guardid: {description.name} validated", extra=extra,
    )  # fmt: skip
