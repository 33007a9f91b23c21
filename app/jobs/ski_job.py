"""Job ``ski-network`` of an uploaded ski: beam identification, camber network training and its
accuracy check, the ski file (:func:`run_ski_job`); and the clean-up of any failed job
(:func:`on_job_failure`)."""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import shutil
import time
from pathlib import Path

import numpy as np
from skisnow.app import service
from skisnow.app.jobs.runner import JobContext
from skisnow.app.settings import Settings
from skisnow.app.storage.common import provenance, sha256_file
from skisnow.app.storage.layout import Layout
from skisnow.solvers.errors import InputError, SkisnowError

log = logging.getLogger(__name__)


def run_ski_job(ctx: JobContext, layout: Layout, settings: Settings, on_ready) -> str:
    """Job ``ski-network``: train the camber network, check it, write the ski file."""
    from skisnow.app.storage.skis import (
        SkiOutline,
        SkiRecord,
        identified_beam,
        mean_profiles,
        read_camber_csv,
        read_ski,
        write_ski,
    )
    from skisnow.app.training.data import camber_training_arrays, job_held_out
    from skisnow.app.training.files import write_network_to_ski
    from skisnow.app.training.fit import train_camber_network
    from skisnow.app.training.model import TRAIN_EXTRA_HINT

    item = ctx.item
    # the upload's name stands in for a ski_id the file left out, as at upload
    data = read_camber_csv(
        layout.ski_csv(item.id),
        default_ski_id=item.name,
        # as the upload read it (items stored before the choice: drop, the default)
        unmeasured=item.metadata.get("unmeasured", "drop"),
    )
    _, x, f, xf, h, side = camber_training_arrays(data)
    # one held-out draw (seeded, recorded) for both models: the network is trained and the beam
    # identified without these cases, and both are judged on them (app.service.profiles)
    # (drawn on the network's cases; every one of them is also a case of the identification)
    fm, xfm, ym, _ = mean_profiles(data)
    held_t, held_m = job_held_out(data, (fm, xfm))
    total = settings.train_ensemble * (settings.train_epochs + settings.train_lbfgs_epochs)
    calls = 0

    def progress(phase: str, epoch: int, loss_tr: float, loss_va: float) -> None:
        nonlocal calls
        calls += 1
        ctx.progress(0.95 * calls / total, f"training ({phase}, epoch {epoch})")

    # wall time of each stage [s], kept in the item's metadata (``job_stage_s``): what the
    # job's time went to (`skisnow bench macro --only-job` reports it, docs/benchmarks.md)
    stage_s: dict[str, float] = {}
    t_stage = time.perf_counter()

    def stage_done(name: str) -> None:
        nonlocal t_stage
        now = time.perf_counter()
        stage_s[name] = round(now - t_stage, 2)
        t_stage = now

    ctx.progress(0.0, "training the camber network")
    try:
        result = train_camber_network(
            x,
            f,
            xf,
            h,
            epochs=settings.train_epochs,
            lbfgs_epochs=settings.train_lbfgs_epochs,
            ensemble=settings.train_ensemble,
            ski_id=item.name,
            metadata={"measured_side": side, "measurements_source": f"upload {item.id}.csv"},
            progress=progress,
            test_index=held_t,
        )
    except ImportError as exc:  # a plain install (no torch): the identified beam may serve
        if str(exc) != TRAIN_EXTRA_HINT:
            raise
        result = None
    stage_done("training")
    # a network that may not serve leaves the job going on: an identified beam that passes its
    # own held-out check serves alone (a coarse grid the network cannot learn, #26; a server
    # without PyTorch, where no network is trained); the job fails only when neither model can
    # serve (below, after the identification). ``network_refused``: why the network may not
    if result is None:
        network, m = None, {}
        network_note = failed = f"network not trained ({TRAIN_EXTRA_HINT})"
        network_refused = TRAIN_EXTRA_HINT
    else:
        network, m = result.network, result.metrics
        rmse_um = float(m.get("test_rmse_band_m", math.nan)) * 1e6
        limit = settings.ski_max_test_rmse_um
        figures = (
            f"held-out RMSE where H* < 0.2 mm = {rmse_um:.2f} µm on {m.get('test_n_cases', 0)} "
            f"test case(s) (limit {limit:g} µm), validation "
            f"{m.get('validation_rmse_band_m', 0) * 1e6:.2f} µm, train "
            f"{m.get('train_rmse_band_m', 0) * 1e6:.2f} µm"
        )
        network_refused = "" if math.isfinite(rmse_um) and rmse_um <= limit else figures
        above = " (above the accuracy limit: not served)" if network_refused else ""
        network_note = f"network trained{above}; {figures}"
        failed = f"accuracy check failed: {figures}"
    ctx.check_stop()
    o = item.metadata["outline"]
    record = SkiRecord(
        measurements=data,
        outline=SkiOutline(
            length_m=float(item.metadata["length_mm"]) * 1e-3,
            balance_point_from_tail_m=float(o["balance_point_from_tail_mm"]) * 1e-3,
            positions_m=np.asarray(o["positions_mm"]) * 1e-3,
            width_m=np.asarray(o["width_mm"]) * 1e-3,
        ),
        metadata={
            k: str(v)
            for k, v in item.metadata.items()
            if k in ("brand_model", "style", "owner_team", "notes", "original_filename")
        }
        | {"description": f"uploaded ski {item.name}", "item_id": item.id}
        # how the file's unmeasured samples were handled (provenance of the measurements)
        | {
            "unmeasured": str(item.metadata.get("unmeasured", "drop")),
            "unmeasured_samples": str(data.unmeasured_samples),
            "omitted_samples": str(data.omitted_samples),
            "positions_dropped_mm": json.dumps(list(data.dropped_positions_mm)),
            "positions_absent_mm": json.dumps(list(data.absent_positions_mm)),
            "cases_dropped": json.dumps(list(data.dropped_cases)),
            "position_shift_mm": repr(data.position_shift_mm),
        },
    )
    ctx.progress(0.96, "identifying the ski's beam from its camber cases")
    record.identified, beam_note = _identify(
        data,
        item,
        lambda frac, msg: ctx.progress(0.96 + 0.03 * frac, f"identifying the ski's beam: {msg}"),
        held_out_index=held_m,
    )
    stage_done("identification")
    if network_refused and identified_beam(record.identified) is None:
        raise InputError(
            f"{failed}; {beam_note}: neither camber model can serve; "
            "measure more load cases or denser positions"
        )
    record.identified, choice_note = _choose_model(
        record.identified, network, (fm, xfm, ym), held_m, item, network_refused, data.positions_m
    )
    stage_done("model_choice")
    work = layout.work(item.id)
    work.mkdir(parents=True, exist_ok=True)
    staged = work / "ski.h5"
    write_ski(staged, record, parameters={"item": item.id, "name": item.name})
    if network is not None:
        write_network_to_ski(staged, network)
    read_ski(staged)  # verify before it enters the catalogue
    final = layout.ski_file(item.id)
    final.parent.mkdir(parents=True, exist_ok=True)
    os.replace(staged, final)
    shutil.rmtree(work, ignore_errors=True)
    stage_done("ski_file")
    ctx.progress(0.98, "drawing the ski page's figures")
    _draw_page_figures(item, final, layout)
    stage_done("figures")
    meta = {
        **item.metadata,
        "accuracy": {k: v for k, v in m.items() if isinstance(v, float)},
        "job_stage_s": stage_s,
    }
    db_item = ctx.db.update_item(
        item.id, state="ready", file_path=str(final), sha256=sha256_file(final), metadata=meta
    )
    on_ready(db_item)
    return f"{network_note}; {beam_note}; {choice_note}"


