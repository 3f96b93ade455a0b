"""The verdict's method: WLS when it ran (its std is the calibrated one), else LS, else any
method with standard deviations (issue 19, deliverable 2)."""

import numpy as np

from guardid.identify.pipeline import MethodResult
from guardid.identify.untrusted import reference_method


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


def test_the_html_table_says_which_method_it_rests_on():
    from guardid.report.html import parameter_table

    def full(method):
        r = _result(method)
        r.rel_std_pct = np.full(2, 10.0)
        r.d_tau = 0.01
        return r

    class Result:
        names = ("a", "b")
        formulas = ("a", "b")
        nominal = np.ones(2)
        results = {"ls": full("ls"), "wls": full("wls")}

    assert "use WLS, guardid's reference method" in parameter_table(Result())
    Result.results = {"ls": full("ls")}
    assert "use LS." in parameter_table(Result())
