"""Bring-your-own skis and grinds, end to end through the REST API (docs/uploads.md).

Upload a grind (64² height map) and a ski (camber CSV measured on the demo ski's beam model),
wait for their jobs, compute /v1/contact with them; restart the app mid-build and see the job
resume from its checkpoints; bad uploads give precise 4xx and leave nothing in storage.
Table and training settings are tiny so that every job takes seconds.
"""

from __future__ import annotations

import io
import json
import re
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from fastapi.testclient import TestClient
from skisnow.app import service
from skisnow.app.main import create_app
from skisnow.app.settings import Settings
from skisnow.app.storage.catalogue import CatalogueDB
from skisnow.solvers.beam import BeamSki
from skisnow.solvers.texture import iso25178_parameters, level_heights, self_affine_surface

REPO = Path(__file__).resolve().parents[2]
CONTACT = {"load_kg": 40, "load_position_mm": -160, "snow_modulus_mpa": 200, "porosity": 0.5}
FAST = {
    "warm_up": False,
    "table_points": 8,
    "table_chunk_size": 2,
    "table_processes": False,
    "job_poll_s": 0.05,
    "train_epochs": 300,
    "train_lbfgs_epochs": 50,
    "train_ensemble": 1,
    # 45 load cases and 300 epochs fit the held-out cases to ~50 µm; the default limit (8 µm)
    # needs the full training on a denser data set (see test_ski_refused_by_accuracy_check)
    "ski_max_test_rmse_um": 200.0,
    "max_upload_bytes": 1_000_000,
}


def heights_um(n: int = 64, seed: int = 1) -> np.ndarray:
    h = self_affine_surface(
        (n, n), 1e-6, hurst=0.8, rms_height_m=1e-6, rng=np.random.default_rng(seed)
    )
    return h * 1e6


