"""The verdict's method: WLS when it ran (its std is the calibrated one), else LS, else any
method with standard deviations (issue 19, deliverable 2)."""

import numpy as np

from guardid.identify.pipeline import MethodResult, reference_method


def _result(method, std=True):
    return MethodResult(method, np.ones(2), np.full(2, 0.1) if std else None)


def test_wls_is_the_reference_when_it_ran():
    results = {m: _result(m) for m in ("ls", "wls", "rls")}
    assert reference_method(results) == "wls"


def test_ls_then_any_method_with_std():
    assert reference_method({"ls": _result("ls"), "rls": _result("rls")}) == "ls"
    assert reference_method({"hopfield": _result("hopfield", std=False),
                             "rls": _result("rls")}) == "rls"  # fmt: skip
    assert reference_method({"hopfield": _result("hopfield", std=False)}) is None


def test_the_html_verdict_names_the_reference_method():
    from guardid.report.html import verdict

    class Result:
        names = ("a", "b")
        nominal = np.ones(2)
        cond = 3.0
        results = {"ls": _result("ls"), "wls": _result("wls")}

    sentence, _ = verdict(Result())
    assert "(WLS," in sentence
