"""Shared fixtures: a small synthetic texture table and a catalogue with the demo skis."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

# the application's OpenMP setting (skisnow.app sets it on import; tests import the kernels
# alone first): before any solver import starts an OpenMP runtime
os.environ.setdefault("GOMP_SPINCOUNT", "1000")

from skisnow.solvers import lookup as L
from skisnow.solvers.elastic import PeriodicHalfSpace
from skisnow.solvers.micro import full_contact_pressure
from skisnow.solvers.texture import self_affine_surface

REPO = Path(__file__).resolve().parents[1]


def make_table(
    heights: np.ndarray,
    ratios: np.ndarray,
    *,
    name: str = "synthetic",
    pixel_m: float = 1e-6,
    e_eff: float = 1e8,
    floor: float = 10e-9,
    tol: float = 1e-6,
) -> L.MicroTable:
    """Build a MicroTable in memory (same kernels as ``skisnow build-tables``)."""
    hs = PeriodicHalfSpace(heights.shape, pixel_m, e_eff, workers=1)
    p_fc, _ = full_contact_pressure(heights, pixel_m, e_eff, halfspace=hs)
    out = L.solve_table_chunk(
        heights,
        pixel_m,
        ratios,
        effective_modulus_pa=e_eff,
        full_contact_pressure_ratio=p_fc / e_eff,
        tol=tol,
        max_iterations=2000,
        gap_floor_m=floor,
    )
    out.pop("solve_time_s")
    mean_h0, mean_rec0 = L.unloaded_statistics(heights, floor)
    clearance = np.geomspace(1e-8, 1e-2, 61)
    return L.MicroTable(
        name=name,
        pixel_size_m=pixel_m,
        grid_shape=heights.shape,
        effective_modulus_pa=e_eff,
        gap_floor_m=floor,
        tol=tol,
        pressure_ratio=ratios,
        full_contact_pressure_ratio=p_fc / e_eff,
        unloaded_mean_gap_m=mean_h0,
        unloaded_mean_reciprocal_gap_per_m=mean_rec0,
        clearance_m=clearance,
        separated_mean_reciprocal_gap_per_m=L.separated_curve(heights, clearance),
        **out,
    )


@pytest.fixture(scope="session", autouse=True)
def _private_data_dir(tmp_path_factory):
    """Every app built in the tests keeps its catalogue database and uploads in a temporary
    data directory, never in the user's (SKISNOW_DATA_DIR, see docs/uploads.md)."""
    import os

    old = os.environ.get("SKISNOW_DATA_DIR")
    os.environ["SKISNOW_DATA_DIR"] = str(tmp_path_factory.mktemp("skisnow-data"))
    yield
    if old is None:
        os.environ.pop("SKISNOW_DATA_DIR", None)
    else:
        os.environ["SKISNOW_DATA_DIR"] = old


@pytest.fixture(scope="session")
def small_table() -> L.MicroTable:
    h = self_affine_surface(
        (64, 64), 1e-6, hurst=0.8, rms_height_m=1e-6, rng=np.random.default_rng(4)
    )
    return make_table(h, np.geomspace(1e-8, 1e-2, 25), name="tiny-grind")


#: a valid /v1/contact body for the ``catalogue`` fixture (demo ski on the small table)
CONTACT_BODY = {
    "ski": "ski-a",
    "grind": "tiny-grind",
    "load_kg": 40,
    "load_position_mm": -160,
    "snow_modulus_mpa": 200,
    "porosity": 0.5,
}


@pytest.fixture(scope="session")
def catalogue(small_table):
    """Demo skis from tables/skis plus the small synthetic table as grind ``tiny-grind``."""
    from skisnow.app import service
    from skisnow.app.storage.common import sha256_file
    from skisnow.app.storage.skis import read_ski

    cat = service.Catalogue(tables_dir=REPO / "tables")
    for path in sorted((REPO / "tables" / "skis").glob("ski-*.h5")):
        cat.skis[path.stem] = service.Ski(path.stem, path, sha256_file(path), read_ski(path))
    cat.grinds["tiny-grind"] = service.Grind(
        "tiny-grind", REPO / "tables" / "tiny-grind.h5", "0" * 64, small_table
    )
    return cat


@pytest.fixture(scope="module")
def camber_csv(tmp_path_factory) -> bytes:
    """A valid camber CSV: demo ski A's beam model, 5 loads × 5 positions, 5 mm sampling."""
    from skisnow.app.storage.skis import CamberData, read_ski, write_camber_csv
    from skisnow.solvers.beam import G_STANDARD, measure_camber

    rec = read_ski(REPO / "tables" / "skis" / "ski-a.h5")
    loads = np.array([20.0, 35.0, 50.0, 65.0, 80.0]) * G_STANDARD
    positions = np.linspace(-0.30, 0.10, 5)
    f, xf, gaps = measure_camber(rec.beam, loads, positions, noise_m=3e-6, rng=7)
    sel = np.arange(0, rec.beam.positions_m.size, 5)
    data = CamberData("my-ski", rec.beam.positions_m[sel], f, xf, ["mean"] * f.size, gaps[:, sel])
    path = tmp_path_factory.mktemp("csv") / "ski.csv"
    write_camber_csv(path, data)
    return path.read_bytes()


#: the grid of :func:`upload_csv`: the smallest that the upload accepts (app.jobs.uploads
#: MIN_GRID_LOADS × MIN_GRID_LOAD_POSITIONS every ≤ MAX_SAMPLE_SPACING_MM)
UPLOAD_LOADS_KG = (10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0)
UPLOAD_POSITIONS_M = (-0.30, -0.20, -0.10, 0.0, 0.10)


@pytest.fixture(scope="module")
def upload_csv(tmp_path_factory) -> bytes:
    """A camber CSV the upload accepts: demo ski A's beam model measured at 9 loads × 5
    positions (the smallest grid that gets a served beam), 5 mm sampling, 3 µm noise; no
    unloaded profile (the ski job does not use one yet)."""
    from skisnow.app.storage.skis import CamberData, read_ski, write_camber_csv
    from skisnow.solvers.beam import G_STANDARD, measure_camber

    rec = read_ski(REPO / "tables" / "skis" / "ski-a.h5")
    loads = np.array(UPLOAD_LOADS_KG) * G_STANDARD
    f, xf, gaps = measure_camber(rec.beam, loads, np.array(UPLOAD_POSITIONS_M), noise_m=3e-6, rng=7)
    sel = np.arange(0, rec.beam.positions_m.size, 5)
    data = CamberData("my-ski", rec.beam.positions_m[sel], f, xf, ["mean"] * f.size, gaps[:, sel])
    path = tmp_path_factory.mktemp("csv") / "ski.csv"
    write_camber_csv(path, data)
    return path.read_bytes()
