"""``identify --plot``: the torque fit and the online estimators' convergence as a PNG."""

from __future__ import annotations

import math

import numpy as np

from guardid.errors import ConfigError
from guardid.report.series import thin


def plot(result, path, A=None, y=None, tracker=None) -> None:
    """Torque fit and online estimators' convergence, as a PNG (needs matplotlib); long
    series are drawn thinned (:func:`guardid.report.series.thin`).

    ``tracker`` (a fed :class:`guardid.online.OnlineIdentifier`, optional): its estimates over
    time replace the batch history of the methods it tracked, with its change reports marked.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise ConfigError(
            "--plot: matplotlib is not installed (pip install 'guardid[plot]')"
        ) from None
    online = [m for m in ("rls", "hopfield", "gradient") if m in result.results]
    n_rows = 1 + len(online)
    fig, axes = plt.subplots(n_rows, 1, figsize=(9, 2.8 * n_rows), squeeze=False)
    ax = axes[0, 0]
    if A is not None and y is not None:
        theta = result.results[next(iter(result.results))].theta
        row, A, y = thin(np.arange(len(y)), A, y)  # the rows drawn
        pred = np.einsum("nib,b->ni", A, theta)
        for j in range(y.shape[1]):
            ax.plot(row, y[:, j], lw=0.8, label=f"measured joint {j + 1}")
            ax.plot(row, pred[:, j], lw=0.8, ls="--", label=f"model joint {j + 1}")
        ax.set_ylabel(f"torque [{result.torque_unit}]")
        ax.set_xlabel("identification row")
        ax.legend(fontsize=7, ncol=2)
    ax.set_title("torque fit")
    for k, m in enumerate(online, start=1):
        r = result.results[m]
        ax = axes[k, 0]
        # signed, so that 1 means the description's value; parameters whose value is 0
        # are drawn as they are (in their own unit)
        scale = np.where(result.nominal != 0, result.nominal, 1.0)
        track = tracker.tracks().get(m) if tracker is not None else None
        if track is not None and set(tracker.names) <= set(result.names):
            idx = [list(result.names).index(n) for n in tracker.names]
            t, theta = thin(track.t, track.theta)
            for k, name in enumerate(tracker.names):
                ax.plot(t, theta[:, k] / scale[idx[k]], lw=0.8, label=name)
            ax.legend(fontsize=6, ncol=6)
            for rep in tracker.reports:
                if rep.method == m:
                    ax.axvline(rep.time_s, color="k", ls=":", lw=1.0)
        elif r.history is not None and r.history_t is not None:
            t, history = thin(r.history_t, r.history)
            ax.plot(t, history / scale, lw=0.8)
        ax.set_title(f"{m.upper()} estimates / YAML value (zero-valued parameters: as estimated)")
        ax.set_xlabel("time [s]")
        ax.set_ylim(-2, 3) if not math.isnan(r.d_tau) else None
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