def _draw_page_figures(item, path: Path, layout: Layout) -> None:
    """Draw the figures of the ski's page into its figure cache (:mod:`app.service.ski_figures`), so
    that its first view is fast. A failure is logged, never fails the job: the page then draws
    them on its first view."""
    from skisnow.app.service.ski_figures import ski_figures
    from skisnow.app.storage.skis import read_ski

    try:
        ski = service.Ski(item.name, path, sha256_file(path), read_ski(path))
        ski_figures(ski, layout.ski_figures(path.stem))
    except Exception as exc:  # a cache not filled must not fail the upload
        log.warning(
            "figures of ski %r not drawn in its job (%s): its page draws them", item.name, exc
        )


def _choose_model(
    identified: dict,
    network: dict,
    cases,
    held_m,
    item,
    network_refused: str = "",
    nodes_m=None,
) -> tuple[dict, str]:
    """The ``identified`` group with the held-out comparison of the two profile models
    (:func:`app.service.profiles.held_out_comparison`) and one sentence for the job result.
    ``network_refused``: why the network may not serve (its failed accuracy check), or '';
    ``nodes_m``: the measured nodes [m] (where a finer-grid beam's gaps are read)."""
    from skisnow.app.service.profiles import MODEL_CHOICE, held_out_comparison
    from skisnow.app.storage.skis import identified_beam
    from skisnow.app.training.data import HELD_OUT_FRACTION, HELD_OUT_SEED
    from skisnow.solvers.identify import estimate_noise

    f, xf, y = cases
    noise = float(identified.get("attrs", {}).get("noise_m", math.nan))
    if not (math.isfinite(noise) and noise > 0):
        noise = estimate_noise(y)
    params = {"item": item.id, "seed": HELD_OUT_SEED, "fraction": HELD_OUT_FRACTION}
    group = held_out_comparison(
        network,
        identified_beam(identified),
        f,
        xf,
        y,
        held_m,
        noise,
        params,
        network_refused,
        nodes_m=nodes_m,
    )
    a = group["attrs"]
    note = f"profile model: {a['served']} ({a['reason']})"
    return {**identified, MODEL_CHOICE: group}, note


