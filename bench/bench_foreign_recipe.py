"""docs/FOREIGN_LOGS.md's DFKI recipes against ``identify``'s defaults, held out (issue 31).

    .venv/bin/python bench/bench_foreign_recipe.py

Leave one run out over the DFKI double pendulum runs 00-02 (tests/data): ``guardid identify``
on the other two with each conditioning variant (``--method ls``), then the held-out run is
scored by the neutral evaluator of tests/test_validation_neutral.py (plain numpy and scipy,
independent of guardid: its own 2 ms grid, 5 Hz zero-phase filter, central differences and
the lab's closed-form regressor; the friction shape guardid fitted), the same rows for every
variant. Score: stacked relative rms error over both joints, rms(tau - Y theta) / rms(tau).
Deterministic (measured data, no noise draw): one run gives the figures.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml
from click.testing import CliRunner

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_validation_neutral import COLUMNS, DATA, _error, _lab_theta  # noqa: E402

from guardid.cli import main  # noqa: E402

VARIANTS = {
    "defaults": [],
    "--cutoff 5": ["--cutoff", "5"],
    "--cutoff 10": ["--cutoff", "10"],
    "--cutoff 20": ["--cutoff", "20"],
    "--cutoff 5 --parallel-filter 2": ["--cutoff", "5", "--parallel-filter", "2"],
    "--cutoff 5 --parallel-filter 3": ["--cutoff", "5", "--parallel-filter", "3"],
    "--cutoff 5 --parallel-filter 4": ["--cutoff", "5", "--parallel-filter", "4"],
}
# the lab's published I1 + m2 l1^2, m1 r1 + m2 l1, m2 r2, I2 (tests/data/.../README.md)
PUBLISHED4 = np.array([0.1079, 0.3491, 0.1111, 0.02392])


def identified(train, extra, out: Path):
    logs = [str(DATA / f"trajectory_{k:02d}.csv") for k in train]
    args = ["identify", *logs, "--robot", "dfki_double_pendulum", "--columns", COLUMNS,
            "--method", "ls", *extra, "-o", str(out)]  # fmt: skip
    res = CliRunner().invoke(main, args)
    if res.exit_code != 0:
        raise SystemExit(res.output)
    p = yaml.safe_load(out.read_text())
    names = [b["name"] for b in p["base_parameters"]]
    values = dict(zip(names, p["methods"]["ls"]["values"], strict=True))
    fr = p["robot_description"]["joints"][0]["friction"]
    return _lab_theta(values), (fr.get("model", "sign"), fr.get("velocity_scale"))


def main_() -> None:
    print(
        "all three runs stacked, LS: error against the published I1 + m2 l1^2, "
        "m1 r1 + m2 l1, m2 r2, I2 [%]"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for v, (label, extra) in enumerate(VARIANTS.items()):
            theta, _ = identified([0, 1, 2], extra, Path(tmp) / f"all{v}.yaml")
            err = 100 * (theta[:4] - PUBLISHED4) / PUBLISHED4
            print(f"{label:34s} " + ", ".join(f"{e:+.1f}" for e in err))
    print("held-out run: stacked relative rms error (neutral numpy evaluator), LS on the others")
    print(f"{'variant':34s} {'00':>7s} {'01':>7s} {'02':>7s} {'mean':>7s}")
    with tempfile.TemporaryDirectory() as tmp:
        for v, (label, extra) in enumerate(VARIANTS.items()):
            errs = []
            for k in range(3):
                train = [j for j in range(3) if j != k]
                theta, friction = identified(train, extra, Path(tmp) / f"p{v}_{k}.yaml")
                errs.append(_error(k, theta, friction))
            cells = " ".join(f"{e:7.4f}" for e in errs)
            print(f"{label:34s} {cells} {np.mean(errs):7.4f}")


if __name__ == "__main__":
    main_()
