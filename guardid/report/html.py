"""One self-contained HTML page for an identification (``identify --report``) or a
validation on held-out runs (``validate --report``).

The page has no script and loads nothing: styles are inline, figures are SVG drawn by
matplotlib into the page. Every section carries an ``id`` (:data:`SECTIONS`) so that a
test, or a person with a link, can find it.
"""

from __future__ import annotations

import html
import io
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from guardid.errors import ConfigError
from guardid.report.series import thin

SECTIONS = {
    "verdict": "Verdict",
    "parameters": "Base parameters",
    "effort": "Measured and predicted effort",
    "spectrum": "Residual spectrum",
    "online": "Online estimators",
    "conditioning": "Conditioning",
    "motors": "Motors",
}
"""Section id -> heading of an identification report, in page order."""

VALIDATION_SECTIONS = {
    "verdict": "Verdict",
    "scores": "Held-out error per run",
    "effort": "Measured and predicted effort",
    "spectrum": "Residual spectrum",
}
"""Section id -> heading of a validation report, in page order."""

GOOD_REL_STD_PCT = 2.0  #: a parameter at or below this relative std is drawn green
POOR_REL_STD_PCT = 10.0  #: above this, red (the pipeline warns from the same bound)


@dataclass
class ReportInputs:
    """What a report shows beside the :class:`~guardid.identify.pipeline.Identification`.

    ``t_rows`` (M,) [s], ``A`` (M, n, b) and ``y`` (M, n): the identification rows (time,
    base regressor, effort in ``result.torque_unit``). ``joint_names`` (n,) and
    ``effort_units`` (n,) name the joints and their effort's unit (N m, or N for a
    prismatic joint). ``tracker``: a fed :class:`guardid.online.OnlineIdentifier` or None.
    ``reference``: base-parameter name -> value a person trusts (truth of a simulation, a
    lab's published values), ``reference_label`` says which. ``samples_read``: rows read
    from the logs before conditioning; ``sources``: the logs' paths; ``command``: the command
    line that made the page.
    """

    t_rows: np.ndarray
    A: np.ndarray
    y: np.ndarray
    joint_names: tuple[str, ...]
    effort_units: tuple[str, ...]
    tracker: object = None
    reference: dict[str, float] | None = None
    reference_label: str = "reference"
    samples_read: int | None = None
    sources: tuple[str, ...] = ()
    command: str = ""
    extra_notes: list[str] = field(default_factory=list)


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise ConfigError(
            "--report: matplotlib is not installed (pip install 'guardid[plot]')"
        ) from None
    return plt


def _svg(fig) -> str:
    """The figure as an inline <svg> element (no XML prologue), then closed."""
    buf = io.StringIO()
    fig.savefig(
        buf, format="svg", bbox_inches="tight",
        metadata={"Creator": None, "Date": None, "Format": None, "Type": None},
    )  # fmt: skip
    _pyplot().close(fig)
    text = buf.getvalue()
    return text[text.index("<svg") :]


def _esc(x) -> str:
    return html.escape(str(x), quote=True)


def _fmt(x: float, digits: int = 4) -> str:
    """A number for the page, never '-0' (the sign of zero says nothing to a reader)."""
    if x is None or not np.isfinite(x):
        return "n/a"
    if x == 0:
        x = 0.0
    text = f"{x:.{digits}g}"
    return "0" if text in ("-0", "0") else text


