"""A long capture's setpoints are made as the run reaches them (``--duration 1e9`` tried to
allocate 497 GiB at once): the rows equal the all-at-once computation, and memory holds
one chunk."""

from __future__ import annotations

import numpy as np
import pytest

from guardid.capture.run import setpoint_counts, setpoint_rows
from guardid.excitation import load_trajectory
from guardid.link.session import LazyRows
from guardid.robot import load_robot


def test_lazy_setpoints_equal_the_whole_array(tmp_path):
    from badinput_tools import invoke

    traj_path = tmp_path / "t.yaml"
    assert invoke("excite", "--no-optimise", "-o", traj_path).exit_code == 0
    desc, traj = load_robot("guard"), load_trajectory(traj_path)
    n = 3 * 4096 + 17  # several chunks and a short last one
    whole = setpoint_counts(traj, desc, n)
    lazy = setpoint_rows(traj, desc, n)
    assert len(lazy) == n
    order = [0, 1, 4095, 4096, 5000, 12, n - 1, 8192, 4097, n - 18]
    for k in order:  # forth and back across chunk borders
        assert lazy[k] == whole[k].tolist(), k
        assert len(lazy._rows) <= lazy.chunk
    assert [lazy[k] for k in range(n)] == whole.tolist()


def test_lazy_rows_refuse_an_index_out_of_range():
    rows = LazyRows(10, lambda a, b: np.zeros((b - a, 2), dtype=np.int64), chunk=4)
    assert rows[9] == [0, 0]
    for k in (10, -1):
        with pytest.raises(IndexError):
            rows[k]
