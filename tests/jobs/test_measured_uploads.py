"""Measured grinds through the REST API (issue #30): a large map with a few unmeasured points
accepted with no options and solved, the reduction recorded, the plane removed whatever
``periodic`` is, and the grind list showing the Sq of the upload's answer."""

from __future__ import annotations

import io

import numpy as np
import pytest
import x3pio
from skisnow.solvers.measured import iso25178_measured
from skisnow.solvers.texture import self_affine_surface
from test_uploads import CONTACT, is_problem, make_client, npy_bytes, post_grind, wait_job

#: the ski base of issue #30: an Alicona InfiniteFocus map, 1197 × 940 points at 3.68 µm, 0.4 %
#: unmeasured (here a synthetic map of that size, written as x3p)
SHAPE = (1197, 940)
DX_M = 3.68e-6


def ski_base_x3p() -> tuple[bytes, np.ndarray]:
    rng = np.random.default_rng(30)
    h = self_affine_surface(SHAPE, DX_M, hurst=0.8, rms_height_m=3e-6, rng=rng)
    i, j = np.indices(SHAPE)
    h = h + 2e-4 * i * DX_M - 1e-4 * j * DX_M  # the sample's tilt
    h[rng.random(SHAPE) < 0.004] = np.nan  # 0.4 % unmeasured, scattered
    buf = io.BytesIO()
    x3pio.write(buf, h.T, x_scale=DX_M, y_scale=DX_M)  # x3pio takes (y, x)
    return buf.getvalue(), h


def test_large_ski_base_map_with_unmeasured_points_is_accepted_and_solved(catalogue, tmp_path):
    data, h = ski_base_x3p()
    # the service's own limits (1 M solve points, 4096² map) scaled down 16× per side so the
    # table builds in seconds: the map is over the solve limit, as the real one is by default
    fast = {"max_upload_bytes": 80 * 1024 * 1024, "max_solve_grid_points": 4 * 64 * 64}
    with make_client(catalogue, tmp_path, table_points=4, **fast) as client:
        r = client.post(
            "/v1/grinds",
            files={"file": ("ski-base.x3p", data, "application/octet-stream")},
            data={"name": "ski-base"},
        )
        assert r.status_code == 202, r.text[:800]
        body = r.json()
        prep = body["preparation"]
        measured = prep["measured"]
        assert measured["unmeasured_points"] == int(np.isnan(h).sum())
        assert 0 < measured["filled_points"] <= measured["unmeasured_points"]
        assert abs(measured["sq_change_percent"]) < 1.0
        red = prep["reduction"]
        assert red["method"] == "block" and red["original_grid"][0] >= SHAPE[0] - 2
        assert 4 * red["grid"][0] * red["grid"][1] <= 4 * 64 * 64
        assert red["pixel_size_um"] == pytest.approx(DX_M * 1e6 * red["block_factor"])
        # ISO 25178 of the measured points, the plane removed (not the tilt's Sq)
        i, j = np.indices(SHAPE)
        ok = np.isfinite(h)
        a = np.column_stack([np.ones(ok.sum()), i[ok], j[ok]])
        coef, *_ = np.linalg.lstsq(a, h[ok], rcond=None)
        levelled = np.where(ok, h - (coef[0] + coef[1] * i + coef[2] * j), np.nan)
        assert body["iso25178"]["Sq_m"] == pytest.approx(np.nanstd(levelled), rel=1e-6)
        assert body["iso25178"]["Sq_m"] < 5e-6
        job = wait_job(client, body["job"], timeout_s=600)
        assert job["state"] == "done", job
        shown = client.get("/v1/grinds/ski-base").json()["metadata"]
        assert shown["reduce"] == "block" and shown["detrend"] == "plane"
        assert shown["preparation"]["reduction"]["block_factor"] == red["block_factor"]
        listed = {g["name"]: g for g in client.get("/v1/grinds").json()["grinds"]}
        assert listed["ski-base"]["iso25178"]["Sq_m"] == body["iso25178"]["Sq_m"]
        r = client.post("/v1/contact", json={"ski": "ski-a", "grind": "ski-base", **CONTACT})
        assert r.status_code == 200, r.text[:500]
        assert all(np.isfinite(v) and v > 0 for v in r.json()["metrics"].values())


def test_reduce_none_is_refused_with_hints_that_keep_the_plane(catalogue, tmp_path):
    big = np.random.default_rng(1).normal(size=(80, 80))
    with make_client(catalogue, tmp_path, max_solve_grid_points=4 * 32 * 32) as client:
        r = post_grind(client, name="big", content=npy_bytes(big), reduce="none")
        detail = is_problem(r, 422)["detail"]
        assert "reduce=block" in detail and "reduce=crop" in detail
        assert "periodic=none" not in detail and "plane is still removed" in detail
        r = post_grind(client, name="big", content=npy_bytes(big), reduce="crop")
        assert r.status_code == 202, r.text[:300]
        assert r.json()["preparation"]["reduction"]["grid"] == [32, 32]


