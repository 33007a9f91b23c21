"""The fair peer benchmark (`skisnow bench micro --work-precision`) on a tiny grid: every
solver's errors are measured against the common reference, tightening the tolerance does not
increase them, threads are pinned in each worker, and the page renders."""

from __future__ import annotations

import math

import pytest
from skisnow.app.evidence import peers, peers_md


def test_time_at_error_interpolates_log_log_and_says_when_unreached():
    pts = [
        {"err": 1e-1, "median_time_s": 1.0, "converged": True},
        {"err": 1e-3, "median_time_s": 4.0, "converged": True},
        {"err": 1e-5, "median_time_s": 9.0, "converged": False},  # not converged: ignored
    ]
    assert peers.time_at_error(pts, "err", 1e-2) == pytest.approx(2.0, rel=1e-12)
    assert peers.time_at_error(pts, "err", 1e-3) == pytest.approx(4.0, rel=1e-12)
    assert math.isnan(peers.time_at_error(pts, "err", 1e-4))
    assert peers.time_at_error(pts, "err", 1.0) == 1.0  # reached by the loosest point


def test_work_precision_tiny(tmp_path):
    pytest.importorskip("ContactMechanics")
    data = peers.bench_work_precision(
        [64], 1, ["skisnow", "contactmechanics"], 1, 0, None, tmp_path / "work"
    )
    (block,) = data["sizes"]
    assert block["reference"]["converged"]
    assert set(block["solvers"]) == {"skisnow", "contactmechanics"}
    for name, rep in block["solvers"].items():
        pts = rep["points"]
        assert len(pts) == len(peers.TOLERANCES[name][1])
        assert all(p["converged"] for p in pts)
        # the tightest point agrees with the reference: one pixel of 64² in a_r at most,
        # the pressure field to 1e-4 (both solve the same discrete problem)
        assert (
            pts[-1]["err_contact_fraction"]
            <= 1 / (64 * 64 * block["reference"]["contact_fraction"]) + 1e-12
        )
        assert pts[-1]["err_pressure_l2"] < 1e-4
        assert pts[-1]["err_pressure_l2"] <= pts[0]["err_pressure_l2"]
        # the worker ran with the pinned thread settings and says so
        assert rep["threads"]["env"]["OMP_NUM_THREADS"] == "1"
        assert rep["versions"]
    assert not list((tmp_path / "work").glob("*.npy"))  # fields are cleaned up
    text = "\n".join(peers_md.render_md(data))
    assert "| contactmechanics | 0.01 |" in text and "### 64²" in text
    peers_md.plot_work_precision(data, tmp_path / "wp.png")
    assert (tmp_path / "wp.png").stat().st_size > 0


def test_whole_process_time_includes_the_solve():
    """A fresh pinned process (start, imports, surface, one solve, exit) takes longer than the
    solve it reports from inside."""
    w = peers.whole_process_s("skisnow", 32, 1e6, 1e-6, 1, 1)
    assert w["process_median_s"] > w["cold_solve_in_process_median_s"] > 0
