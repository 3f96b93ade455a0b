"""Why the Hopfield network could not converge, said in numbers worked out by hand
(:func:`guardid.identify.methods.hopfield_limits`) and carried into the not-converged line."""

from __future__ import annotations

import numpy as np

from guardid.identify.methods import hopfield_limits
from guardid.identify.pipeline import MethodResult
from guardid.identify.trust import mark_not_converged


def _rows(m: int) -> np.ndarray:
    """(m, 1, 2): rows e1, e2 alternating, so A^T A = diag(m/2, m/2)."""
    A = np.zeros((m, 1, 2))
    A[0::2, 0, 0] = 1.0
    A[1::2, 0, 1] = 1.0
    return A


def test_reach_in_time_constants_by_hand():
    # nominal (1, 0.5): half-widths |nominal| = (1, 0.5) (the floor, 0.1 x median, is lower);
    # S A^T A S = diag(10 x 1, 10 x 0.25) for 20 rows, smallest eigenvalue 2.5;
    # dt / beta = 0.01 / 0.1: reach 0.1 x 2.5 = 0.25 < 3
    args = (_rows(20), [1.0, 0.5], [1.0, 0.5])
    why = hopfield_limits(*args, beta=0.1, dt=0.01, passes=1, names=("a", "b"))
    assert "gets 0.25 of its time constants" in why and "box" not in why
    # twelve passes: reach 3, enough; beta 0.005: reach 5
    assert hopfield_limits(*args, beta=0.1, dt=0.01, passes=12, names=("a", "b")) == ""
    assert hopfield_limits(*args, beta=0.005, dt=0.01, passes=1, names=("a", "b")) == ""
    # beta 0.01: reach 2.5, short of 3
    assert "gets 2.5 of" in hopfield_limits(*args, beta=0.01, dt=0.01, passes=1, names="ab")


def test_least_squares_outside_the_box_is_named():
    # box of b: 2 +- 2 = [0, 4]; LS puts b at 4.5 (outside), a at 1.9 (inside [0, 2])
    why = hopfield_limits(_rows(20), [1.0, 2.0], [1.9, 4.5], 0.01, 0.01, 1, ("a", "b"))
    assert "puts b outside its box" in why and "time constants" not in why


def test_the_why_goes_into_the_not_converged_line():
    ls = MethodResult("ls", np.zeros(2), d_stacked=0.10)
    hop = MethodResult("hopfield", np.zeros(2), d_stacked=0.40,
                       settings={"why_not_converged": "WHY"})  # fmt: skip
    (line,) = mark_not_converged({"ls": ls, "hopfield": hop}, None)
    assert not hop.converged and line.startswith("HOPFIELD: not converged") and "why: WHY" in line
    hop2 = MethodResult("hopfield", np.zeros(2), d_stacked=0.40)
    (line,) = mark_not_converged({"ls": ls, "hopfield": hop2}, None)
    assert "why" not in line
