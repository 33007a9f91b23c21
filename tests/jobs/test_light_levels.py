"""Light-load levels (docs/tables.md, Light-load levels): the selection rule, the
recombination from the three finest levels, the pass (checkpointed, resumable, the same table
killed or not), its storage, its CLI and what the answer reports."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
import skisnow.solvers.lookup as L
from skisnow.app.jobs.table_build import build_tables
from skisnow.app.jobs.table_light_levels import light_load_pass, light_load_refinements
from skisnow.app.jobs.table_settings import BuildSettings
from skisnow.app.service.answer import pixel_error_estimate
from skisnow.app.storage.common import tables_dir
from skisnow.app.storage.tables import read_table, table_data_sha256
from skisnow.solvers.errors import InputError
from skisnow.solvers.micro import solve_micro
from skisnow.solvers.texture import GrindParameters, Texture, linear_grind

PIXEL = 1.5e-6  # [m]
SEED = 7
#: a narrow strip of the grind-1 generator; its two-level table's finest level is 2× [-]
SHAPE = (32, 256)


def _surface(k: int) -> Texture:
    with h5py.File(tables_dir() / "textures" / "grind-1.h5", "r") as f:
        params = GrindParameters(**json.loads(f.attrs["generator_parameters_json"]))
    h = linear_grind(SHAPE, PIXEL, params, SEED, refine=k)
    return Texture(h, PIXEL / k, "strip", source=f"test strip refined {k}x")


# ---------------------------------------------------------------------------- pure rules


def test_selection_takes_the_range_and_the_node_below():
    a = np.array([1e-5, 5e-5, 1e-4, 3e-4, 9e-4, 1e-3, 0.1, 1.0])
    full = np.array([False] * 7 + [True])
    np.testing.assert_array_equal(L.select_light_load_nodes(a, full), [1, 2, 3, 4])
    # the adaptive fourth level's nodes are left out; the high end is exclusive
    np.testing.assert_array_equal(L.select_light_load_nodes(a, full, exclude=[3]), [1, 2, 4])
    # the range starting at the first node: no node below
    np.testing.assert_array_equal(
        L.select_light_load_nodes(a, full, a_r_range=(1e-5, 1e-4)), [0, 1]
    )
    assert L.select_light_load_nodes(a, full, a_r_range=(0.2, 0.5)).size == 0
    with pytest.raises(InputError, match="a_r_range"):
        L.select_light_load_nodes(a, full, a_r_range=(1e-3, 1e-4))
    with pytest.raises(InputError, match="full_contact"):
        L.select_light_load_nodes(a, full[:3])


def test_refinements_halve_the_finest_pixel_down_to_the_finest_grid():
    # grind-2: 1024², finest 0.375 µm (4×) -> 8×, 16×; grind-1: finest 0.75 µm -> 4×, 8×, 16×
    assert light_load_refinements((1024, 1024), 1.5e-6, 0.375e-6, 16384) == [8, 16]
    assert light_load_refinements((1024, 1024), 1.5e-6, 0.75e-6, 16384) == [4, 8, 16]
    assert light_load_refinements((1024, 1024), 1.5e-6, 0.75e-6, 8192) == [4, 8]
    with pytest.raises(InputError, match="finest-grid"):
        light_load_refinements((1024, 1024), 1.5e-6, 0.375e-6, 4096)


def _level(a_r, gap=1.0):
    n = np.size(a_r)
    return {
        "real_contact_area_fraction": np.asarray(a_r, float),
        "mean_gap_m": np.full(n, gap),
        "mean_reciprocal_gap_per_m": np.full(n, 1.0),
        "mean_reciprocal_gap_raw_per_m": np.full(n, 1.0),
        "iterations": np.full(n, 5, np.int64),
        "residual": np.full(n, 1e-7),
        "converged": np.ones(n, bool),
        "full_contact": np.zeros(n, bool),
    }


def test_recombination_uses_the_three_finest_of_stored_and_extra_levels():
    # a first-order sequence a(Δ) = 0.01 + 0.004 Δ/Δ0 on pixels Δ0, Δ0/2 (stored), /4, /8
    coarse, fine = _level([0.014, 0.02]), _level([0.012, 0.02])
    stored = {k: np.stack([coarse[k], fine[k]]) for k in L._LEVEL_KEYS}
    extra = [_level([0.011]), _level([0.0105])]
    out, info = L.combine_with_light_load_levels(stored, [0], extra)
    assert out["real_contact_area_fraction"][0] == pytest.approx(0.01, rel=1e-12)
    assert info["three_level_estimate_real_contact_area_fraction"][0] == 1.0  # order 1 stable
    assert out["real_contact_area_fraction_error"][0] == pytest.approx(0.0, abs=1e-15)
    # one extra level on a two-level table: stored 2 + extra 1, the coarsest stored enters
    out1, _ = L.combine_with_light_load_levels(stored, [0], extra[:1])
    assert out1["real_contact_area_fraction"][0] == pytest.approx(0.01, rel=1e-12)
    with pytest.raises(InputError, match="three levels"):
        L.combine_with_light_load_levels(stored, [0], [])
    with pytest.raises(InputError, match="shape"):
        L.combine_with_light_load_levels(stored, [0], [_level([0.011, 0.0])])
    with pytest.raises(InputError, match="two or more"):
        L.combine_with_light_load_levels(None, [0], extra)


# ------------------------------------------------------------------------------ the pass


@pytest.fixture(scope="module")
def light(tmp_path_factory):
    """A two-level strip table, the pass on it, and the pass killed after its first solve and
    rerun."""
    from dask.distributed import Client, LocalCluster

    settings = BuildSettings(
        points=6, ratio_min=3e-4, ratio_max=3e-2, chunk_size=3, pixel_levels="refine"
    )
    cluster = LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    )
    with Client(cluster) as client:
        two = build_tables(
            [_surface(1)],
            tmp_path_factory.mktemp("two"),
            settings,
            client=client,
            progress=False,
            refined={"strip": _surface(2)},
        )["strip"]
    cluster.close()
    a = read_table(two).real_contact_area_fraction
    a_r_range = (float(a[2]), float(a[4]))  # nodes 2, 3 and the node below: 1
    calls, solved = [], []

    def counted(k):
        calls.append(k)
        return _surface(k)

    def kill_after_first(refine, node):
        solved.append((refine, node))
        raise KeyboardInterrupt("simulated kill")

    kw = dict(finest_grid=256 * 8, a_r_range=a_r_range, progress=False)
    whole = light_load_pass(two, tmp_path_factory.mktemp("whole"), counted, **kw)
    out = tmp_path_factory.mktemp("killed")
    with pytest.raises(KeyboardInterrupt):
        light_load_pass(two, out, counted, on_node_done=kill_after_first, **kw)
    assert not (out / "strip.h5").exists()
    resumed = light_load_pass(
        two, out, counted, on_node_done=lambda r, n: solved.append((r, n)), **kw
    )
    assert not (out / ".checkpoints").exists()
    return read_table(two), read_table(whole), read_table(resumed), calls, solved, resumed, two


def test_light_load_pass_recombines_only_the_selected_nodes(light):
    two, table, *_ = light
    nodes = table.light_load_nodes
    np.testing.assert_array_equal(nodes, [1, 2, 3])
    lv = table.levels
    np.testing.assert_allclose(lv["light_pixel_size_m"], [PIXEL / 4, PIXEL / 8], rtol=1e-14)
    assert lv["light_real_contact_area_fraction"].shape == (2, 3)
    assert lv["light_node"].dtype == np.int64
    # the stored levels and the other nodes are unchanged
    for key, value in two.levels.items():
        np.testing.assert_array_equal(lv[key], value)
    other = np.setdiff1d(np.arange(two.pressure_ratio.size), nodes)
    for q, err in L.ERROR_FIELDS.items():
        np.testing.assert_array_equal(getattr(table, q)[other], getattr(two, q)[other])
        np.testing.assert_array_equal(getattr(table, err)[other], getattr(two, err)[other])
        np.testing.assert_array_equal(lv[f"light_previous_{q}"], getattr(two, q)[nodes])
    # the nodes: the three finest levels (stored 2×, extra 4× and 8×) recombined
    levels = [{k: two.levels[k][1, nodes] for k in L._LEVEL_KEYS}] + [
        {k: lv[f"light_{k}"][j] for k in L._LEVEL_KEYS} for j in range(2)
    ]
    expect, info = L.combine_three_pixel_levels(*levels)
    for q, err in L.ERROR_FIELDS.items():
        np.testing.assert_allclose(getattr(table, q)[nodes], expect[q], rtol=1e-14)
        np.testing.assert_allclose(getattr(table, err)[nodes], expect[err], rtol=1e-14)
        np.testing.assert_array_equal(
            lv[f"light_three_level_estimate_{q}"], info[f"three_level_estimate_{q}"]
        )
    # the finest level is an independent cold solve at 1/8 of the texture's pixel
    fine = _surface(8)
    e = table.effective_modulus_pa
    res = solve_micro(
        fine.heights_m, fine.pixel_size_m, table.pressure_ratio[nodes[1]] * e, e, workers=1
    )
    assert lv["light_real_contact_area_fraction"][1, 1] == pytest.approx(
        res.real_contact_area_fraction, rel=1e-12
    )
    info = json.loads(table.attrs["light_load_levels_json"])
    assert info["input_data_sha256"] == two.attrs["data_sha256"]
    assert info["nodes"] == [1, 2, 3] and info["refine"] == [4, 8]
    assert info["device"] == "cpu"
    assert table.attrs["data_sha256"] != two.attrs["data_sha256"]
    # the answer reports the light-load levels where a cell lies next to one of their nodes
    p = table.pressure_ratio[2] * e
    answer = pixel_error_estimate(table, np.array([[p, 0.0]]), np.array([[0.1, 0.0]]), 0.0, e)
    assert answer["light_load_levels"]["pixel_size_um"] == pytest.approx(
        [PIXEL / 4 * 1e6, PIXEL / 8 * 1e6]
    )
    assert answer["light_load_levels"]["cells_near"] == 1
    assert "light_load_levels" not in pixel_error_estimate(
        two, np.array([[p]]), np.array([[0.1]]), 0.0, e
    )


def test_light_load_pass_resumes_to_the_same_table(light):
    _two, whole, resumed, calls, solved, path, _ = light
    # first run: surfaces 4, 8; killed run: 4; rerun: 4, 8 (one surface per level and run)
    assert calls == [4, 8, 4, 4, 8]
    assert solved[0] == (4, 1) and (4, 1) not in solved[1:]  # only the missing solves
    assert len(solved) == 6
    assert json.loads(resumed.attrs["light_load_levels_json"])["solves_resumed"] == 1
    assert table_data_sha256(resumed) == table_data_sha256(whole)
    assert resumed.attrs["data_sha256"] == whole.attrs["data_sha256"]
    with pytest.raises(InputError, match="already"):
        light_load_pass(path, path.parent, lambda k: None, progress=False)


def test_light_load_pass_refuses_one_level_tables_and_a_grid_too_small(tmp_path, light):
    two, *_, two_path = light
    with pytest.raises(InputError, match="finest-grid"):
        light_load_pass(two_path, tmp_path, lambda k: None, finest_grid=256, progress=False)
    with pytest.raises(InputError, match="two or more"):
        L.with_light_load_levels(
            L.MicroTable(**{**_fields(two), "levels": None}),
            [],
            [],
            pixel_sizes_m=[],
            full_contact_pressure_ratios=[],
        )


def _fields(table):
    import dataclasses

    return {f.name: getattr(table, f.name) for f in dataclasses.fields(table)}


def test_cli_light_load_levels_needs_a_table_and_runs_the_pass(tmp_path, light, capsys):
    from skisnow.app.cli import main

    *_, two_path = light
    assert main(["build-tables", "grind-1", "--out", str(tmp_path), "--light-load-levels"]) == 2
    assert "--from-table" in capsys.readouterr().err
    argv = ["build-tables", "grind-1", "--out", str(tmp_path), "--from-table", str(two_path)]
    assert main([*argv, "--light-load-levels", "--adaptive-level"]) == 2
    assert "one after the other" in capsys.readouterr().err
    # the strip's two-level table at a finest grid of 256²: no finer level fits
    assert main([*argv, "--light-load-levels", "--finest-grid", "256"]) == 2
    assert "leaves no level finer" in capsys.readouterr().err


def test_sixteen_fold_refinement_is_the_same_surface():
    """refine 16 (the 16384² level of a 1024² grind): block average within 1e-3 of the RMS of
    the unrefined map, and within 1e-3 of its RMS of the 8× map's 2×2 block average."""
    coarse, h8, h16 = _surface(1).heights_m, _surface(8).heights_m, _surface(16).heights_m
    n0, n1 = SHAPE
    avg16 = h16.reshape(n0, 16, n1, 16).mean(axis=(1, 3))
    assert np.sqrt(np.mean((avg16 - coarse) ** 2)) <= 1e-3 * coarse.std()
    avg16_to_8 = h16.reshape(n0 * 8, 2, n1 * 8, 2).mean(axis=(1, 3))
    assert np.abs(avg16_to_8 - h8).max() <= 1e-3 * coarse.std()
    with pytest.raises(InputError, match="refine"):
        _surface(32)
