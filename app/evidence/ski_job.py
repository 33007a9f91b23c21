"""The ski job end to end, the last part of ``skisnow bench macro`` (issue #26, Benchmark: "ski
job end to end (network + beam): report it").

Each ski is measured by the virtual device (:func:`app.evidence.identification.design_camber_data`:
a study design, draw 0 of ``scripts/own_ski_study.py`` on its grid, the unloaded profile first,
3 µm noise), written as the CSV a technician uploads, and sent through ``POST /v1/skis`` of a
fresh app on a temporary data directory with the **service's settings** as ``skisnow serve``
reads them (by default the default camber network: :class:`app.settings.Settings`
``train_epochs``, ``train_lbfgs_epochs``, ``train_ensemble``; the run records those it used).
The time is the user's: from the upload's request to the job's ``done``, polled every 0.2 s.
The job's own split (``job_stage_s`` in the item's metadata: training, identification, model
choice, ski file, figures) says where it went.

Needs torch (the network's training: ``pip install -e '.[train]'``) and httpx (the app's test
client: ``.[test]``); both come with the test dependencies.
"""

from __future__ import annotations

import logging
import os
import tempfile
import time
from pathlib import Path

from skisnow.app.evidence import identification as ib

log = logging.getLogger(__name__)

__all__ = ["JOB_SKIS", "POLL_S", "bench_ski_job", "render_md"]

#: (design, grid) of the skis timed: one design per family (classic, functional, skate;
#: app.evidence.identification.BENCH_DESIGNS), each on the dense 13 × 9 grid and on the smallest
#: grid the upload accepts, 9 × 5
JOB_SKIS = tuple((d, g) for d in ib.BENCH_DESIGNS for g in ("dense", "coarse"))
#: how often the job's state is read [s]
POLL_S = 0.2
#: a job that takes longer is reported as timed out [s]
TIMEOUT_S = 3600.0


#: the settings of the network the run used (reported with the run)
TRAINING_KEYS = ("train_epochs", "train_lbfgs_epochs", "train_ensemble", "ski_max_test_rmse_um")


def _settings(data_dir: Path, overrides: dict | None = None):
    """The service's settings as ``skisnow serve`` reads them (defaults, SKISNOW_* environment)
    on ``data_dir``, no warm-up, the job polled every :data:`POLL_S`; ``overrides``: a test's
    smaller network."""
    from skisnow.app.settings import Settings

    return Settings(data_dir=data_dir, warm_up=False, job_poll_s=POLL_S, **(overrides or {}))


def _client(make_app, settings):
    """A fresh app from ``make_app(settings, catalogue)`` (the API factory; this module sits below
    the API and is handed it), answering for the shipped tables and skis."""
    try:
        from fastapi.testclient import TestClient
    except ImportError as exc:  # httpx missing
        raise RuntimeError(
            "the ski job bench drives the app through its test client, which needs httpx: "
            "pip install -e '.[test]'"
        ) from exc
    from skisnow.app import service
    from skisnow.app.storage.skis import SHIPPED_SKI_DIR

    shipped = service.load_catalogue(SHIPPED_SKI_DIR.parent)
    return TestClient(make_app(settings, shipped), raise_server_exceptions=False)


def _one(make_app, design: str, grid: str, work: Path, overrides: dict | None) -> dict:
    """Upload one measured ski and wait for its job: the row of the bench."""
    from skisnow.app.storage.skis import write_camber_csv

    data, truth = ib.design_camber_data(design, grid=grid)
    name = data.ski_id
    csv = work / f"{name}.csv"
    write_camber_csv(csv, data)
    length_mm = (truth.positions_m[-1] - truth.positions_m[0]) * 1e3
    data_dir = work / name
    data_dir.mkdir(parents=True)
    row: dict = {"design": design, "grid": grid, "cases": int(data.loads_n.size)}
    load_before = os.getloadavg()[0]
    with _client(make_app, _settings(data_dir, overrides)) as client:
        t0 = time.perf_counter()
        r = client.post(
            "/v1/skis",
            files={"file": (csv.name, csv.read_bytes(), "text/csv")},
            data={"name": name, "length_mm": f"{length_mm:.0f}", "width_mm": "44"},
        )
        if r.status_code != 202:
            return {**row, "state": f"refused ({r.status_code})", "message": r.text[:400]}
        job_id = r.json()["job"]
        while True:
            job = client.get(f"/v1/jobs/{job_id}").json()
            if job.get("state") in ("done", "failed"):
                break
            if time.perf_counter() - t0 > TIMEOUT_S:
                job = {**job, "state": "timed out"}
                break
            time.sleep(POLL_S)
        row["time_s"] = round(time.perf_counter() - t0, 1)
        row["state"] = job.get("state")
        row["message"] = job.get("error") or job.get("message")
        item = client.get(f"/v1/skis/{name}").json()
    meta = item.get("metadata") or {}
    row["stage_s"] = meta.get("job_stage_s", {})
    # the network's held-out RMSE where H* < 0.2 mm [µm]: above the limit it is not served
    rmse_m = (meta.get("accuracy") or {}).get("test_rmse_band_m")
    row["network_test_rmse_um"] = None if rmse_m is None else round(rmse_m * 1e6, 2)
    row["profile_model"] = (item.get("profile_model") or {}).get("name")
    row["load_avg_1min"] = [load_before, os.getloadavg()[0]]
    log.info("ski job bench: %s %s in %.0f s %s", name, row["state"], row["time_s"], row["stage_s"])
    return row


