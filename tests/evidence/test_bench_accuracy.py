"""Smoke test of ``skisnow bench accuracy --quick``: structure, outputs, errors that shrink."""

from __future__ import annotations

import json

import numpy as np
import pytest
from skisnow.app.evidence import accuracy_common as BA
from skisnow.app.evidence import writer
from skisnow.app.evidence.accuracy import bench_accuracy
from skisnow.app.evidence.accuracy_plots import plot_accuracy
from skisnow.app.evidence.accuracy_table import thin_table


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    docs = tmp_path_factory.mktemp("docs")
    data = bench_accuracy(BA.QUICK, progress=False)
    path = writer.write_stage("accuracy", data, plot_accuracy, docs_dir=docs)
    return docs, json.loads(path.read_text())


def test_convergence_classifier():
    c = BA.convergence([1.0, 1.5, 1.75, 1.875])  # halving differences: first order
    assert c["converges"] and c["observed_order"] == pytest.approx(1.0)
    assert BA.convergence([1.0, 2.0, 1.9, 5.0])["verdict"] == "does not converge"
    assert BA.convergence([1.0, 1.5, 1.95, 2.0])["verdict"] == "converges slowly"
    assert BA.convergence([1.0, 1.02, 0.99, 1.0])["verdict"] == "bounded"
    # Richardson: first-order sequence 2 - 2^-k extrapolates to 2
    assert BA.richardson([1.5, 1.75, 1.875], 1.0) == pytest.approx(2.0)


def test_pareto_front():
    pts = [(1.0, 0.1, "a"), (2.0, 0.2, "b"), (3.0, 0.01, "c"), (0.5, 0.5, "d")]
    assert BA.pareto_front(pts) == ["d", "a", "c"]


def test_thin_table_keeps_the_ends(small_table):
    sub = thin_table(small_table, 9)
    assert len(sub.pressure_ratio) == 9
    assert sub.pressure_ratio[0] == small_table.pressure_ratio[0]
    assert sub.pressure_ratio[-1] == small_table.pressure_ratio[-1]


def test_outputs_and_structure(run):
    docs, d = run
    assert d["stage"] == "accuracy" and "provenance" in d
    for png in ("micro", "table", "macro", "end-to-end", "network"):
        assert (docs / "bench" / f"accuracy-{png}.png").stat().st_size > 1000
    md = (docs / "benchmarks.md").read_text()
    assert "## Accuracy" in md and "converge" in md
    series = d["micro"]["series"][0]
    assert [r["n"] for r in series["rows"]] == list(BA.QUICK.micro_sizes)
    assert set(series["convergence"]) == set(BA.MICRO_METRICS)
    e2e = d["end_to_end"]
    names = {s["preset"] for s in e2e["settings"]}
    assert {"fast", "default", "fine", "reference"} <= names
    ref = next(s for s in e2e["settings"] if s["preset"] == "reference")
    assert ref["max_rel_error_converging"] == 0.0
    assert set(e2e["rule"]) == {"fast", "default", "fine"}
    ski = d["network"]["skis"][0]
    assert set(ski["max_rel_error"]) == set(BA.ANSWER_METRICS)
    assert ski["median_network_s"] > 0 and ski["median_beam_s"] > 0


def test_micro_errors_shrink_with_refinement(run):
    """a_r, the mean gap and the floored reciprocal gap converge on finer pixels."""
    rows = run[1]["micro"]["series"][0]["rows"]
    for m in ("real_contact_area_fraction", "mean_gap_m", "mean_reciprocal_gap_per_m"):
        err = [abs(r["rel_error"][m]) for r in rows]
        assert err[0] > err[1] > err[2] == 0.0, (m, err)


def test_table_errors_shrink_with_more_points(run):
    rows = run[1]["table"]["grinds"][0]["rows"]
    assert [r["points"] for r in rows] == [9, 18, 36, 72]
    grind = run[1]["table"]["grinds"][0]
    n_pixels = float(np.prod(grind["grid_shape"]))
    for m in BA.TABLE_METRICS:
        err = [r["max_rel_error"][m] for r in rows[:3]]
        # once interpolation is fine enough the error sits at the pixel-counting floor of the
        # tabulated a_r (one or two contact pixels where the largest error sits: the two-level
        # value 2 a_fine - a_coarse moves by up to 1.5 coarse pixels), not lower
        at = rows[2]["held_out_max_at"][m]["real_contact_area_fraction"]
        floor = 2.0 / (at * n_pixels) if m == "real_contact_area_fraction" else 0.0
        assert err[1] <= err[0] and err[2] <= err[1] + floor and err[2] < err[0], (m, err, floor)
    assert rows[3]["max_rel_error"]["mean_gap_m"] is None  # no direct solves in --quick


def test_default_preset_beats_fast(run):
    s = {x["preset"]: x for x in run[1]["end_to_end"]["settings"] if x["preset"]}
    assert s["default"]["max_rel_error_converging"] <= s["fast"]["max_rel_error_converging"]