def _identify(data, item, callback=None, held_out_index=None) -> tuple[dict, str]:
    """Identify the beam of an uploaded ski (docs/physics.md §4c): the stored ``identified``
    group and one sentence for the job result. A failure is recorded, never raised: the ski still
    works with the rigid model and its network. ``callback(fraction, message)``: the
    identification's progress (the job shows it; minutes on a loaded machine).
    ``held_out_index``: the job's held-out cases (indices into the cases of
    :func:`app.storage.skis.mean_profiles`), not identified, the check's cases."""
    from skisnow.app.path_pool import identify_with_pool
    from skisnow.app.service.profiles import identification_group
    from skisnow.app.storage.skis import mean_profiles
    from skisnow.solvers.identify import identify_beam_checked

    try:
        f, xf, y, note = mean_profiles(data)
        # thread counts fixed (this process and the workers): the same data and seed give
        # the same beam whatever the machine's BLAS default (#26)
        ident, check = identify_with_pool(
            identify_beam_checked,
            data.positions_m,
            f,
            xf,
            y,
            held_out_index=held_out_index,
            callback=callback,
        )
    except SkisnowError as exc:
        reason = f"beam not identified: {exc}"
        failed = {"attrs": {"ok": False, "reason": reason, **provenance({"item": item.id})}}
        return failed, reason + " (rigid model only)"
    group = identification_group(
        ident, check, note, f, xf, {"item": item.id}, y, nodes_m=data.positions_m
    )
    if not ident.ok:
        return group, f"beam not identified: {ident.reason} (rigid model only)"
    return group, (
        f"beam identified: misfit {ident.misfit_m * 1e6:.2f} µm against device noise "
        f"{ident.noise_m * 1e6:.2f} µm over {f.size - check['held_out_cases']} cases, "
        f"{(check['held_out_rms_m'] or 0.0) * 1e6:.2f} µm on {check['held_out_cases']} held-out "
        f"cases ({note})"
    )


def on_job_failure(ctx: JobContext, layout: Layout) -> None:
    """A failed job leaves its item ``failed`` with no files (the job row keeps the error)."""
    if ctx.item is None:
        return
    layout.remove_item_files(ctx.item.id)
    with contextlib.suppress(Exception):
        ctx.db.update_item(ctx.item.id, state="failed", file_path=None, sha256=None)