def bench_ski_job(
    make_app, skis: tuple[tuple[str, str], ...] = JOB_SKIS, overrides: dict | None = None
) -> dict:
    """Time the ski job of each (design, grid) in :data:`JOB_SKIS` from upload to done, with the
    service's default settings (``overrides``: settings changed, for a test), through the app of
    ``make_app(settings, catalogue)`` (:func:`app.api.factory.create_api`); one run each, one
    after the other."""
    with tempfile.TemporaryDirectory(prefix="skisnow-job-bench-") as tmp:
        used = _settings(Path(tmp), overrides)
        rows = {}
        for design, grid in skis:
            rows[f"{design}-{grid}-d0"] = _one(make_app, design, grid, Path(tmp), overrides)
    training = {k: getattr(used, k) for k in TRAINING_KEYS}
    return {"training": training, "poll_s": POLL_S, "skis": rows}


def _stages(stage_s: dict) -> str:
    order = ("training", "identification", "model_choice", "ski_file", "figures")
    return " / ".join(_seconds(stage_s[k]) if k in stage_s else "—" for k in order)


def _rmse(v: float | None, limit: float) -> str:
    """The network's held-out RMSE [µm], with "not served" above the limit."""
    if v is None:
        return "—"
    return f"{v:.1f}" + (" (not served)" if v > limit else "")


def _seconds(v: float) -> str:
    """A stage's seconds: whole above 10 s, two digits below (0.38, 4.2)."""
    return f"{v:.0f}" if v >= 10 else f"{v:.2g}"


def render_md(d: dict) -> list[str]:
    """The paragraph and table "Ski job end to end" of docs/benchmarks.md from a stored run."""
    if not d or not d.get("skis"):
        return []
    t = d.get("training", {})
    lines = [
        "### Ski job end to end (issue #26)",
        "",
        "A measured ski uploaded through `POST /v1/skis` of a fresh app with the service's default "
        f"settings (camber network: {t.get('train_epochs')} Adam + {t.get('train_lbfgs_epochs')} "
        f"L-BFGS epochs × {t.get('train_ensemble')} members), timed from the upload's request "
        f"to the job's `done` (polled every {d.get('poll_s', POLL_S):g} s); the split is the "
        "job's own (`job_stage_s` in the item's metadata). Skis: study designs measured by the "
        "virtual device (draw 0 of `scripts/own_ski_study.py`, the unloaded profile first, 3 µm "
        "noise), the dense grid 13 × 9 and the coarse 9 × 5, the smallest the upload accepts. A "
        "network whose held-out RMSE (where H* < 0.2 mm, device noise included) is above the "
        "limit is not served and the identified beam serves alone; before #26's fix such a job "
        'failed ("accuracy check failed"). One run each, on 2 cores.',
        "",
        "| ski | cases | state | upload to done [s] | training / identification / model choice / "
        "ski file / figures [s] | network held-out RMSE [µm] (limit "
        f"{t.get('ski_max_test_rmse_um', 8.0):g}) | profile model served | 1-min load before → "
        "after |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, r in d["skis"].items():
        la = r.get("load_avg_1min") or []
        load = f"{la[0]:.1f} → {la[1]:.1f}" if len(la) == 2 else "—"
        time_s = r.get("time_s")
        lines.append(
            f"| {name} | {r.get('cases', '—')} | {r.get('state')} | "
            f"{'—' if time_s is None else f'{time_s:.0f}'} | {_stages(r.get('stage_s') or {})} | "
            f"{_rmse(r.get('network_test_rmse_um'), t.get('ski_max_test_rmse_um', 8.0))} | "
            f"{r.get('profile_model') or '—'} | {load} |"
        )
    lines.append("")
    return lines
