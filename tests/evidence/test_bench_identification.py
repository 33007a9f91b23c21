"""The identification part of ``skisnow bench macro`` (app/evidence/identification.py, issue
#26 Benchmark), without running an identification (minutes per ski; tests/solvers/
test_identify.py checks the identification and its starts): the section rendered from a stored
run, the report's start-and-fit fields from an identification's ``extra``, the study designs'
data (the own-ski study's), the ski job's held-out cases and the job times read from the study.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from skisnow.app.evidence import identification as ib
from skisnow.app.evidence import macro
from skisnow.app.service.identification import _starts_and_fits
from skisnow.app.storage.skis import CamberData, mean_profiles
from skisnow.app.training.data import camber_training_arrays, job_held_out

REPO = Path(__file__).resolve().parents[2]


def _row(time_s: float, **kw) -> dict:
    row = {
        "identified": True,
        "reason": "",
        "cases": 46,
        "time_s": time_s,
        "starts_wall_s": 20.4,
        "forward_wall_s": 74.6,
        "cpu_s": 170.2,
        "starts_run": 2,
        "forward_fits": 4,
        "candidates_objective_min": 2000.0,
        "candidates_objective_range": 4.0,
        "candidates_misfit_um": [3.0012, 3.0456],
        "candidates_max_dc_middle_um": 1.234,
        "candidates_max_dlog_ei_middle": 0.0456,
        "misfit_um": 3.0012,
        "noise_um": 3.01,
        "held_out_vs_measured_rms_um": 2.998,
        "held_out_vs_design_beam_rms_um": 0.0964,
        "load_avg_1min": [1.9, 2.4],
    }
    return {**row, **kw}


def test_section_renders_each_ski_and_says_whether_the_target_is_met():
    d = {
        "target_s": 120.0,
        "skis": {
            "ski-a": _row(95.2, vs_shipped_beam={"max_dc_um": 0.0, "max_dlog_ei": 0.0}),
            "skate-coarse-d0": _row(130.6, cases=46, held_out_cases=9),
        },
    }
    lines = ib.render_md(d)
    assert lines[0] == "### Beam identification (issue #26: several starts included)"
    rows = [line for line in lines if line.startswith("| ski-a") or line.startswith("| skate")]
    assert rows[0] == (
        "| ski-a | 46 | 95 (20 + 75) | 170 | 2 / 4 | 2.0e-03 | 3.001–3.046 | 1.23 / 0.046 "
        "| 3.00 / 3.01 | 3.00 | 0.096 |"
    )
    assert rows[1].startswith("| skate-coarse-d0 | 46 (9 held out) | 131 (20 + 75) |")
    # the variant start's fits, when the row has them
    with_v = ib.render_md({"skis": {"ski-a": _row(95.2, variant_fits=2)}})
    assert any(
        line.startswith("| ski-a | 46 | 95 (20 + 75) | 170 | 2 / 4 + 2 variant |")
        for line in with_v
    )
    text = "\n".join(lines)
    assert "Target: ≤ 2 min per ski on 2 cores, several starts included; not met: 1 of 2" in text
    assert "(skate-coarse-d0; the slowest 131 s)." in text  # load 2.4: not a loaded machine
    assert "load average 1.9–2.4" in text
    assert "ski-a max |Δc| 0.000 µm, max |Δ ln EI| 0.0000" in text
    # a stored comparison with another commit is kept on the regenerated page
    note = "The same run at the commit before: 491 s CPU."
    again = "\n".join(ib.render_md({**d, "comparison": note}))
    assert f"CPU: this process and its two path workers together. {note} The machine" in again
    # under load the verdict says the wall times are upper bounds
    loaded = "\n".join(ib.render_md({"skis": {"a": _row(130.0, load_avg_1min=[6.4, 6.9])}}))
    assert "(a; the slowest 130 s), measured while other jobs loaded the 2 cores" in loaded
    assert "load average 6.4–6.9): the wall times are upper bounds" in loaded
    # all within the target
    met = ib.render_md({"skis": {"ski-a": _row(95.2)}})
    assert any("; met: the slowest ski took 95 s." in line for line in met)
    # a ski that was not identified is named with its reason
    bad = ib.render_md({"skis": {"x": _row(50.0, identified=False, reason="too few cases")}})
    assert "Not identified: x (too few cases)." in bad
    assert ib.render_md({}) == []


def test_section_renders_a_run_from_before_the_several_starts():
    """docs/bench/macro.json of a run before #26 (demo skis only, no start columns) still
    renders: the columns it did not record show a dash."""
    old = {
        "ski-a": {
            "identified": True,
            "cases": 426,
            "held_out_cases": 85,
            "time_s": 73.0,
            "start_time_s": 11.0,
            "forward_time_s": 59.0,
            "noise_um": 3.01,
            "misfit_um": 3.0,
            "held_out_vs_measured_rms_um": 3.0,
            "held_out_vs_design_beam_rms_um": 0.087,
        }
    }
    rows = [line for line in macro.render_md({"skis": {}, "identification": old})]
    assert (
        "| ski-a | 426 (85 held out) | 73 (— + —) | — | — / — | — | —–— | — / — | 3.00 / 3.01 "
        "| 3.00 | 0.087 |" in rows
    )


def test_report_fields_of_the_starts_and_fits():
    """identify_report's start-and-fit fields from an identification's ``extra``: wall times,
    counts, the summed fit times, and the candidates' spread in µm."""
    extra = {
        "wall_starts_s": 12.5,
        "wall_forward_s": 40.0,
        "starts_run": 2,
        "starts": [{"start": "projection"}, {"start": "uniform"}],
        "forward_fits": 4,
        "forward_candidates": [
            {"time_s": t, "misfit_m": m}
            for t, m in zip((10.0, 20.0, 15.0, 25.0), (3.0e-6, 3.1e-6, 3.2e-6, 9e-6), strict=True)
        ],
        "alternatives": [2, 1],
        "variant_candidates": [{"time_s": 8.0, "misfit_m": 3.05e-6}],
        "variant_alternatives": [0],
        "restarted": False,
        "tried_rejected_starts": False,
        "start": "uniform",
        "variant_chosen": None,
        "main_misfit_m": 3.0e-6,
        "candidate_spread": {
            "converged": 3,
            "misfit_min_m": 3.0e-6,
            "misfit_max_m": 3.2e-6,
            "objective_min": 1800.0,
            "objective_range": 20.0,
            "max_dc_middle_m": 2e-6,
            "max_dlog_ei_middle": 0.05,
        },
    }
    f = _starts_and_fits(extra)
    assert f["starts_wall_s"] == 12.5 and f["forward_wall_s"] == 40.0
    assert f["starts_run"] == 2 and f["starts_checked"] == 2 and f["forward_fits"] == 4
    assert f["forward_fits_time_s"] == 70.0
    assert f["chosen_start"] == "uniform" and f["candidates_converged"] == 3
    assert f["candidates_misfit_um"] == pytest.approx([3.0, 3.2], rel=1e-12)
    assert f["candidates_max_dc_middle_um"] == pytest.approx(2.0, rel=1e-12)
    assert f["candidates_objective_range"] == 20.0
    # the alternative beams' misfits: the main fits' in the identification's order, then the
    # variant starts' fits
    assert f["alternative_beams_misfit_um"] == pytest.approx([3.2, 3.1, 3.05], rel=1e-12)
    assert f["variant_fits"] == 1 and f["variant_fits_time_s"] == 8.0
    assert f["variant_misfit_um"] == pytest.approx([3.05], rel=1e-12)
    assert f["variant_chosen"] is None and f["main_misfit_um"] == pytest.approx(3.0, rel=1e-12)
    # a variant fit chosen (solvers.identify.variant_choice): its index and the main misfit
    chosen = _starts_and_fits({**extra, "variant_chosen": 0, "main_misfit_m": 3.9e-6})
    assert chosen["variant_chosen"] == 0
    assert chosen["main_misfit_um"] == pytest.approx(3.9, rel=1e-12)
    # no converged candidate: the spread fields are empty, not an error
    none = _starts_and_fits({"candidate_spread": {"converged": 0}, "forward_candidates": []})
    assert none["candidates_converged"] == 0 and none["candidates_misfit_um"] == [None, None]
    assert none["alternative_beams_misfit_um"] == [] and none["variant_fits"] == 0
    assert none["variant_chosen"] is None and none["main_misfit_um"] is None


