"""``guardid identify`` on logs captured through firmware=avr vs firmware=py, over seeds.

Run: python bench/bench_avr_identify.py [--seconds 60] [--seeds 1-15] [--mcu atmega328p]

Per seed: one tracking excitation (guardid excite --base-freq 0.2 --harmonics 3), captured
for --seconds on sim://guard?seed=S&firmware=py and ...&firmware=avr (the same plant seed,
so the same robot and the same trajectory), then identified as ``guardid identify`` does
(same arguments, the log's highest harmonic). For every base parameter whose relative std
is under 5 %: |estimate - truth| / std, truth = the robot YAML's value (the plant's). Prints
one line per seed and firmware, then the median and worst over the seeds per parameter.
The AVR path must not be worse than the Python emulator's: a bias of its own (ADC, timing
model) shows as a parameter whose error is far out only for avr.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

METHODS = ("ls", "wls")


def seeds(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def capture_log(traj: Path, seconds: float, url: str, log: Path) -> dict:
    from click.testing import CliRunner

    from guardid.cli import main as cli

    argv = ["capture", "--trajectory", str(traj), "--duration", str(seconds), "--port", url]
    res = CliRunner().invoke(cli, [*argv, "--quiet", "-o", str(log)])
    if res.exit_code != 0:
        raise SystemExit(f"capture {url} failed: {res.output}")
    return {"output": res.output.strip().splitlines()[-1] if res.output.strip() else ""}


def identify_log(log: Path):
    from guardid.commands.identify import _load_all
    from guardid.identify import IdentifyOptions, identify

    (runs, description) = _load_all(
        [str(log)],
        None,
        {"columns": (), "sample_period": None, "mat_var": None, "mat_columns": None},
    )
    return identify(runs, description, IdentifyOptions(methods=METHODS))


def main() -> None:
    from click.testing import CliRunner

    from guardid.cli import main as cli

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seeds", default="1-15")
    ap.add_argument("--mcu", default="atmega328p", choices=("atmega328p", "atmega2560"))
    args = ap.parse_args()
    z = {fw: {m: [] for m in METHODS} for fw in ("py", "avr")}
    names = None
    with tempfile.TemporaryDirectory() as tmp:
        traj = Path(tmp) / "track.yaml"
        CliRunner().invoke(cli, ["excite", "--base-freq", "0.2", "--harmonics", "3", "-o",
                                 str(traj)], catch_exceptions=False)  # fmt: skip
        for seed in seeds(args.seeds):
            for fw in ("py", "avr"):
                url = f"sim://guard?seed={seed}&firmware={fw}"
                url += f"&mcu={args.mcu}" if fw == "avr" else ""
                log = Path(tmp) / f"{fw}{seed}.csv"
                c0 = time.process_time()
                capture_log(traj, args.seconds, url, log)
                cpu = time.process_time() - c0
                ident = identify_log(log)
                names = ident.names
                for m in METHODS:
                    r = ident.results[m]
                    zz = np.where(r.rel_std_pct < 5.0, (r.theta - ident.nominal) / r.std, np.nan)
                    z[fw][m].append(zz)
                    out = [f"{n} {v:+.1f}" for n, v in zip(names, zz, strict=True) if v == v]
                    print(f"seed {seed:2d} {fw:3s} {m:3s} (capture {cpu:5.1f} s CPU) "
                          f"(estimate - truth)/std: {', '.join(out)}", flush=True)  # fmt: skip
    print("--- |estimate - truth| / std over the seeds (parameters with rel std < 5 %)")
    for fw in ("py", "avr"):
        for m in METHODS:
            a = np.abs(np.array(z[fw][m]))
            for k, n in enumerate(names):
                col = a[:, k][~np.isnan(a[:, k])]
                if col.size:
                    signed = np.array(z[fw][m])[:, k]
                    over = int((col > 3).sum())
                    print(f"{fw:3s} {m:3s} {n:10s} seeds {col.size:2d}  median "
                          f"{np.median(col):4.2f}  worst {col.max():4.2f}  mean signed "
                          f"{np.nanmean(signed):+5.2f}  over 3: {over}")  # fmt: skip


if __name__ == "__main__":
    main()
