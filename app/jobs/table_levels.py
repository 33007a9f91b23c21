"""The pixel levels of a table build (``--pixel-levels``): the level textures of one texture,
one job per level, and the table assembled from the levels' chunks (the zero-pixel limit and
its error estimate, :func:`solvers.lookup.combine_pixel_levels` /
:func:`~solvers.lookup.combine_three_pixel_levels`). Imports ``storage`` and ``solvers``.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from skisnow.app.jobs.table_settings import (
    NAME_RE,
    BuildSettings,
    checkpoint_key,
    solver_source_sha256,
)
from skisnow.app.storage.tables import (
    LEVEL_REFINEMENT,
    read_checkpoint,
    refinements,
)
from skisnow.solvers.elastic import PeriodicHalfSpace
from skisnow.solvers.errors import InputError
from skisnow.solvers.lookup import (
    ERROR_FIELDS,
    ORDER_TOLERANCE,
    PIXEL_EXTRAPOLATION_ORDERS,
    MicroTable,
    chunk_bounds,
    combine_pixel_levels,
    combine_three_pixel_levels,
    separated_curve,
    unloaded_statistics,
)
from skisnow.solvers.micro import full_contact_pressure
from skisnow.solvers.texture import Texture, iso25178_parameters

log = logging.getLogger(__name__)


@dataclass
class _Job:
    texture: Texture  # the level's heights and pixel size
    key: str
    directory: Path
    full_contact_pressure_ratio: float
    bounds: list[tuple[int, int]]
    results: dict[int, dict[str, np.ndarray]]

    def chunk_path(self, index: int) -> Path:
        return self.directory / f"chunk-{index:03d}.h5"


def _coarsened(texture: Texture) -> Texture:
    h = np.asarray(texture.heights_m, dtype=float)
    k = LEVEL_REFINEMENT
    if h.shape[0] % k or h.shape[1] % k:
        raise InputError(
            f"texture {texture.name!r}: --pixel-levels coarsen needs grid sizes divisible by "
            f"{k}, got {h.shape}"
        )
    coarse = h.reshape(h.shape[0] // k, k, h.shape[1] // k, k).mean(axis=(1, 3))
    return Texture(
        coarse,
        texture.pixel_size_m * k,
        texture.name,
        texture.missing_fraction,
        f"{texture.source}; block-averaged {k}x{k}",
        detrend=texture.detrend,
    )


def _levels(
    texture: Texture, settings: BuildSettings, refined: dict[str, Texture] | None
) -> list[Texture]:
    """The level textures of one table, coarse first (the texture itself is one of them)."""
    if settings.pixel_levels == "none":
        return [texture]
    if settings.pixel_levels == "coarsen":
        return [_coarsened(texture), texture]
    fine = (refined or {}).get(texture.name)
    finer = [fine] if isinstance(fine, Texture) else list(fine or [])
    factors = refinements(settings.pixel_levels)
    if len(finer) != len(factors):
        raise InputError(
            f"texture {texture.name!r}: --pixel-levels {settings.pixel_levels} needs its "
            f"surface refined {factors}x (app.storage.textures.refined_texture), got "
            f"{len(finer)} refined texture(s)"
        )
    shape = tuple(np.shape(texture.heights_m))
    for k, level in zip(factors, finer, strict=True):
        if np.shape(level.heights_m) != (shape[0] * k, shape[1] * k) or not np.isclose(
            level.pixel_size_m * k, texture.pixel_size_m, rtol=1e-12
        ):
            raise InputError(f"refined texture of {texture.name!r} is not {k}x finer")
    return [texture, *finer]


def _level_name(name: str, index: int, count: int) -> str:
    return name if count == 1 else f"{name}.level{index}"


def _prepare(texture: Texture, settings: BuildSettings, out_dir: Path, job_name: str) -> _Job:
    if not NAME_RE.match(texture.name or ""):
        raise InputError(f"texture name {texture.name!r} cannot be a file name")
    heights = np.asarray(texture.heights_m, dtype=float)
    if heights.ndim != 2 or not np.all(np.isfinite(heights)) or np.ptp(heights) == 0:
        raise InputError(f"texture {texture.name!r}: heights must be 2-D, finite and not flat")
    e_eff = settings.effective_modulus_pa
    hs = PeriodicHalfSpace(heights.shape, texture.pixel_size_m, e_eff, workers=1)
    p_fc, _ = full_contact_pressure(heights, texture.pixel_size_m, e_eff, halfspace=hs)
    key = checkpoint_key(texture, settings)
    job = _Job(
        texture=texture,
        key=key,
        directory=out_dir / ".checkpoints" / job_name / key[:16],
        full_contact_pressure_ratio=p_fc / e_eff,
        bounds=chunk_bounds(settings.points, settings.chunk_size),
        results={},
    )
    for index in range(len(job.bounds)):
        done = read_checkpoint(job.chunk_path(index), key)
        if done is not None:
            job.results[index] = done
    return job


def _assemble(
    texture: Texture, level_jobs: list[_Job], settings: BuildSettings
) -> tuple[MicroTable, dict]:
    level_arrays = []
    for job in level_jobs:
        parts = [job.results[i] for i in range(len(job.bounds))]
        level_arrays.append({name: np.concatenate([p[name] for p in parts]) for name in parts[0]})
    diagnostics = {"solve_time_s": np.sum([a.pop("solve_time_s") for a in level_arrays], axis=0)}
    extra: dict = {}
    order_info: dict = {}
    if len(level_arrays) == 1:
        arrays = level_arrays[0]
    else:
        if len(level_arrays) == 2:
            arrays = combine_pixel_levels(*level_arrays, refinement=LEVEL_REFINEMENT)
        else:
            arrays, order_info = combine_three_pixel_levels(
                *level_arrays, refinement=LEVEL_REFINEMENT
            )
        for name in ERROR_FIELDS.values():
            extra[name] = arrays.pop(name)
        extra["levels"] = {
            **order_info,
            "pixel_size_m": np.array([float(j.texture.pixel_size_m) for j in level_jobs]),
            "full_contact_pressure_ratio": np.array(
                [j.full_contact_pressure_ratio for j in level_jobs]
            ),
            **{
                name: np.stack([a[name] for a in level_arrays])
                for name in level_arrays[0]
                if name != "residual"
            },
        }
    finest = level_jobs[-1]
    heights = np.asarray(texture.heights_m, dtype=float)
    mean_h0, mean_rec0 = unloaded_statistics(heights, settings.gap_floor_m)
    clearance = settings.clearance_m
    try:
        iso = iso25178_parameters(heights, texture.pixel_size_m, periodic=True)
    except InputError as exc:  # pragma: no cover - flat textures are rejected earlier
        log.warning("no ISO parameters for %s: %s", texture.name, exc)
        iso = {}
    attrs = {
        "max_iterations": int(settings.max_iterations),
        "chunk_size": int(settings.chunk_size),
        "checkpoint_key": ",".join(j.key for j in level_jobs),
        "solver_source_sha256": solver_source_sha256(),
        "points_not_converged": int(np.count_nonzero(~arrays["converged"])),
        "texture_detrend": texture.detrend,
        "pixel_levels": settings.pixel_levels,
    }
    if len(level_jobs) == 2:
        method = (
            "Richardson extrapolation to zero pixel size from two levels "
            "(solvers.lookup.combine_pixel_levels); error estimate = |correction| "
            "(order None: finest level kept, estimate = last change)"
        )
    else:
        method = (
            "Richardson extrapolation to zero pixel size from the two finest of three levels "
            "(solvers.lookup.combine_three_pixel_levels); error estimate = |difference of the "
            "successive extrapolants| where the observed order is within order_tolerance of "
            "the assumed one (/levels/three_level_estimate_* = 1), else the larger of that and "
            "the two-level |correction| (= 0); order None: finest level kept, estimate = last "
            "change"
        )
    if len(level_jobs) > 1:
        attrs["pixel_extrapolation_json"] = json.dumps(
            {
                "method": method,
                "levels": len(level_jobs),
                "order_tolerance": ORDER_TOLERANCE if len(level_jobs) > 2 else None,
                "level_pixel_size_m": [float(j.texture.pixel_size_m) for j in level_jobs],
                "level_grid_shape": [list(np.shape(j.texture.heights_m)) for j in level_jobs],
                "level_source": [j.texture.source for j in level_jobs],
                "refinement": LEVEL_REFINEMENT,
                "orders": PIXEL_EXTRAPOLATION_ORDERS,
                "flags_from": "finest level (full_contact, iterations); converged = all levels",
            },
            sort_keys=True,
        )
    table = MicroTable(
        name=texture.name,
        pixel_size_m=float(texture.pixel_size_m),
        grid_shape=tuple(int(v) for v in heights.shape),
        effective_modulus_pa=float(settings.effective_modulus_pa),
        gap_floor_m=float(settings.gap_floor_m),
        tol=float(settings.tol),
        pressure_ratio=settings.pressure_ratio,
        full_contact_pressure_ratio=float(finest.full_contact_pressure_ratio),
        unloaded_mean_gap_m=mean_h0,
        unloaded_mean_reciprocal_gap_per_m=mean_rec0,
        clearance_m=clearance,
        separated_mean_reciprocal_gap_per_m=separated_curve(heights, clearance),
        iso_parameters=iso,
        attrs=attrs,
        **arrays,
        **extra,
    )
    return table, diagnostics
