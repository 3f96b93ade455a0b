"""Figures of the reproductions (matplotlib, the optional ``plot`` extra).

Seed 000: Fig. 3 / 6 squared estimation error, Figs. 4-5 alpha and gamma, Figs. 7-8 gamma,
time axis in pi seconds as in the paper. Seed 001: Fig. 6, RLS estimates over time.
"""

from __future__ import annotations

import math
from pathlib import Path

from guardid.errors import GuardidError


def require_matplotlib():
    """Return pyplot (Agg backend) or raise a one-line GuardidError."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise GuardidError(
            "--plot needs matplotlib: pip install matplotlib (or pip install 'guardid[plot]')"
        ) from None
    return plt


def _save(plt, fig, out_dir, name) -> str:
    path = Path(out_dir) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return str(path)


def seed000_step(rep, out_dir) -> list[str]:
    """Figs. 3 (squared error), 4 (alpha), 5 (gamma) and the gradient comparison."""
    from guardid.reproduce import flexsim as fs

    plt = require_matplotlib()
    s = rep.series
    tp = s["t"] / math.pi
    key = f"hop_exact_{fs.BETA:g}"
    paths = []
    fig, ax = plt.subplots(figsize=(7, 4))
    for k, lab in ((key, "exact"), (f"hop_noisy_{fs.BETA:g}", "noisy")):
        ax.plot(tp, fs.sq_error(s[k], s["theta"]), label=f"Hopfield, {lab}, beta={fs.BETA:g}")
    ax.axhline(fs.THRESHOLD, color="k", lw=0.5, ls=":")
    ax.set(xlabel="Time (pi seconds)", ylabel="||theta_tilde||^2", xlim=(0, 8))
    ax.set_title("Fig. 3: estimation error along a sudden parameter change")
    ax.legend()
    paths.append(_save(plt, fig, out_dir, "seed000_fig3_error.png"))
    for i, (fig_no, sym) in enumerate((("4", "alpha"), ("5", "gamma"))):
        j = i  # alpha is column 0, gamma column 1
        fig, ax = plt.subplots(figsize=(7, 4))
        ax.plot(tp, s["theta"][:, j], "k", label=f"Actual parameter {sym}")
        ax.plot(tp, s[key][:, j], label=f"Estimation for {sym} (exact)")
        ax.plot(
            tp, s[f"hop_noisy_{fs.BETA:g}"][:, j], lw=0.8, label=f"Estimation for {sym} (noisy)"
        )
        ax.set(xlabel="Time (pi seconds)", ylabel=f"Parameter {sym} (kg m^2)", xlim=(0, 8))
        ax.set_title(f"Fig. {fig_no}: estimation of {sym} with a sudden parameter change")
        ax.legend()
        paths.append(_save(plt, fig, out_dir, f"seed000_fig{fig_no}_{sym}.png"))
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.semilogy(tp, fs.sq_error(s[key], s["theta"]), label=f"Hopfield beta={fs.BETA:g}")
    for eta in sorted(float(k[5:]) for k in s if k.startswith("grad_")):
        h = s[f"grad_{eta:g}"]
        n = h.shape[0]
        ax.semilogy(tp[:n], fs.sq_error(h, s["theta"][:n]), lw=0.8, label=f"gradient eta={eta:g}")
    ax.set(xlabel="Time (pi seconds)", ylabel="||theta_tilde||^2", xlim=(0, 8), ylim=(1e-8, 1e3))
    ax.set_title("Hopfield vs gradient (exact measurements)")
    ax.legend()
    paths.append(_save(plt, fig, out_dir, "seed000_step_gradient.png"))
    return paths


def seed000_track(rep, out_dir, figs) -> list[str]:
    """Fig. 6 (squared error), Fig. 7 (slow gamma) or Fig. 8 (fast gamma), every beta."""
    from guardid.reproduce import flexsim as fs

    plt = require_matplotlib()
    s = rep.series
    tp = s["t"] / math.pi
    paths = []
    if "fig6" in figs:
        fig, ax = plt.subplots(figsize=(7, 4))
        for beta in s["betas"]:
            for lab in ("exact", "noisy"):
                err = fs.sq_error(s[f"hop_{lab}_{beta:g}"], s["theta"])
                ax.plot(tp, err, lw=0.8, label=f"{lab}, beta={beta:g}")
        ax.axhline(fs.THRESHOLD, color="k", lw=0.5, ls=":")
        ax.set(xlabel="Time (pi seconds)", ylabel="||theta_tilde||^2", xlim=(0, 8), ylim=(0, 0.35))
        ax.set_title("Fig. 6: estimation error for slowly varying parameters")
        ax.legend()
        paths.append(_save(plt, fig, out_dir, "seed000_fig6_error.png"))
    for name, title in (
        ("fig7", "Fig. 7: estimation of slowly varying gamma"),
        ("fig8", "Fig. 8: estimation of gamma with fast variation"),
    ):
        if name not in figs:
            continue
        fig, ax = plt.subplots(figsize=(7, 4))
        ax.plot(tp, s["theta"][:, 1], "k", label="Real value of gamma")
        for beta in s["betas"]:
            ax.plot(tp, s[f"hop_exact_{beta:g}"][:, 1], lw=0.8, label=f"Estimation, beta={beta:g}")
        ax.set(xlabel="Time (pi seconds)", ylabel="Parameter gamma (kg m^2)", xlim=(0, 8))
        ax.set_ylim(1.6, 2.15)
        ax.set_title(title + " (exact measurements)")
        ax.legend()
        paths.append(_save(plt, fig, out_dir, f"seed000_{name}_gamma.png"))
    return paths


def seed001_fig6(rep, out_dir) -> list[str]:
    """Fig. 6: RLS parameter estimates converging to the Table 1 values (plus Hopfield)."""
    plt = require_matplotlib()
    s = rep.series
    paths = []
    for key, label, fname in (
        ("rls", "RLS", "seed001_fig6_rls.png"),
        ("hop", "Hopfield", "seed001_hopfield.png"),
    ):
        fig, ax = plt.subplots(figsize=(7, 4))
        for i, name in enumerate(s["names"]):
            line = ax.plot(s[f"{key}_t"], s[key][:, i], lw=0.9, label=f"{name} estimate")[0]
            ax.axhline(s["true"][i], color=line.get_color(), ls=":", lw=0.8)
        ax.set(xlabel="Time (s)", ylabel="Parameter value (kg m^2 or kg m)", ylim=(-0.2, 2.5))
        title = "Fig. 6: " if key == "rls" else ""
        ax.set_title(f"{title}{label} parameter estimation (dotted: actual values)")
        ax.legend(ncol=3, fontsize=8)
        paths.append(_save(plt, fig, out_dir, fname))
    return paths
