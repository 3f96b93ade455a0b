"""The HTML report: its pieces against closed-form truth, and the page as a person sees it.

The page test renders ``identify --report`` in headless Chromium (Debian's ``chromium``),
reads back the DOM Chromium built and a screenshot. Without Chromium the page test skips,
except under CI (``CI=true``), where .ci/run installs it and a skip would hide a failure.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from guardid.errors import GuardidError
from guardid.report import SECTIONS, write_report
from guardid.report.html import VALIDATION_SECTIONS, residual_spectrum, verdict

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
]


def _cli(*args, cwd):
    return subprocess.run(
        [sys.executable, "-m", "guardid", *args], cwd=cwd, capture_output=True, text=True
    )


@pytest.mark.parametrize("cells", [None, 7 * 1200], ids=["one-call", "blocks-of-7"])
def test_residual_spectrum_finds_a_sinusoid_on_uneven_rows(monkeypatch, cells):
    # rows: a masked, decimated subset of a 15 ms grid, as identification leaves them;
    # "blocks-of-7": the frequencies in blocks of about 7 (scipy's arrays kept small)
    import guardid.report.html as html

    if cells is not None:
        monkeypatch.setattr(html, "SPECTRUM_CELLS", cells)
    rng = np.random.default_rng(3)
    t = np.arange(0, 60, 0.015)
    t = t[rng.random(len(t)) < 0.3]
    amp, f0 = 0.3, 1.7
    r = np.column_stack([amp * np.sin(2 * np.pi * f0 * t), 0.01 * rng.standard_normal(len(t))])
    f, a = residual_spectrum(t, r, n_freq=2000)
    k = int(np.argmax(a[:, 0]))
    assert abs(f[k] - f0) < 0.02
    assert a[k, 0] == pytest.approx(amp, rel=0.1)
    assert np.max(a[:, 1]) < 0.1 * amp  # the noise column has no such line
    from scipy.signal import lombscargle  # every frequency in one call, by hand

    x = r[:, 0] - r[:, 0].mean()
    want = np.sqrt(4.0 * lombscargle(t, x, 2 * np.pi * f) / len(t))
    np.testing.assert_allclose(a[:, 0], want, rtol=1e-9, atol=1e-12)


def _result(theta, std, nominal=(1.0, 2.0, 0.5)):
    theta, std = np.asarray(theta, float), np.asarray(std, float)
    ls = SimpleNamespace(method="ls", theta=theta, std=std)
    return SimpleNamespace(
        names=("ZZ1R", "ZZ2R", "MX2R"), results={"ls": ls}, cond=12.0,
        nominal=np.asarray(nominal, float),
    )  # fmt: skip


def test_verdict_names_the_poorly_identified_parameter():
    text, ok = verdict(_result([1.0, 2.0, 0.5], [0.01, 0.02, 0.1]))  # MX2R: 20 %
    assert not ok and "MX2R" in text and "20" in text
    text, ok = verdict(_result([1.0, 2.0, 0.5], [0.01, 0.02, 0.005]))  # all 1 %
    assert ok and "identified to 1 %" in text.lower()


def test_verdict_sets_aside_a_parameter_consistent_with_zero():
    # ZZ2R is 0.01 +- 0.02: its relative std (200 %) says nothing; against a tenth of its
    # kind's scale (the largest described inertia, 2 kg m^2) the std is 10 %: resolved
    text, ok = verdict(_result([1.0, 0.01, 0.5], [0.01, 0.02, 0.005]))
    assert ok and "consistent with zero: ZZ2R" in text


def test_verdict_flags_an_unexcited_parameter_near_zero():
    # 0.1 +- 0.5: within 3 std of zero, and the std is 250 % of a tenth of its kind's scale
    text, ok = verdict(_result([1.0, 0.1, 0.5], [0.01, 0.5, 0.005]))
    assert not ok and "ZZ2R" in text


def test_write_report_never_replaces_a_log_or_an_input(tmp_path):
    log = tmp_path / "run.csv"
    log.write_text("tick,time_s\n1,0.0\n")
    with pytest.raises(GuardidError, match="not an HTML report"):
        write_report(log, "<!DOCTYPE html><html></html>")
    assert log.read_text() == "tick,time_s\n1,0.0\n"
    page = tmp_path / "r.html"
    write_report(page, "<!DOCTYPE html><html>1</html>")
    write_report(page, "<!DOCTYPE html><html>2</html>")  # a previous report is replaced
    assert page.read_text().endswith("2</html>")
    with pytest.raises(GuardidError, match="overwrite its input"):
        write_report(page, "<!DOCTYPE html><html>3</html>", inputs_paths=[page])


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    d = tmp_path_factory.mktemp("report")
    for args in (
        ("excite", "--kind", "sines", "-o", "s.yaml"),
        ("capture", "--trajectory", "s.yaml", "--duration", "20", "--quiet", "-o", "s.csv"),
        ("identify", "s.csv", "--method", "ls,wls,rls", "--report", "r.html", "-o", "p.yaml"),
        ("validate", "s.csv", "--params", "p.yaml", "--report", "v.html"),
    ):
        done = _cli(*args, cwd=d)
        assert done.returncode == 0, done.stderr
    return d / "r.html"


def test_report_is_self_contained(report):
    page = report.read_text(encoding="utf-8")
    assert page.startswith("<!DOCTYPE html>")
    for sid in SECTIONS:
        assert f"id='{sid}'" in page
    # nothing to fetch: no scripts, no linked styles, every reference inside the page
    for needle in ("<script", "<link", "@import", "url(http", " src="):
        assert needle not in page
    refs = re.findall(r'href="([^"]*)"', page)
    assert refs and all(r.startswith("#") for r in refs)


def _chromium(*args, tmp):
    if CHROMIUM is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is not installed; .ci/run installs it (apt-get install chromium)")
        pytest.skip("chromium not installed (apt-get install chromium)")
    profile = tempfile.mkdtemp(dir=tmp)
    return subprocess.run(
        [CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_report_renders_in_chromium_with_every_section(report, tmp_path):
    url = report.resolve().as_uri()
    done = _chromium("--enable-logging=stderr", "--v=0", "--dump-dom", url, tmp=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    dom = done.stdout
    for sid, heading in SECTIONS.items():
        assert f'id="{sid}"' in dom, sid
        assert heading in dom
    assert dom.count("<svg") >= 3  # effort, spectrum, online estimators
    assert "Uncaught" not in done.stderr and "CONSOLE" not in done.stderr
    shot = tmp_path / "shot.png"
    done = _chromium("--window-size=1100,1400", f"--screenshot={shot}", url, tmp=tmp_path)
    assert done.returncode == 0 and shot.exists(), done.stderr[-2000:]
    from matplotlib.image import imread

    pixels = imread(shot)
    assert pixels.shape[:2] == (1400, 1100)
    # a page with a table and figures: many distinct colours, not a blank or an error page
    flat = (pixels[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
    assert len(np.unique(flat, axis=0)) > 50


def test_docs_screenshot_is_in_the_docs_the_readme_links():
    root = Path(__file__).resolve().parents[1]
    assert (root / "docs" / "report.png").exists()
    assert "](report.png)" in (root / "docs" / "IDENTIFY.md").read_text(encoding="utf-8")
    assert "docs/IDENTIFY.md#the-report" in (root / "README.md").read_text(encoding="utf-8")


def test_validation_report_renders_with_every_section(report, tmp_path):
    url = (report.parent / "v.html").resolve().as_uri()
    done = _chromium("--dump-dom", url, tmp=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    for sid, heading in VALIDATION_SECTIONS.items():
        assert f'id="{sid}"' in done.stdout, sid
        assert heading in done.stdout
    assert done.stdout.count("<svg") >= 2  # effort and spectrum of the one run
    assert "p.yaml:LS" in done.stdout and "p.yaml:WLS" in done.stdout