def test_periodic_choices_keep_the_plane_and_the_list_shows_the_answers_sq(catalogue, tmp_path):
    n = 64
    i, j = np.indices((n, n))
    rng = np.random.default_rng(5)
    rough = self_affine_surface((n, n), 1e-6, hurst=0.8, rms_height_m=1e-6, rng=rng)
    tilted_um = (rough + 2e-7 * i - 3e-7 * j) * 1e6  # a tilt of Sq ≈ 6.7 µm
    with make_client(catalogue, tmp_path, table_points=4) as client:
        sq = {}
        for periodic in ("none", "window"):
            r = post_grind(
                client, name=f"p-{periodic}", content=npy_bytes(tilted_um), periodic=periodic
            )
            assert r.status_code == 202, r.text[:300]
            sq[periodic] = r.json()["iso25178"]["Sq_m"]
            meta = client.get(f"/v1/grinds/p-{periodic}").json()["metadata"]
            assert meta["detrend"] == "plane"  # periodic=none no longer switches to mean
            assert wait_job(client, r.json()["job"])["state"] == "done"
        with_tilt = iso25178_measured(tilted_um * 1e-6, 1e-6)  # the mean only removed
        assert sq["none"] == pytest.approx(sq["window"], rel=1e-12)
        assert sq["none"] < 0.25 * with_tilt["Sq_m"]
        listed = {g["name"]: g for g in client.get("/v1/grinds").json()["grinds"]}
        for periodic in ("none", "window"):
            assert listed[f"p-{periodic}"]["iso25178"]["Sq_m"] == sq[periodic]


def test_the_shipped_ski_base_is_a_measured_grind_that_solves(tmp_path):
    """The third shipped grind (tables/LICENSES.md): a measured Alicona map of a ski base, with
    its provenance in the table, the ISO parameters of its measured points, and a contact."""
    from pathlib import Path

    from fastapi.testclient import TestClient
    from skisnow.app import service
    from skisnow.app.main import create_app
    from skisnow.app.settings import Settings
    from skisnow.app.storage.textures import read_texture

    tables = Path(__file__).resolve().parents[2] / "tables"
    cat = service.load_catalogue(tables)
    table = cat.grinds["ski-base"].table
    assert table.attrs["texture_provenance"].startswith("measured: ski base, Alicona")
    assert table.iso_parameters["Sq_m"] == pytest.approx(18.155e-6, rel=1e-3)  # measured points
    assert table.converged.all()
    tex = read_texture(tables / "textures" / "ski-base.h5")
    assert tex.shape == (398, 312) and tex.pixel_size_m == pytest.approx(11.04e-6, rel=1e-3)
    assert "SkiInfiniteFocus.x3p" in tex.source and "LGPL" in tex.source
    settings = Settings(data_dir=tmp_path, warm_up=False, job_workers=0)
    with TestClient(create_app(settings, catalogue=cat)) as client:
        listed = {g["name"]: g for g in client.get("/v1/grinds").json()["grinds"]}
        assert listed["ski-base"]["provenance"].startswith("measured")
        assert listed["grind-1"]["provenance"] == "synthetic"
        r = client.post("/v1/contact", json={"ski": "ski-a", "grind": "ski-base", **CONTACT})
        assert r.status_code == 200, r.text[:300]
        assert "measured;" in client.get("/").text


def test_upload_notes_a_skipped_position_row_and_refuses_overridden_calibration(
    catalogue, tmp_path
):
    """#27 point 5 through the API: a csv whose first row lists x positions is read without
    it, with a note in the answer; an x3p given pixel_size_um or height_unit is a 422."""
    rng = np.random.default_rng(7)
    h_um = self_affine_surface((40, 40), 1e-6, hurst=0.8, rms_height_m=1e-6, rng=rng) * 1e6
    rows = [np.arange(40) * 2.0, *h_um]
    text = "\n".join(",".join(f"{v:.9g}" for v in row) for row in rows).encode()
    with make_client(catalogue, tmp_path, table_points=4) as client:
        r = post_grind(client, name="with-x-row", content=text, filename="g.csv")
        assert r.status_code == 202, r.text[:300]
        body = r.json()
        assert body["item"]["metadata"]["grid"] == [40, 40]
        assert any("row 1" in n for n in body["preparation"]["notes"])
        buf = io.BytesIO()
        x3pio.write(buf, h_um.T * 1e-6, x_scale=1e-6, y_scale=1e-6)
        for field in ({"pixel_size_um": "2", "height_unit": None}, {"pixel_size_um": None}):
            r = post_grind(client, name="x3p", content=buf.getvalue(), filename="g.x3p", **field)
            detail = is_problem(r, 422)["detail"]
            assert "own calibration; do not give" in detail
        wait_job(client, body["job"])


def test_a_2048_square_map_is_accepted_by_the_default_limits(catalogue, tmp_path):
    """The default limits (80 MiB body, 4096² map, 1024² solve grid) take a 2048² map and
    block-average it 4 × 4 (mirror: 1024²); no job runs here (job_workers=0)."""
    from skisnow.app.settings import Settings

    defaults = Settings()
    rng = np.random.default_rng(8)
    h_um = rng.normal(size=(2048, 2048)).astype(np.float32)
    h_um[1000:1003, 700] = np.nan  # a few unmeasured points
    limits = {
        "max_upload_bytes": defaults.max_upload_bytes,
        "max_grid_points": defaults.max_grid_points,
        "max_solve_grid_points": defaults.max_solve_grid_points,
        "job_workers": 0,
    }
    with make_client(catalogue, tmp_path, **limits) as client:
        r = post_grind(client, name="big", content=npy_bytes(h_um))
        assert r.status_code == 202, r.text[:300]
        prep = r.json()["preparation"]
        assert prep["measured"]["filled_points"] == 3
        assert prep["reduction"]["block_factor"] == 4 and prep["reduction"]["grid"] == [512, 512]
        assert r.json()["item"]["metadata"]["solve_grid"] == [1024, 1024]
