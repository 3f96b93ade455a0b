"""The ``validate --simulate --report`` section: measured and simulated joint angles."""

from __future__ import annotations

import numpy as np

from guardid.report.html import _esc, _fmt, _pyplot, _svg, _wide_table
from guardid.report.series import thin

SECTION = ("simulation", "Measured and simulated angles")
"""(id, heading) of the section."""


def angles_figure(t, q_meas, sims, joint_names, title: str) -> str:
    """Per joint: the measured and each set's simulated angle [deg] over time ``t`` [s],
    and below it each set's simulated minus measured angle [deg], as SVG."""
    plt = _pyplot()
    n = q_meas.shape[1]
    fig, axes = plt.subplots(2 * n, 1, figsize=(9, 2.0 * 2 * n), squeeze=False, sharex=True)
    labels = list(sims)
    tt, qq, *ss = thin(np.asarray(t), np.degrees(q_meas), *(np.degrees(sims[k]) for k in labels))
    for j in range(n):
        top, low = axes[2 * j, 0], axes[2 * j + 1, 0]
        top.plot(tt, qq[:, j], lw=1.6, color="k", label="measured")
        for k, s in zip(labels, ss, strict=True):
            top.plot(tt, s[:, j], lw=0.8, label=k)
            low.plot(tt, s[:, j] - qq[:, j], lw=0.8, label=k)
        top.set_ylabel(f"{joint_names[j]} [deg]")
        low.set_ylabel(f"{joint_names[j]} sim - meas [deg]", fontsize=7)
        for ax in (top, low):
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=3, loc="upper right")
    axes[0, 0].set_title(title, fontsize=10)
    axes[-1, 0].set_xlabel("time [s]")
    return _svg(fig)


def simulation_section(runs, names, replayed, joint_names) -> tuple[str, str, str]:
    """(id, heading, HTML): the replay scores per run and set, and the angles figure per
    run; ``replayed``: (run name, label) -> simulated angles (N, n) [rad], and ``scores``
    (:class:`guardid.replay.ReplayScore` list)."""
    scores = replayed["scores"]
    labels = list(dict.fromkeys(s.label for s in scores))
    rows = ["<tr><th>run</th>" + "".join(f"<th>{_esc(k)}</th>" for k in labels) + "</tr>"]
    figs = []
    for run, name in zip(runs, names, strict=True):
        cells = []
        for k in labels:
            s = next(x for x in scores if x.run == name and x.label == k)
            if s.failed:
                cells.append(f"<td>not simulable: {_esc(s.failed)}</td>")
                continue
            detail = "<br>".join(
                f"{j}: rms {_fmt(r, 3)} / max {_fmt(m, 3)} counts"
                for j, r, m in zip(joint_names, s.rms_counts, s.max_counts, strict=True)
            )
            cells.append(f"<td><span class='z'>{detail}</span></td>")
        rows.append(f"<tr><td>{_esc(name)}</td>{''.join(cells)}</tr>")
        sims = {k: replayed[(name, k)] for k in labels if (name, k) in replayed}
        if sims:
            figs.append(angles_figure(run.t, run.q, sims, joint_names, f"{name}: replayed"))
    caption = ("Each set replayed in closed loop with the log's setpoints from its first state; "
               "error = simulated minus measured joint angle, in encoder counts.")  # fmt: skip
    body = _wide_table(rows) + f"<p class='caption'>{_esc(caption)}</p>" + "".join(figs)
    return (*SECTION, body)