def npy_bytes(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


#: the arrays of a stored identification that make its beam
BEAM_ARRAYS = ("positions_m", "bending_stiffness_nm2", "unloaded_gap_m")


def make_client(catalogue, data_dir: Path, **overrides) -> TestClient:
    cat = service.Catalogue(
        tables_dir=catalogue.tables_dir, skis=dict(catalogue.skis), grinds=dict(catalogue.grinds)
    )
    settings = Settings(data_dir=data_dir, **{**FAST, **overrides})
    return TestClient(create_app(settings, catalogue=cat))


def post_grind(client, name="my-grind", content=None, filename="g.npy", headers=None, **fields):
    data = {"name": name, "pixel_size_um": "1", "height_unit": "um", "shop_code": "S1", **fields}
    data = {k: v for k, v in data.items() if v is not None}
    content = npy_bytes(heights_um()) if content is None else content
    return client.post(
        "/v1/grinds",
        files={"file": (filename, content, "application/octet-stream")},
        data=data,
        headers=headers or {},
    )


def post_ski(client, content, name="my-ski", filename="ski.csv", headers=None, **fields):
    data = {"name": name, "length_mm": "2000", "width_mm": "44", "style": "classic", **fields}
    return client.post(
        "/v1/skis",
        files={"file": (filename, content, "text/csv")},
        data=data,
        headers=headers or {},
    )


def wait_job(client, job_id: str, timeout_s: float = 120.0, headers=None) -> dict:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        job = client.get(f"/v1/jobs/{job_id}", headers=headers or {}).json()
        assert 0.0 <= job["progress"] <= 1.0
        if job["state"] in ("done", "failed"):
            return job
        time.sleep(0.05)
    raise AssertionError(f"job {job_id} did not finish in {timeout_s} s: {job}")


def stored_files(data_dir: Path) -> list[str]:
    """Files under the data directory other than the database."""
    return sorted(
        str(p.relative_to(data_dir))
        for p in data_dir.rglob("*")
        if p.is_file() and not p.name.startswith("catalogue.db")
    )


def is_problem(resp, status: int) -> dict:
    assert resp.status_code == status, resp.text[:500]
    assert resp.headers["content-type"].startswith("application/problem+json")
    body = resp.json()
    assert body["status"] == status and body["detail"]
    return body


# ----------------------------------------------------------------------------- grinds


def test_a_finished_upload_is_usable_at_once_on_a_process_that_has_not_polled(catalogue, tmp_path):
    """Two service processes on one database: the one that did not run the job serves the
    item as soon as a client asks for it, not only after its next poll (docker CI saw
    ``usable: false`` from the second uvicorn worker right after the job was done)."""
    with (
        make_client(catalogue, tmp_path) as a,
        make_client(catalogue, tmp_path, job_poll_s=3600.0) as b,
    ):
        r = post_grind(a, name="seen-by-b")
        assert r.status_code == 202, r.text
        assert wait_job(a, r.json()["job"])["state"] == "done"
        assert "seen-by-b" not in b.app.state.catalogue.grinds  # b has not polled since
        listed = {g["name"] for g in b.get("/v1/grinds").json()["grinds"]}
        assert "seen-by-b" in listed
        b.app.state.uploads.live.drop_all()  # as if b had never loaded it
        shown = b.get("/v1/grinds/seen-by-b").json()
        assert shown["state"] == "ready" and shown["usable"] is True
        r = b.post("/v1/contact", json={"ski": "ski-a", "grind": "seen-by-b", **CONTACT})
        assert r.status_code == 200, r.text[:500]
        page = b.get("/results", params={"ski": "ski-a", "grind": "seen-by-b", **CONTACT})
        assert page.status_code == 200, page.text[:500]
        # an unknown name is still a 404 naming the known ones
        body = is_problem(
            b.post("/v1/contact", json={"ski": "ski-a", "grind": "nope", **CONTACT}), 404
        )
        assert "seen-by-b" in body["known"]


def test_grind_upload_build_contact_rename_delete(catalogue, tmp_path):
    with make_client(catalogue, tmp_path) as client:
        r = post_grind(client, machine="Wintersteiger", temperature_window="-5..0 C")
        assert r.status_code == 202, r.text
        body = r.json()
        assert body["item"]["state"] == "pending" and body["item"]["name"] == "my-grind"
        iso = body["iso25178"]
        levelled, _ = level_heights(heights_um() * 1e-6, 1e-6)
        expected = iso25178_parameters(levelled, 1e-6, periodic=False)
        assert iso == pytest.approx(expected, rel=1e-9)
        assert r.headers["location"] == f"/v1/jobs/{body['job']}"
        job = wait_job(client, body["job"])
        assert job["state"] == "done", job
        assert job["item"] == "my-grind" and job["progress"] == 1.0 and job["error"] is None

        listed = {g["name"]: g for g in client.get("/v1/grinds").json()["grinds"]}
        assert "my-grind" in listed and listed["my-grind"]["grid"] == [128, 128]
        shown = client.get("/v1/grinds/my-grind").json()
        assert shown["state"] == "ready" and shown["usable"] is True
        assert shown["metadata"]["machine"] == "Wintersteiger"
        assert shown["metadata"]["table_points"] == 8
        # measured maps are mirrored to fit the periodic solver (docs/topography.md)
        assert shown["metadata"]["periodic"] == "mirror"
        assert shown["metadata"]["solve_grid"] == [128, 128]
        # ... after their least-squares plane is removed, which the item and table record
        assert shown["metadata"]["detrend"] == "plane"
        assert listed["my-grind"]["detrend"] == "plane"
        with h5py.File(tmp_path / "grinds" / f"{shown['id']}.h5") as f:
            assert f["texture"].attrs["detrend"] == "plane"
            assert f.attrs["texture_detrend"] == "plane"

        r = client.post("/v1/contact", json={"ski": "ski-a", "grind": "my-grind", **CONTACT})
        assert r.status_code == 200, r.text[:500]
        metrics = r.json()["metrics"]
        assert all(np.isfinite(v) and v > 0 for v in metrics.values())

        # only the finished table is stored; the scratch space and the texture are gone
        item_id = shown["id"]
        assert stored_files(tmp_path) == [f"grinds/{item_id}.h5"]

        r = client.patch("/v1/grinds/my-grind", json={"name": "shop-7"})
        assert r.status_code == 200 and r.json()["name"] == "shop-7"
        is_problem(client.get("/v1/grinds/my-grind"), 404)
        r = client.post("/v1/contact", json={"ski": "ski-a", "grind": "shop-7", **CONTACT})
        assert r.status_code == 200
        assert r.json()["metrics"] == metrics
        is_problem(
            client.post("/v1/contact", json={"ski": "ski-a", "grind": "my-grind", **CONTACT}), 404
        )

        # shipped items are read-only; names are unique per kind
        is_problem(client.delete("/v1/grinds/tiny-grind"), 403)
        is_problem(client.patch("/v1/skis/ski-a", json={"name": "x"}), 403)
        is_problem(post_grind(client, name="shop-7"), 409)
        is_problem(post_grind(client, name="tiny-grind"), 409)

    # the catalogue persists across a restart
    with make_client(catalogue, tmp_path) as client:
        assert "shop-7" in {g["name"] for g in client.get("/v1/grinds").json()["grinds"]}
        assert client.delete("/v1/grinds/shop-7").status_code == 204
        assert "shop-7" not in {g["name"] for g in client.get("/v1/grinds").json()["grinds"]}
        is_problem(client.get("/v1/grinds/shop-7"), 404)
    assert stored_files(tmp_path) == []


def test_second_lifespan_of_one_app_serves_uploads_as_uploads(catalogue, tmp_path):
    """A stopped app started again (the same app object: test clients, the fuzz run) must not
    take the uploads it had loaded for shipped items: before the fix, a grind deleted after
    the restart was still served, and a re-upload of its name never replaced it (found by the
    fuzz run, issue #15 point 6)."""
    client = make_client(catalogue, tmp_path)
    with client:
        assert wait_job(client, post_grind(client, name="g1").json()["job"])["state"] == "done"
        old = client.get("/v1/grinds/g1").json()["sha256"]
    assert "g1" not in client.app.state.catalogue.grinds  # stop unloads it
    with client:  # second lifespan of the same app
        assert client.get("/v1/grinds/g1").json()["read_only"] is False
        assert client.delete("/v1/grinds/g1").status_code == 204
        assert "g1" not in {g["name"] for g in client.get("/v1/grinds").json()["grinds"]}
        is_problem(client.post("/v1/contact", json={"ski": "ski-a", "grind": "g1", **CONTACT}), 404)
        # a new upload of that name is served, not the deleted one
        r = post_grind(client, name="g1", content=npy_bytes(heights_um(seed=2)))
        assert wait_job(client, r.json()["job"])["state"] == "done"
        listed = {g["name"]: g for g in client.get("/v1/grinds").json()["grinds"]}
        assert listed["g1"]["sha256"] != old
        assert listed["g1"]["sha256"] == client.get("/v1/grinds/g1").json()["sha256"]


def test_restart_mid_build_resumes_from_checkpoints(catalogue, tmp_path):
    from skisnow.app.storage.tables import read_table

    slow = {"table_points": 12, "table_chunk_size": 1}
    with make_client(catalogue, tmp_path, **slow) as client:
        r = post_grind(client, name="resumed", periodic="none")
        assert r.status_code == 202, r.text
        job_id = r.json()["job"]
        t0 = time.monotonic()
        while client.get(f"/v1/jobs/{job_id}").json()["progress"] == 0:
            assert time.monotonic() - t0 < 60, "no chunk finished"
            time.sleep(0.02)
    # the service stopped mid-build: the job is queued again, its checkpoints kept
    db = CatalogueDB(f"sqlite:///{tmp_path / 'catalogue.db'}")
    job = db.job(job_id)
    db.close()
    assert job.state == "queued", job
    assert "resumes" in job.message
    checkpoints = list(tmp_path.glob("work/*/.checkpoints/*/*/chunk-*.h5"))
    assert 0 < len(checkpoints) < 12
    assert not list(tmp_path.glob("grinds/*.h5"))

    with make_client(catalogue, tmp_path, **slow) as client:
        job = wait_job(client, job_id)
        assert job["state"] == "done", job
        # periodic=none does not change the detrend: the plane is removed by default
        assert client.get("/v1/grinds/resumed").json()["metadata"]["detrend"] == "plane"
        shown = client.get("/v1/grinds/resumed").json()
        assert shown["usable"] is True
        table = read_table(tmp_path / "grinds" / f"{shown['id']}.h5")
        assert table.attrs["chunks_resumed"] >= len(checkpoints)
        r = client.post("/v1/contact", json={"ski": "ski-b", "grind": "resumed", **CONTACT})
        assert r.status_code == 200, r.text[:300]


def test_grind_upload_detrend_field_is_honoured_and_recorded(catalogue, tmp_path):
    n = 64
    i, j = np.indices((n, n)) / (n - 1)
    raw_um = heights_um(n, seed=3) + 0.8 * i - 0.5 * j + 25.0  # tilted, off-centre
    with make_client(catalogue, tmp_path) as client:
        for detrend in ("none", "mean", "plane"):
            name = f"d-{detrend}"
            r = post_grind(client, name=name, content=npy_bytes(raw_um), detrend=detrend)
            assert r.status_code == 202, r.text[:500]
            levelled, _ = level_heights(raw_um * 1e-6, 1e-6, detrend=detrend)
            expected = iso25178_parameters(levelled, 1e-6, periodic=False)
            assert r.json()["iso25178"] == pytest.approx(expected, rel=1e-9)
            assert client.get(f"/v1/grinds/{name}").json()["metadata"]["detrend"] == detrend
        # the tilt is kept or removed as asked: the slope rms differs
        shown = {d: client.get(f"/v1/grinds/d-{d}").json()["metadata"] for d in ("mean", "plane")}
        assert shown["mean"]["iso25178"]["Sq_m"] > 1.01 * shown["plane"]["iso25178"]["Sq_m"]
        bad = is_problem(post_grind(client, name="d-bad", detrend="tilt"), 422)
        assert [e["field"].split(".")[-1] for e in bad["errors"]] == ["detrend"], bad
        assert "Traceback" not in str(bad)


def test_job_of_a_crashed_process_is_requeued(tmp_path):
    import socket

    from skisnow.app.jobs import JobRunner

    db = CatalogueDB(f"sqlite:///{tmp_path / 'c.db'}")
    item = db.add_item("grind", "g")
    job = db.add_job("noop", item.id)
    db.update_job(job.id, state="running", runner=f"{socket.gethostname()}:999999999:dead")
    seen = []
    runner = JobRunner(db, {"noop": lambda ctx: seen.append(ctx.item.name) or "ok"}, poll_s=0.02)
    runner.start()
    try:
        t0 = time.monotonic()
        while db.job(job.id).state != "done":
            assert time.monotonic() - t0 < 10
            time.sleep(0.02)
    finally:
        runner.stop()
        db.close()
    assert seen == ["g"]


# ------------------------------------------------------------------------------- skis


def test_ski_upload_train_and_contact(catalogue, tmp_path, upload_csv):
    assert len(upload_csv) > 64 * 1024  # larger than the JSON body limit: the upload limit applies
    with make_client(catalogue, tmp_path) as client:
        r = post_ski(client, upload_csv, brand_model="Fischer Speedmax", owner_team="team-x")
        assert r.status_code == 202, r.text[:500]
        figures = r.json()["data"]
        assert figures["load_cases"] == 45 and figures["sample_spacing_mm"] == pytest.approx(5)
        # 45 cases: the beam identification takes minutes on a busy 2-core machine
        job = wait_job(client, r.json()["job"], timeout_s=900.0)
        assert job["state"] == "done", job
        assert "held-out RMSE" in job["message"]
        listed = {s["name"]: s for s in client.get("/v1/skis").json()["skis"]}
        shown = client.get("/v1/skis/my-ski").json()
        ident = shown["beam"]["identification"]
        # a beam identified from the camber cases (held-out check passed, misfit at the noise)
        # is the profile model; otherwise the network is
        served = ident["ok"] and "identified from the camber data" in shown["beam"]["source"]
        profile = "identified_beam" if served else "network"
        assert listed["my-ski"]["profile_model"] == profile
        assert listed["my-ski"]["length_mm"] == pytest.approx(2000)
        assert shown["metadata"]["brand_model"] == "Fischer Speedmax"
        assert shown["metadata"]["accuracy"]["test_rmse_band_m"] < 200e-6
        r = client.post("/v1/contact", json={"ski": "my-ski", "grind": "tiny-grind", **CONTACT})
        assert r.status_code == 200, r.text[:500]
        assert r.json()["provenance"]["ski"]["profile_model"] == profile
        assert r.json()["apparent"]["contact_area_cm2"] > 0
        # the ski file, its CSV and the figures of its page, drawn by the job
        assert sorted(stored_files(tmp_path)) == sorted(
            [
                f"skis/{shown['id']}.h5",
                f"uploads/{shown['id']}.csv",
                f"cache/ski-figures/{shown['id']}.json",
            ]
        )
        # the job identified (or failed to identify) the ski's beam, and says which
        beam = shown["beam"]
        # the 45 cases of the 9 loads × 5 positions (upload_csv), some held out
        from skisnow.app.storage.skis import read_ski as read_ski_file

        stored_ski = read_ski_file(tmp_path / "skis" / f"{shown['id']}.h5")
        n_held = np.size(stored_ski.identified["held_out_index"])
        assert n_held >= 1 and len(ident["case_misfit_um"]) + n_held == 45
        assert ident["noise_um"] == pytest.approx(3.0, rel=0.15)
        # the ski's page shows the same: profile model, and every case's misfit with its load
        page = client.get("/skis/my-ski")
        assert page.status_code == 200
        assert f"<code>{profile}</code>" in page.text
        # its figures are the job's drawing, read from the cache (a new drawing has other ids)
        drawn = json.loads((tmp_path / "cache" / "ski-figures" / f"{shown['id']}.json").read_text())
        assert drawn["figures"] and all(svg in page.text for svg in drawn["figures"].values())
        assert f"profile model: {profile}" in client.get("/").text
        # the CSV's 9 loads × 5 positions (upload_csv), less the held-out cases
        assert set(ident["case_load_kg"]) <= {10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0}
        assert set(ident["case_position_mm"]) <= {-300.0, -200.0, -100.0, 0.0, 100.0}
        rows = re.findall(
            r'<tr class="identified"><td>([^<]+)</td><td>([^<]+)</td><td>([^<]+)</td>', page.text
        )
        assert [float(r[2]) for r in rows] == ident["case_misfit_um"]
        assert page.text.count('<tr class="held-out">') == len(
            (ident.get("held_out") or {}).get("error_um", [])
        )
        # the job stored each held-out case's error with the identification: the page and the
        # API read it (no prediction on read), and it is the stored beam's prediction error
        from skisnow.app.service.profiles import HELD_OUT_ERRORS, HELD_OUT_STORED
        from skisnow.app.storage.skis import mean_profiles, read_ski
        from skisnow.solvers.identify import predict_gaps

        record = read_ski(tmp_path / "skis" / f"{shown['id']}.h5")
        stored = record.identified[HELD_OUT_ERRORS]
        assert ident["held_out"]["provenance"]["source"] == HELD_OUT_STORED
        assert stored["attrs"]["source"] == HELD_OUT_STORED
        held = np.sort(record.identified["held_out_index"])
        assert held.size == n_held and np.array_equal(stored["case_index"], held)
        f, xf, y, _ = mean_profiles(record.measurements)
        stored_beam = BeamSki(*(record.identified[k] for k in BEAM_ARRAYS))
        # read at the measured nodes (the beam is on 1 mm model nodes, the file every 5 mm)
        gaps = predict_gaps(stored_beam, f[held], xf[held], record.measurements.positions_m)
        expected = np.sqrt(np.mean((gaps - y[held]) ** 2, axis=1))
        np.testing.assert_allclose(stored["rms_error_m"], expected, rtol=1e-12, atol=0)
        assert ident["held_out"]["error_um"] == [float(f"{e * 1e6:.4g}") for e in expected]
        body = {"ski": "my-ski", "grind": "tiny-grind", **CONTACT}
        flex = client.post("/v1/contact", json={**body, "ski_model": "flexible"})
        auto = client.post("/v1/contact", json={**body, "ski_model": "auto"}).json()
        codes = [w["code"] for w in auto["warnings"]]
        if served:
            # a beam that passed the held-out check serves flexible and auto alike
            assert "beam identified" in job["message"]
            assert beam["available"] and len(beam["bending_stiffness_nm2"]) == 41
            assert "identified from the camber data" in beam["source"]
            assert flex.status_code == 200, flex.text[:300]
            assert flex.json()["provenance"]["ski_model"]["used"] == "flexible"
            assert "flexible_unavailable" not in codes
        else:
            assert (
                "beam not identified" in job["message"]
                or "profile model: network" in job["message"]
            )
            assert flex.status_code == 422 and "no beam model" in flex.json()["detail"]
            assert auto["provenance"]["ski_model"]["used"] == "rigid"
            assert "flexible_unavailable" in codes


@pytest.fixture(scope="module")
def camber_csv_unloaded(tmp_path_factory) -> bytes:
    """A 9 × 5 camber CSV (the smallest grid the upload accepts) with the unloaded profile first
    (load_kg 0, load position 0: ignored), as a camber device records it: demo ski A's beam,
    3 µm noise, every 5 mm."""
    from skisnow.app.storage.skis import CamberData, read_ski, write_camber_csv
    from skisnow.solvers.beam import G_STANDARD, measure_camber, measure_unloaded

    rec = read_ski(REPO / "tables" / "skis" / "ski-a.h5")
    loads = np.linspace(10.0, 90.0, 9) * G_STANDARD
    f, xf, gaps = measure_camber(rec.beam, loads, np.linspace(-0.30, 0.10, 5), noise_m=3e-6, rng=7)
    g0 = measure_unloaded(rec.beam, noise_m=3e-6, rng=8)
    sel = np.arange(0, rec.beam.positions_m.size, 5)
    data = CamberData(
        "my-ski",
        rec.beam.positions_m[sel],
        np.concatenate([[0.0], f]),
        np.concatenate([[0.0], xf]),
        ["mean"] * (f.size + 1),
        np.vstack([g0[sel], gaps[:, sel]]),
    )
    path = tmp_path_factory.mktemp("csv0") / "ski.csv"
    write_camber_csv(path, data)
    return path.read_bytes()


def test_ski_upload_with_the_unloaded_profile_ends_done(catalogue, tmp_path, camber_csv_unloaded):
    """A CSV with the unloaded profile (load_kg 0) trains: the network's range starts at 0 N and
    answers the measured unloaded profile at F = 0; both models are judged on the same held-out
    cases (seeded, recorded, never the unloaded one) and the better one serves. The file is sent
    as a Windows spreadsheet saves "Unicode text" of a device that scans from the tip (UTF-16,
    tabs, decimal commas, 'Load (kg)' headers, positions decreasing, no ski_id and side
    columns): the job reads the stored bytes to the same measurements as the neutral file, the
    ski named as uploaded."""
    from skisnow.app.service.profiles import MODEL_CHOICE
    from skisnow.app.storage.skis import mean_profiles, read_camber_csv, read_ski
    from skisnow.solvers import camber

    neutral = camber_csv_unloaded.decode().splitlines()
    cases: dict[str, list[str]] = {}
    for row in neutral[1:]:
        cases.setdefault(",".join(row.split(",")[1:4]), []).append(row)
    assert {r.split(",")[1] for r in neutral[1:]} == {"mean"}  # a middle-line device's file
    rows = [
        r.split(",", 2)[2].replace(",", "\t").replace(".", ",")
        for c in cases.values()
        for r in reversed(c)
    ]
    header = "Load (kg)\tLoad position (mm)\tPosition (mm)\tGap (mm)"
    sheet = "\r\n".join([header, *rows]).encode("utf-16")  # 1.2 MB: twice the UTF-8 size
    with make_client(catalogue, tmp_path, max_upload_bytes=4_000_000) as client:
        r = post_ski(client, sheet, name="zero-ski")
        assert r.status_code == 202, r.text[:500]
        job = wait_job(client, r.json()["job"])
        assert job["state"] == "done", job
        shown = client.get("/v1/skis/zero-ski").json()
        assert shown["metadata"]["data"]["text_encoding"] == "UTF-16"
        assert shown["metadata"]["data"]["positions_in_file"].startswith("decreasing")
        assert shown["metadata"]["data"]["columns_not_in_file"] == ["ski_id=zero-ski", "side=mean"]
        record = read_ski(tmp_path / "skis" / f"{shown['id']}.h5")
        assert record.measurements.ski_id == "zero-ski"
        read = read_camber_csv(camber_csv_unloaded.decode())
        np.testing.assert_array_equal(record.measurements.profiles_m, read.profiles_m)
        np.testing.assert_array_equal(record.measurements.positions_m, read.positions_m)
        net = record.network
        assert net["attrs"]["load_min_n"] == 0.0 and net["attrs"]["unloaded_cases"] == 1
        f, _, y, _ = mean_profiles(record.measurements)
        assert f.size == 46 and (f == 0).sum() == 1
        choice = record.identified[MODEL_CHOICE]
        held = np.asarray(choice["case_index"])
        assert held.size == 9 and (f[held] > 0).all()
        assert choice["attrs"]["seed"] == 0
        np.testing.assert_allclose(np.sort(net["split_test_loads_n"]), np.sort(f[held]))
        # the network never saw the held-out cases, and neither did the identification
        assert not np.isin(held, np.flatnonzero(f == 0)).any()
        if "held_out_index" in record.identified:
            assert np.array_equal(np.sort(record.identified["held_out_index"]), held)
        served = choice["attrs"]["served"]
        assert shown["profile_model"]["name"] == served
        comparison = shown["profile_model"]["held_out_comparison"]
        assert comparison["served"] == served and comparison["held_out_cases"] == 9
        assert f"profile model: {served}" in job["message"]
        # F = 0 answers the measured unloaded profile where it matters (H* < 0.2 mm), to the
        # 300-epoch network's own fit of its loaded training cases there (plus the 3 µm noise);
        # whatever x_F (tests/training/test_unloaded.py)
        pred = camber.predict_profiles(net, np.zeros(5), np.linspace(-0.3, 0.1, 5)).gaps_m
        band = [camber.contact_band_rmse_m(p, y[f == 0][0]) for p in pred]
        limit = 1.5 * net["attrs"]["metric_train_rmse_band_m"] + 3e-6
        assert max(band) < limit, (band, limit)
        page = client.get("/skis/zero-ski")
        assert page.status_code == 200 and 'id="model-choice-table"' in page.text


def test_a_junior_ski_from_a_windows_spreadsheet_gets_its_beam_and_true_answers(
    catalogue, tmp_path
):
    """A ski unlike every study design: 1.5 m long, 0.7 kN·m², loads 5–45 kg, measured on both
    sides (9 × 5 cases and the unloaded profile each, 3 µm noise), sent as a Windows
    spreadsheet's CSV (`;`, decimal commas, Windows-1252), the tip's last samples unmeasured
    ("nan"). The job ends done with its beam
    served, and the answers agree with the true beam's within 3 % and inside their band."""
    from skisnow.app.storage.skis import CamberData, camber_csv_text, read_ski
    from skisnow.solvers.beam import G_STANDARD, ClassicSkiDesign, measure_camber, measure_unloaded

    design = ClassicSkiDesign(
        tail_m=-0.72,
        tip_m=0.78,
        tail_contact_m=-0.66,
        tip_contact_m=0.58,
        camber_height_m=1.1e-3,
        pocket_m=(-0.25, 0.2),
        pocket_height_m=3e-4,
        stiffness_nm2=700.0,
        end_stiffness_ratio=0.2,
        tail_rise_m=0.005,
        tip_rise_m=0.03,
    )
    truth = design.build(1e-3)
    rng = np.random.default_rng(11)
    f_all, xf_all, sides, profiles = [], [], [], []
    for side in ("left", "right"):
        y0 = measure_unloaded(truth, noise_m=3e-6, rng=rng)
        f, xf, y = measure_camber(
            truth,
            np.linspace(5, 45, 9) * G_STANDARD,
            np.linspace(-0.2, 0.08, 5),
            noise_m=3e-6,
            rng=rng,
        )
        f_all += [0.0, *f]
        xf_all += [0.0, *xf]
        sides += [side] * (f.size + 1)
        profiles += [y0, *y]
    data = CamberData(
        "Junior Ø",
        truth.positions_m[::5],
        np.array(f_all),
        np.array(xf_all),
        sides,
        np.array(profiles)[:, ::5],
    )
    # the tip's last two samples out of the device's range in every case, one dropout near
    # the tip: written "nan", their positions dropped from every case (docs/macro.md)
    data.profiles_m[:, -2:] = np.nan
    data.profiles_m[7, -3] = np.nan
    dropped_mm = data.positions_m[-3:] * 1e3
    sheet = "\r\n".join(
        line.replace(",", ";").replace(".", ",") for line in camber_csv_text(data).splitlines()
    ).encode("cp1252")
    with make_client(catalogue, tmp_path) as client:
        r = post_ski(client, sheet, name="junior", length_mm="1500")
        assert r.status_code == 202, r.text[:500]
        assert r.json()["data"]["text_encoding"] == "Windows-1252"
        assert r.json()["data"]["unmeasured"]["positions_dropped_mm"] == pytest.approx(dropped_mm)
        assert r.json()["data"]["unmeasured"]["cases_dropped"] == []
        job = wait_job(client, r.json()["job"])
        assert job["state"] == "done", job
        shown = client.get("/v1/skis/junior").json()
        assert shown["profile_model"]["name"] == "identified_beam"
        record = read_ski(tmp_path / "skis" / f"{shown['id']}.h5")
        assert record.measurements.ski_id == "Junior Ø"
        # the job read the file as the upload did: the unmeasured positions dropped, recorded
        assert not np.isin(record.measurements.positions_m * 1e3, dropped_mm).any()
        assert np.isfinite(record.measurements.profiles_m).all()
        assert json.loads(record.metadata["positions_dropped_mm"]) == pytest.approx(dropped_mm)
        assert json.loads(record.metadata["cases_dropped"]) == []
        # samples every 5 mm, the beam on 1 mm model nodes with the samples among them
        nodes = np.asarray(record.identified["positions_m"])
        assert np.allclose(np.diff(nodes), 1e-3, rtol=1e-6)
        assert np.isin(record.measurements.positions_m, nodes).all()
        assert shown["beam"]["identification"]["model_spacing_mm"] == pytest.approx(1.0)
        ski = service.Ski("junior-truth", tmp_path / "skis" / "t.h5", "", record)
        true_ski = service.Ski(
            "junior-truth",
            ski.path,
            "",
            type(record)(record.measurements, record.outline, beam=truth),
        )
        cat = service.Catalogue(
            tables_dir=catalogue.tables_dir,
            skis={"junior-truth": true_ski},
            grinds=dict(catalogue.grinds),
        )
        for model in ("rigid", "flexible"):
            q = {
                "ski": "junior",
                "grind": "tiny-grind",
                "load_kg": 25,
                "load_position_mm": -123,
                "snow_modulus_mpa": 200,
                "porosity": 0.5,
                "ski_model": model,
            }
            a = client.post("/v1/contact", json=q)
            assert a.status_code == 200, a.text[:500]
            a = a.json()
            want = service.contact(
                cat,
                service.ContactInputs(
                    "junior-truth", "tiny-grind", 25, -123, 200, 0.5, ski_model=model
                ),
            )["apparent"]["contact_area_cm2"]
            got = a["apparent"]["contact_area_cm2"]
            lo, hi = a["band"]["intervals"]["contact_area_cm2"]
            assert abs(got / want - 1) < 0.03, (model, got, want)
            assert lo <= want <= hi, (model, lo, want, hi)


#: a network far above the accuracy limit (5 epochs against the default limit, 8 µm)
ROUGH_NETWORK = {"train_epochs": 5, "train_lbfgs_epochs": 0, "ski_max_test_rmse_um": 8.0}


def _upload_and_wait(client, content: bytes, name: str) -> dict:
    """Upload a camber CSV (accepted) and wait for its job: the job's view."""
    r = post_ski(client, content, name=name)
    assert r.status_code == 202, r.text[:500]
    return wait_job(client, r.json()["job"])


def test_a_network_above_the_accuracy_limit_leaves_the_beam_to_serve(
    catalogue, tmp_path, upload_csv
):
    """A network that fails the accuracy check (5 epochs, limit 8 µm) does not fail the job
    when the beam identified from the same cases passes its own held-out check: the beam
    serves, the held-out comparison says why, and the job's stage times are kept (#26: with the
    service's default settings the 9 × 5 grid the upload accepts failed here, 25 µm on
    race-classic; docs/benchmarks.md "Ski job end to end")."""
    with make_client(catalogue, tmp_path, **ROUGH_NETWORK) as client:
        job = _upload_and_wait(client, upload_csv, "rough")
        assert job["state"] == "done", job
        assert "above the accuracy limit: not served" in job["message"]
        assert "limit 8 µm" in job["message"]
        shown = client.get("/v1/skis/rough").json()
        assert shown["usable"] is True
        model = shown["profile_model"]
        assert model["name"] == "identified_beam"
        comparison = model["held_out_comparison"]
        assert comparison["served"] == "identified_beam"
        assert "failed its accuracy check" in comparison["reason"]
        # the network was judged all the same: its held-out error is far above the beam's
        assert comparison["network_excess_band_um"] > comparison["beam_excess_band_um"]
        stages = shown["metadata"]["job_stage_s"]
        assert list(stages) == ["training", "identification", "model_choice", "ski_file", "figures"]
        assert all(v >= 0 for v in stages.values()) and stages["identification"] > 0
        answer = client.post(
            "/v1/contact",
            json={"ski": "rough", "grind": "tiny-grind", **CONTACT},
        )
        assert answer.status_code == 200, answer.text[:300]


def test_a_server_without_pytorch_serves_the_identified_beam(
    catalogue, tmp_path, upload_csv, monkeypatch
):
    """A plain install (README's service command) has no PyTorch, so no network is trained: the
    job still identifies the beam, which serves alone; the ski answers (found by the README's
    service check: every upload failed with "needs PyTorch")."""
    from skisnow.app.training import fit
    from skisnow.app.training.model import TRAIN_EXTRA_HINT

    def no_torch(*args, **kwargs):
        raise ImportError(TRAIN_EXTRA_HINT)

    monkeypatch.setattr(fit, "train_camber_network", no_torch)
    with make_client(catalogue, tmp_path) as client:
        job = _upload_and_wait(client, upload_csv, "plain")
        assert job["state"] == "done", job
        assert job["message"].startswith(f"network not trained ({TRAIN_EXTRA_HINT}); beam ")
        shown = client.get("/v1/skis/plain").json()
        assert shown["usable"] is True
        model = shown["profile_model"]
        assert model["name"] == "identified_beam"
        reason = model["held_out_comparison"]["reason"]
        assert reason == f"no camber network to compare ({TRAIN_EXTRA_HINT})"
        q = {"ski": "plain", "grind": "tiny-grind", "load_kg": 40, "load_position_mm": -160}
        q |= {"snow_modulus_mpa": 200, "porosity": 0.5}
        for ski_model in ("rigid", "flexible", "auto"):
            r = client.post("/v1/contact", json={**q, "ski_model": ski_model})
            assert r.status_code == 200, r.text[:300]
        assert client.get("/skis/plain").status_code == 200
    # and where the identification fails too, the job fails with both reasons
    from skisnow.app.jobs import ski_job

    reason = "beam not identified: misfit 9.00 µm is 3.0× the device noise"
    monkeypatch.setattr(
        ski_job, "_identify", lambda *a, **k: ({"attrs": {"ok": False, "reason": reason}}, reason)
    )
    with make_client(catalogue, tmp_path / "again") as client:
        job = _upload_and_wait(client, upload_csv, "plain")
        assert job["state"] == "failed"
        assert job["error"].startswith(f"network not trained ({TRAIN_EXTRA_HINT}); beam not")
        assert "neither camber model can serve" in job["error"]


def test_ski_refused_when_neither_model_can_serve(catalogue, tmp_path, upload_csv, monkeypatch):
    """The network fails its accuracy check and the beam is not identified: the job fails with
    both reasons and keeps nothing; the name can be used again."""
    from skisnow.app.jobs import ski_job

    def no_beam(data, item, callback=None, held_out_index=None):
        reason = "beam not identified: misfit 9.00 µm is 3.0× the device noise"
        return {"attrs": {"ok": False, "reason": reason}}, reason + " (rigid model only)"

    monkeypatch.setattr(ski_job, "_identify", no_beam)
    with make_client(catalogue, tmp_path, **ROUGH_NETWORK) as client:
        job = _upload_and_wait(client, upload_csv, "rough")
        assert job["state"] == "failed"
        assert "accuracy check failed" in job["error"] and "limit 8 µm" in job["error"]
        assert "beam not identified: misfit 9.00 µm" in job["error"]
        assert "neither camber model can serve" in job["error"]
        shown = client.get("/v1/skis/rough").json()
        assert shown["state"] == "failed" and shown["usable"] is False
        assert stored_files(tmp_path) == []
        assert client.delete("/v1/skis/rough").status_code == 204


# ------------------------------------------------------------------------ bad uploads


@pytest.fixture(scope="module")
def bad_client(catalogue, tmp_path_factory):
    data_dir = tmp_path_factory.mktemp("bad")
    with make_client(catalogue, data_dir, max_upload_bytes=800_000) as client:
        yield client, data_dir


def _csv_lines(camber_csv: bytes) -> list[str]:
    return camber_csv.decode().splitlines()


def _huge_npy_header() -> bytes:
    """A .npy whose header declares 8192 × 8192 float64 (the body is left out)."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": "<f8", "fortran_order": False, "shape": (8192, 8192)}
    )
    return buf.getvalue()


def _damaged_npy_header(at: bytes) -> bytes:
    """A .npy of the 64² test map with a NUL byte in place of the first ``at`` of its header:
    numpy's header parser raised SyntaxError or tokenize.TokenError, a 500 (found by the fuzz
    run, issue #15 point 6)."""
    data = bytearray(npy_bytes(heights_um()))
    data[data.index(at)] = 0
    return bytes(data)


def _nan_map() -> np.ndarray:
    return np.full((64, 64), np.nan)


GRIND_CASES = {
    "truncated npy": (dict(content=npy_bytes(heights_um())[:5000]), 422, "file"),
    "npy header with a NUL": (dict(content=_damaged_npy_header(b"}")), 422, "npy header"),
    "npy header unclosed": (dict(content=_damaged_npy_header(b")")), 422, "npy header"),
    "all NaN": (dict(content=npy_bytes(_nan_map())), 422, "valid point"),
    "1-pixel map": (dict(content=npy_bytes(np.ones((1, 1)))), 422, "too small"),
    "huge grid": (dict(content=_huge_npy_header()), 422, "exceeds the limit"),
    "wrong height unit": (dict(height_unit="m"), 422, "wrong height unit"),
    "unknown height unit": (dict(height_unit="furlong"), 422, "height_unit"),
    "missing pixel size": (dict(pixel_size_um=None), 422, "pixel_size_um"),
    "PNG named .npy": (dict(content=b"\x89PNG\r\n\x1a\n" + b"0" * 100), 415, "magic"),
    "unknown format": (dict(content=b"MZ\x90\x00" + bytes(600), filename="g.exe"), 415, "content"),
    "pickle in npy": (dict(content=npy_bytes(np.array([{}], dtype=object))), 415, "objects"),
    "over the upload limit": (dict(content=b"\x93NUMPY" + b"0" * 900_000), 413, "exceeds"),
    "bad name": (dict(name="../etc/passwd"), 422, "name"),
    "CSV not rectangular": (dict(content=b"1,2,3\n4,5\n", filename="g.csv"), 422, "truncated"),
}


@pytest.mark.parametrize("case", sorted(GRIND_CASES))
def test_bad_grind_uploads_are_4xx_and_leave_nothing(bad_client, case):
    client, data_dir = bad_client
    kwargs, status, words = GRIND_CASES[case]
    body = is_problem(
        post_grind(client, name=kwargs.pop("name", f"bad-{len(case)}"), **kwargs), status
    )
    assert words in body["detail"], body
    assert str(data_dir) not in body["detail"]  # no server paths in messages
    assert stored_files(data_dir) == []
    assert client.get("/v1/jobs").json()["jobs"] == []


def _ski_cases(lines: list[str]) -> dict:
    header, rows = lines[0], lines[1:]
    neg = rows[10].rsplit(",", 1)[0] + ",-1.0"
    # an unmeasured gap in the middle of every case: keeping one uniform grid would drop half
    # the ski or every case, refused (a reading lost near the tip or tail only drops those
    # positions, one inside the span in a few cases those cases)
    mid = rows[200].split(",")[4]
    nan = [r.rsplit(",", 1)[0] + ",nan" if r.split(",")[4] == mid else r for r in rows]
    few = [r for r in rows if r.split(",")[2] in ("20", "80")]  # 2 loads × 5 positions
    return {
        "negative gap": ([header, *rows[:10], neg, *rows[11:]], 422, "line 12: gap_mm"),
        "NaN gap": (
            [header, *nan],
            422,
            "the least that keeps one uniform grid is the stretch",
        ),
        "truncated": ([header, *rows[:-100], rows[-100][:12]], 422, "line"),
        "too sparse": ([header, *few], 422, "2 loads × 5 load positions"),
        "wrong header": (["x,y,z", *rows], 422, "line 1: header"),
    }


@pytest.mark.parametrize(
    "case", ["negative gap", "NaN gap", "truncated", "too sparse", "wrong header"]
)
def test_bad_ski_uploads_are_4xx_and_leave_nothing(bad_client, upload_csv, case):
    client, data_dir = bad_client
    lines, status, words = _ski_cases(_csv_lines(upload_csv))[case]
    body = is_problem(post_ski(client, ("\n".join(lines) + "\n").encode(), name="bad"), status)
    assert words in body["detail"], body
    assert stored_files(data_dir) == []


def test_other_bad_ski_requests(bad_client, upload_csv):
    client, data_dir = bad_client
    small = ("\n".join(_csv_lines(upload_csv)[:1000]) + "\n").encode()
    is_problem(post_ski(client, small, filename="ski.xlsx"), 415)
    is_problem(post_ski(client, b"\x00\x01binary", filename="ski.csv"), 415)
    is_problem(post_ski(client, small, style="telemark"), 422)
    is_problem(post_ski(client, small, width_mm="400"), 422)
    is_problem(client.post("/v1/skis", json={"name": "x"}), 415)
    is_problem(post_ski(client, upload_csv * 2), 413)  # > this client's 800 kB
    assert stored_files(data_dir) == []


# ------------------------------------------------------------------------------ teams


def test_team_tokens_guard_changes(catalogue, tmp_path):
    tokens = {"token-a": "team-a", "token-b": "team-b"}
    a = {"authorization": "Bearer token-a"}
    b = {"authorization": "Bearer token-b"}
    with make_client(catalogue, tmp_path, team_tokens=tokens) as client:
        r = post_grind(client, name="a-grind")
        assert is_problem(r, 401) and r.headers["www-authenticate"] == "Bearer"
        r = post_grind(client, name="a-grind", headers=a)
        assert r.status_code == 202
        job_id = r.json()["job"]
        assert r.json()["item"]["team"] == "team-a"
        # busy while its job is queued or running
        is_problem(client.delete("/v1/grinds/a-grind", headers=a), 409)
        assert wait_job(client, job_id, headers=a)["state"] == "done"
        # another team's item does not exist for team b, for changes as for reads (404, not
        # 403: its existence is not leaked; tests/api/test_safe_defaults.py has the reads)
        is_problem(client.patch("/v1/grinds/a-grind", json={"name": "b"}, headers=b), 404)
        is_problem(client.delete("/v1/grinds/a-grind", headers=b), 404)
        is_problem(client.get("/v1/grinds/a-grind"), 404)  # a reader of no team
        assert client.get("/v1/grinds/a-grind", headers=a).status_code == 200
        assert client.delete("/v1/grinds/a-grind", headers=a).status_code == 204