@pytest.mark.parametrize(("grid", "cases"), [("coarse", 9 * 5), ("dense", 13 * 9)])
def test_design_data_are_the_own_ski_study_data(grid, cases):
    """The bench's study designs are measured as scripts/own_ski_study.py measures draw 0 on
    each grid with the unloaded profile: the same cases and the same noise draw."""
    sys.path.insert(0, str(REPO / "scripts"))
    import own_ski_study as oss

    data, truth = ib.design_camber_data("skate", grid=grid)
    assert data.ski_id == f"skate-{grid}-d0"
    seeds = oss.seeds_of("skate", 0, grid)
    ref = oss.camber_data("x", truth, grid, seeds["measurement"], True, 1.0)
    assert data.loads_n.size == 1 + cases and data.loads_n[0] == 0.0
    np.testing.assert_array_equal(data.loads_n, ref.loads_n)
    np.testing.assert_array_equal(data.load_positions_m, ref.load_positions_m)
    np.testing.assert_array_equal(data.positions_m, ref.positions_m)
    np.testing.assert_array_equal(data.profiles_m, ref.profiles_m)
    # another seed, another draw
    other, _ = ib.design_camber_data("skate", seed=1, grid=grid)
    assert np.abs(other.profiles_m - data.profiles_m).max() > 1e-6


def test_design_data_refuse_an_unknown_grid():
    from skisnow.solvers.errors import InputError

    with pytest.raises(InputError, match="grid must be one of"):
        ib.design_camber_data("skate", grid="sparse")


def test_job_held_out_names_the_same_cases_for_both_models():
    """The ski job's held-out cases (app.training.data.job_held_out): the network's indices
    and the identification's (mean profiles, other order) name the same (F, x_F); the
    unloaded profile is never held out; 20 % of the loaded cases."""
    rng = np.random.default_rng(3)
    f = np.repeat(np.linspace(100.0, 800.0, 6), 5)
    xf = np.tile(np.linspace(-0.3, 0.1, 5), 6)
    f, xf = np.concatenate([[0.0], f]), np.concatenate([[0.0], xf])
    x = np.linspace(-0.9, 0.9, 11)
    y = rng.normal(0.0, 1e-4, (f.size, x.size))
    order = rng.permutation(f.size)
    data = CamberData("t", x, f[order], xf[order], ["mean"] * f.size, y[order])
    _, _, ft, xft, _, _ = camber_training_arrays(data)
    fm, xfm, _, _ = mean_profiles(data)
    held_t, held_m = job_held_out(data, (fm, xfm))
    assert held_t.size == held_m.size == 6
    np.testing.assert_array_equal(np.sort(ft[held_t]), np.sort(fm[held_m]))
    pairs_t = {(a, b) for a, b in zip(ft[held_t], xft[held_t], strict=True)}
    assert pairs_t == {(a, b) for a, b in zip(fm[held_m], xfm[held_m], strict=True)}
    assert np.all(fm[held_m] > 0)
    assert np.all(np.diff(held_m) > 0)
