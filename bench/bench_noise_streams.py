"""Are the Monte Carlo seeds' noise streams independent, or shifted copies? (issue 27)

Per seed, the plant that ``sim://guard?seed=N&start=50&supply=0.02&ripple=0.01`` builds
(:func:`guardid.plant.make_plant`, the Monte Carlo's port options): its sensor-noise
generator's first 4 x TICKS standard normal draws (four a tick: voltage and current of each
joint) and its supply factors. In numpy: whether any value recurs between seeds (a shifted
copy shares its values), the largest cross-correlation over every lag of the current-noise
draws of pairs of seeds against pairs of numpy's independent draws, and the lag-0
correlations over all pairs (sd x sqrt(n) is 1 for independent streams).

    python bench/bench_noise_streams.py [--seeds 7000-7039,5000-5039] [--ticks 80000]
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np

from guardid.fakeport.options import parse_sim_url
from guardid.plant import make_plant
from guardid.robot import load_robot

OPTIONS = "start=50&supply=0.02&ripple=0.01"


def streams(seed: int, ticks: int):
    """(sensor noise draws (4 ticks,), supply factors (ticks,)) of the seed's plant."""
    url = f"sim://guard?seed={seed}&{OPTIONS}"
    plant = make_plant(load_robot("guard"), parse_sim_url(url))
    gauss = plant._rng.gauss  # the generator the plant draws its sensor noise from
    noise = np.array([gauss(0.0, 1.0) for _ in range(4 * ticks)])
    supply = np.fromiter(itertools.islice(plant._supply, ticks), float, ticks)
    return noise, supply


def max_xcorr(a: np.ndarray, b: np.ndarray) -> float:
    """Largest |cross-correlation| over all lags x sqrt(n) (about 4-5 for independent n=8e4)."""
    a, b = a - a.mean(), b - b.mean()
    n = a.size
    c = np.fft.irfft(np.fft.rfft(a, 2 * n) * np.conj(np.fft.rfft(b, 2 * n)), 2 * n)
    return float(np.abs(c).max() / (a.std() * b.std() * n) * np.sqrt(n))


def seed_list(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi or lo) + 1))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="7000-7039,5000-5039")
    ap.add_argument("--ticks", type=int, default=80000, help="80000: a 1200 s capture")
    a = ap.parse_args()
    seeds = seed_list(a.seeds)
    data = {s: streams(s, a.ticks) for s in seeds}
    for k, label in ((0, "sensor noise"), (1, "supply factor")):
        values = np.concatenate([data[s][k] for s in seeds])
        print(
            f"{label}: {values.size} values over {len(seeds)} seeds, "
            f"{values.size - np.unique(values).size} recur"
        )
    current = {s: data[s][0][1::4] for s in seeds}  # the pan current's draws
    rng = np.random.default_rng(1)
    pairs = list(zip(seeds[0::2], seeds[1::2], strict=False))
    got = [max_xcorr(current[x], current[y]) for x, y in pairs]
    ref = [max_xcorr(rng.standard_normal(a.ticks), rng.standard_normal(a.ticks)) for _ in pairs]
    print(
        f"max over lags |xcorr| x sqrt(n), {len(pairs)} pairs of seeds: median {np.median(got):.2f}"
        f", worst {max(got):.2f}; numpy's independent draws: median {np.median(ref):.2f}, "
        f"worst {max(ref):.2f}"
    )
    c = np.corrcoef(np.array([current[s] for s in seeds]))
    off = c[np.triu_indices(len(seeds), 1)] * np.sqrt(a.ticks)
    print(
        f"lag-0 correlation x sqrt(n) over {off.size} pairs: sd {off.std():.3f} (1 if "
        f"independent), worst |.| {np.abs(off).max():.2f}"
    )


if __name__ == "__main__":
    main()