def effort_figure(t_rows, y, pred, joint_names, effort_units, title: str) -> str:
    """Measured and predicted effort per joint over time, and the residual, as SVG."""
    plt = _pyplot()
    n = y.shape[1]
    fig, axes = plt.subplots(n, 1, figsize=(9, 2.4 * n), squeeze=False, sharex=True)
    t, yy, pp = thin(np.asarray(t_rows), y, pred)
    for j in range(n):
        ax = axes[j, 0]
        ax.plot(t, yy[:, j], ".", ms=1.6, label="measured")
        ax.plot(t, pp[:, j], ".", ms=1.6, label="predicted")
        ax.plot(t, yy[:, j] - pp[:, j], ".", ms=1.2, color="0.45", label="residual")
        ax.set_ylabel(f"{joint_names[j]} [{effort_units[j]}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=3, loc="upper right", markerscale=5)
    axes[0, 0].set_title(title, fontsize=10)
    axes[-1, 0].set_xlabel("time [s] (identification rows)")
    return _svg(fig)


SPECTRUM_CELLS = 1 << 21
"""Rows x frequencies per call of scipy's Lomb-Scargle in :func:`residual_spectrum` [-]:
its temporaries stay some tens of MB whatever the rows (a 20 min log at every tick: 0.6 GB
at once)."""


def residual_spectrum(t_rows, residual, n_freq: int = 256):
    """(f [Hz] (F,), amplitude (F, n)) of the residual on possibly uneven row times.

    Lomb-Scargle (the rows are a masked, decimated subset of a uniform grid), up to the
    Nyquist frequency of the median row spacing; amplitude in the effort's unit.
    """
    from scipy.signal import lombscargle

    t = np.asarray(t_rows, dtype=float)
    r = np.asarray(residual, dtype=float)
    if len(t) < 8:
        return np.zeros(0), np.zeros((0, r.shape[1]))
    dt = float(np.median(np.diff(t)))
    span = float(t[-1] - t[0])
    f_lo = 1.0 / span if span > 0 else 0.1
    f = np.linspace(f_lo, 0.5 / dt, n_freq)
    amp = np.empty((len(f), r.shape[1]))
    block = max(1, SPECTRUM_CELLS // len(t))  # scipy forms (rows, frequencies) arrays
    for j in range(r.shape[1]):
        x = r[:, j] - r[:, j].mean()
        for a in range(0, len(f), block):
            power = lombscargle(t, x, 2 * np.pi * f[a : a + block])
            amp[a : a + block, j] = np.sqrt(4.0 * power / len(t))
    return f, amp


def spectrum_figure(t_rows, residual, joint_names, effort_units) -> str:
    plt = _pyplot()
    f, amp = residual_spectrum(t_rows, residual)
    fig, ax = plt.subplots(figsize=(9, 2.6))
    for j in range(amp.shape[1]):
        ax.semilogy(f, np.maximum(amp[:, j], 1e-12), lw=0.9, label=joint_names[j])
    ax.set_xlabel("frequency [Hz]")
    units = sorted(set(effort_units))
    ax.set_ylabel(f"residual amplitude [{', '.join(units)}]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    return _svg(fig)


def online_figure(result, tracker) -> str | None:
    """Online estimates over time relative to the description's values, or None."""
    plt = _pyplot()
    tracks = tracker.tracks() if tracker is not None else {}
    online = [m for m in ("rls", "hopfield", "gradient") if m in result.results]
    series = []
    scale = np.where(result.nominal != 0, result.nominal, 1.0)
    for m in online:
        track = tracks.get(m)
        if track is not None and set(tracker.names) <= set(result.names):
            idx = [list(result.names).index(n) for n in tracker.names]
            series.append((m, track.t, track.theta / scale[idx], tracker.names))
        elif result.results[m].history is not None and result.results[m].history_t is not None:
            r = result.results[m]
            series.append((m, r.history_t, r.history / scale, result.names))
    if not series:
        return None
    fig, axes = plt.subplots(len(series), 1, figsize=(9, 2.6 * len(series)), squeeze=False)
    axes[-1, 0].set_xlabel("time [s]")
    axes[0, 0].set_title("online estimates / the description's value (0-valued: as estimated)",
                         fontsize=9)  # fmt: skip
    for ax, (m, t, theta, names) in zip(axes[:, 0], series, strict=True):
        t, theta = thin(np.asarray(t), np.asarray(theta))
        for k, name in enumerate(names):
            ax.plot(t, theta[:, k], lw=0.8, label=name)
        if tracker is not None:
            for rep in tracker.reports:
                if rep.method == m:
                    ax.axvline(rep.time_s, color="k", ls=":", lw=1.0)
        ax.set_ylim(-1, 3)
        ax.set_ylabel(f"{m.upper()} / YAML value")
        ax.legend(fontsize=6, ncol=1, loc="center left", bbox_to_anchor=(1.0, 0.5))
        ax.grid(alpha=0.3)
    return _svg(fig)


def verdict(result) -> tuple[str, bool]:
    """(one sentence, trusted): how well the reference method (WLS, else LS, else any with
    standard deviations: :func:`~guardid.identify.untrusted.reference_method`) resolves every
    base parameter, by :func:`guardid.online.information.assess` at :data:`POOR_REL_STD_PCT`;
    first, a result identify refused (``untrusted``, written with ``--force``) says so, with
    every reason."""
    from guardid.identify.untrusted import reference_method
    from guardid.online.information import assess, describe

    untrusted = list(getattr(result, "untrusted", None) or [])
    if untrusted:
        return f"Not to be trusted (written with --force): {'; '.join(untrusted)}.", False
    name = reference_method(result.results)
    ls = None if name is None else result.results[name]
    if ls is None:
        return "No method with standard deviations ran: the uncertainty is unknown.", False
    if not (np.all(np.isfinite(ls.std)) and np.all(np.isfinite(ls.theta))):
        return "Not identified: some estimates or standard deviations are not finite.", False
    a = assess(ls.theta, ls.std, result.names, result.nominal, POOR_REL_STD_PCT)
    text = describe(a)
    return (
        f"{text[0].upper()}{text[1:]} ({ls.method.upper()}, cond(A) {_fmt(result.cond, 3)}).",
        a.all_resolved,
    )


def _bar(rel_pct: float) -> str:
    """A horizontal bar for a relative std [%], full width at 20 %."""
    if not np.isfinite(rel_pct):
        return '<span class="bar bad" style="width:100%"></span>'
    width = min(100.0, 100.0 * rel_pct / 20.0)
    cls = (
        "good" if rel_pct <= GOOD_REL_STD_PCT else "fair" if rel_pct <= POOR_REL_STD_PCT else "bad"
    )
    return f'<span class="bar {cls}" style="width:{width:.1f}%"></span>'


def _wide_table(rows) -> str:
    """A table that scrolls sideways on a narrow window instead of overflowing the page."""
    return f"<div class='wide'><table>{''.join(rows)}</table></div>"


def parameter_table(result, reference=None, reference_label="reference") -> str:
    from guardid.identify.untrusted import reference_method

    methods = list(result.results)
    base = result.results.get(reference_method(result.results)) or next(
        iter(result.results.values())
    )
    head = f"<tr><th>parameter</th><th>relative std ({_esc(base.method.upper())})</th>"
    head += "<th>description (YAML)</th>"
    if reference:
        head += f"<th>{_esc(reference_label)}</th>"
    from guardid.closedloop import STD_NOT_HONEST

    for m in methods:
        note = " (std not honest)" if m in STD_NOT_HONEST else ""
        head += f"<th>{_esc(m.upper() + note)}</th>"
    head += "<th>formula</th></tr>"
    rows = [head]
    for k, name in enumerate(result.names):
        rel = float(base.rel_std_pct[k]) if base.rel_std_pct is not None else math.nan
        cells = [
            f"<td><b>{_esc(name)}</b></td>",
            f"<td class='barcell'>{_bar(rel)} {_fmt(rel, 2)} %</td>",
            f"<td>{_fmt(result.nominal[k])}</td>",
        ]
        if reference:
            ref = reference.get(name)
            cells.append(f"<td>{_fmt(ref) if ref is not None else ''}</td>")
        for m in methods:
            r = result.results[m]
            text = _fmt(r.theta[k])
            if r.std is not None:
                text += f" &plusmn; {_fmt(r.std[k], 2)}"
                if reference and reference.get(name) is not None and r.std[k] > 0:
                    z = (r.theta[k] - reference[name]) / r.std[k]
                    text += f" <span class='z'>({_fmt(z, 2)} &sigma;)</span>"
            elif r.output_spread is not None:  # not a std: no +-, no distance in sigma
                text += f" <span class='z'>(spread {_fmt(r.output_spread[k], 2)})</span>"
            cells.append(f"<td>{text}</td>")
        cells.append(f"<td class='formula'>{_esc(result.formulas[k])}</td>")
        rows.append("<tr>" + "".join(cells) + "</tr>")
    fit = ", ".join(f"{m.upper()} {_fmt(100 * result.results[m].d_tau, 3)} %" for m in methods)
    caption = (
        f"In-sample relative effort error d_tau: {fit}. The bar is the relative standard "
        f"deviation: green up to {GOOD_REL_STD_PCT:g} %, amber up to {POOR_REL_STD_PCT:g} %, "
        "red beyond; full width is 20 %."
    )
    if base.method == "wls":
        caption += (
            " The bar and the verdict use WLS, guardid's reference method: its standard "
            "deviations matched the spread of its estimates over seeds (bench/bench_std_check.py)"
            "; LS pools one noise level over joints whose residuals differ several-fold."
        )
    elif base.std is not None:
        caption += f" The bar and the verdict use {_esc(base.method.upper())}."
    if reference:
        caption += f" (&sigma;): the estimate's distance from the {_esc(reference_label)} in std."
    if any(r.output_spread is not None for r in result.results.values()):
        caption += (
            " MLP (spread): the spread of the network's output over the rows, not an "
            "uncertainty of its estimate."
        )
    return _wide_table(rows) + f"<p class='caption'>{caption}</p>"


def conditioning_section(result, inputs: ReportInputs) -> str:
    items = [f"cut-off {_fmt(result.cutoff_hz, 3)} Hz"]
    used = int(inputs.A.shape[0])
    if inputs.samples_read:
        items.append(
            f"{used} identification rows used of {inputs.samples_read} samples read "
            f"({_fmt(100.0 * used / inputs.samples_read, 3)} %)"
        )
    else:
        items.append(f"{used} identification rows used")
    notes = list(result.notes) + list(inputs.extra_notes)
    body = "".join(f"<li>{_esc(x)}</li>" for x in items + notes)
    expl = (
        "Rows are dropped where a joint sticks or reverses (friction is then not the model's), "
        "near the ends of the run (filter edge effects), and by decimation to about the "
        "cut-off's Nyquist rate, so that the rows' noise is roughly independent and the "
        "standard deviations are honest."
    )
    return f"<ul>{body}</ul><p class='caption'>{expl}</p>"


def motors_section(result) -> str:
    if not result.motors:
        return "<p>No motor equation in this log (it needs voltages and encoder ticks).</p>"
    rows = ["<tr><th>joint</th><th>R [&Omega;]</th><th>Ke [V s/rad]</th></tr>"]
    for mo in result.motors:
        rows.append(
            f"<tr><td>{_esc(mo.joint)}</td>"
            f"<td>{_fmt(mo.resistance)} &plusmn; {_fmt(mo.resistance_std, 2)}</td>"
            f"<td>{_fmt(mo.ke, 5)} &plusmn; {_fmt(mo.ke_std, 2)}</td></tr>"
        )
    return f"<table>{''.join(rows)}</table>"


_STYLE = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:2em auto;
max-width:1100px;color:#222;line-height:1.4;padding:0 1em}
h1{font-size:1.5em;margin-bottom:.2em}h2{font-size:1.15em;border-bottom:1px solid #ddd;
padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;font-size:.85em}td,th{border:1px solid #ddd;padding:3px 7px;
text-align:right;white-space:nowrap}th{background:#f3f3f3}td.formula{text-align:left;
white-space:normal;font-family:monospace;font-size:.9em;max-width:14em}
.wide{overflow-x:auto}.barcell{min-width:9em;text-align:left}.bar{display:inline-block;height:.8em;
vertical-align:middle;margin-right:.4em;border-radius:2px;max-width:8em}
.bar.good{background:#2e9d4a}.bar.fair{background:#e0a526}.bar.bad{background:#c9362c}
.verdict{font-size:1.1em;padding:.7em 1em;border-radius:4px}
.verdict.ok{background:#e6f4ea;border-left:6px solid #2e9d4a}
.verdict.no{background:#fdecea;border-left:6px solid #c9362c}
.caption,.meta{color:#555;font-size:.85em}.z{color:#666}.warn{color:#9a5b00}
svg{max-width:100%;height:auto}
"""


def _page(title: str, inputs_meta: list[str], sections: list[tuple[str, str, str]]) -> str:
    meta = "".join(f"<div class='meta'>{_esc(m)}</div>" for m in inputs_meta if m)
    body = "".join(
        f"<section id='{sid}'><h2>{_esc(heading)}</h2>{content}</section>"
        for sid, heading, content in sections
    )
    return (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        f"<title>{_esc(title)}</title><style>{_STYLE}</style></head>"
        f"<body><h1>{_esc(title)}</h1>{meta}{body}</body></html>\n"
    )


def identification_report(result, inputs: ReportInputs, title: str | None = None) -> str:
    """The identification page (sections :data:`SECTIONS`) as an HTML string."""
    from guardid.identify.untrusted import reference_method

    base = result.results.get(reference_method(result.results)) or next(
        iter(result.results.values())
    )
    pred = np.einsum("mjb,b->mj", inputs.A, base.theta)
    sentence, trusted = verdict(result)
    warns = "".join(f"<li class='warn'>{_esc(w)}</li>" for w in result.warnings)
    verdict_html = f"<div class='verdict {'ok' if trusted else 'no'}'>{_esc(sentence)}</div>"
    if warns:
        verdict_html += f"<ul>{warns}</ul>"
    online = online_figure(result, inputs.tracker)
    if online is None:
        online = "<p>No online estimator ran (methods rls, hopfield or gradient).</p>"
    elif inputs.tracker is not None and inputs.tracker.reports:
        online = (
            "<ul>"
            + "".join(f"<li>{_esc(str(r))}</li>" for r in inputs.tracker.reports)
            + "</ul>"
            + online
        )
    units = inputs.effort_units
    content = {
        "verdict": verdict_html,
        "parameters": parameter_table(result, inputs.reference, inputs.reference_label),
        "effort": effort_figure(
            inputs.t_rows,
            inputs.y,
            pred,
            inputs.joint_names,
            units,
            f"{base.method.upper()} prediction, in-sample",
        ),  # fmt: skip
        "spectrum": spectrum_figure(inputs.t_rows, inputs.y - pred, inputs.joint_names, units),
        "online": online,
        "conditioning": conditioning_section(result, inputs),
        "motors": motors_section(result),
    }
    meta = [
        "logs: " + ", ".join(inputs.sources) if inputs.sources else "",
        f"command: {inputs.command}" if inputs.command else "",
    ]
    sections = [(sid, heading, content[sid]) for sid, heading in SECTIONS.items()]
    return _page(title or "guardid identification report", meta, sections)


@dataclass
class ValidationRun:
    """One held-out run of a validation report.

    ``t_rows`` (M,) [s] and ``y`` (M, n) the scored rows' times and measured effort;
    ``preds``: parameter-set label -> predicted effort (M, n); ``scores``: label ->
    (stacked relative rms error [-], per-joint rms error in the joint's unit (n,));
    ``passive``: names of the joints whose effort is negligible; ``rowless``: names of the
    joints none of whose rows was usable (not scored).
    """

    name: str
    t_rows: np.ndarray
    y: np.ndarray
    preds: dict[str, np.ndarray]
    scores: dict[str, tuple[float, np.ndarray]]
    passive: tuple[str, ...] = ()
    rowless: tuple[str, ...] = ()


def validation_report(
    runs: list[ValidationRun], joint_names, effort_units, command: str = "", notes=(),
    title: str | None = None, extra=(),
) -> str:  # fmt: skip
    """The validation page (sections :data:`VALIDATION_SECTIONS`, then ``extra``: (id,
    heading, HTML) sections) as an HTML string."""
    labels = list(runs[0].preds)
    mean = {k: float(np.mean([r.scores[k][0] for r in runs])) for k in labels}
    best = min(labels, key=lambda k: mean[k])
    sentence = "Held-out stacked relative rms error, mean over runs: " + ", ".join(
        f"{k} {_fmt(100 * mean[k], 3)} %" for k in labels
    )
    verdict_html = f"<div class='verdict ok'>{_esc(sentence)}; lowest: {_esc(best)}.</div>"
    if notes:
        verdict_html += "<ul>" + "".join(f"<li>{_esc(x)}</li>" for x in notes) + "</ul>"
    head = "<tr><th>run</th>" + "".join(f"<th>{_esc(k)}</th>" for k in labels) + "</tr>"
    rows = [head]
    for r in runs:
        cells = []
        for k in labels:
            rel, per_joint = r.scores[k]
            detail = ", ".join(
                f"{j} no usable row" if j in r.rowless else f"{j} {_fmt(v, 3)} {u}"
                for j, v, u in zip(joint_names, per_joint, effort_units, strict=True)
            )
            cells.append(f"<td>{_fmt(100 * rel, 3)} %<br><span class='z'>{detail}</span></td>")
        passive = f"<br><span class='z'>passive: {', '.join(r.passive)}</span>" if r.passive else ""
        rows.append(f"<tr><td>{_esc(r.name)}{passive}</td>{''.join(cells)}</tr>")
    caption = (
        "Headline: rms(effort - predicted effort) / rms(effort) over all joints' rows "
        "stacked, every parameter set under the same conditioning; per joint: rms error in "
        "the joint's unit."
    )
    scores = _wide_table(rows) + f"<p class='caption'>{caption}</p>"
    figs, specs = [], []
    for r in runs:
        pred = r.preds[best]
        figs.append(
            effort_figure(
                r.t_rows, r.y, pred, joint_names, effort_units, f"{r.name}: {best} prediction"
            )
        )
        specs.append(f"<h3>{_esc(r.name)}</h3>" + spectrum_figure(
            r.t_rows, r.y - pred, joint_names, effort_units
        ))  # fmt: skip
    content = {
        "verdict": verdict_html,
        "scores": scores,
        "effort": "".join(figs),
        "spectrum": "".join(specs),
    }
    sections = [(sid, h, content[sid]) for sid, h in VALIDATION_SECTIONS.items()]
    sections += list(extra)
    meta = [f"command: {command}" if command else ""]
    return _page(title or "guardid validation report", meta, sections)


def write_report(path, page: str, inputs_paths=()) -> Path:
    """Write ``page`` to ``path`` [an .html file]; refuses to replace one of ``inputs_paths``
    or an existing file that is not an HTML page (a log, say). Returns the path."""
    path = Path(path)
    for src in inputs_paths:
        try:
            if path.exists() and os.path.samefile(path, src):
                raise ConfigError(f"{path}: --report would overwrite its input {src}")
        except OSError:
            continue
    if path.exists():
        with open(path, "rb") as f:
            head = f.read(64).lstrip().lower()
        if not head.startswith((b"<!doctype html", b"<html")):
            raise ConfigError(f"{path}: --report: exists and is not an HTML report; not replaced")
    try:
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(page, encoding="utf-8")
        os.replace(tmp, path)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot write the report: {exc.strerror}") from None
    return path
