"""``skisnow bench accuracy``: error against a converged reference versus time, for each stage.

Stages (issue #6 §2), each measured in the same run so that times compare as ratios:

- ``micro``: one texture solve at 256² … 4096² pixels on the **same 1.536 mm patch** (finer
  pixels on the same area, not a larger area). The grind is the shipped texture's surface
  refined to the finest grid (:func:`solvers.texture.linear_grind` with ``refine``: same
  parameters, seed and random draws); coarser grids are block averages of it (area-averaged
  pixels, as an interferometer records them), so 1024² is the shipped texture. Reference: the
  finest grid. The two-level value of the shipped tables (zero-pixel extrapolation from 1024²
  and 2048², :func:`solvers.lookup.combine_pixel_levels`) is compared with the limit from the
  finer grids (before: 1024² alone; after: the two-level value).
  Every metric of :class:`solvers.micro.MicroResult` is checked for convergence: the floored
  reciprocal gap should converge, the raw one (no floor) is expected not to (docs/physics.md §5).
- ``table``: PCHIP interpolation of the shipped 72-point tables and of tables thinned to fewer
  pressure points against direct solves of the same texture at off-grid pressures (and at the
  72-point nodes a thinned table leaves out).
- ``macro`` and ``end-to-end``: :func:`app.service.contact` (the computation of
  ``POST /v1/contact``) at candidate macro grids against a fine reference grid, on the same
  table; the named presets of :mod:`app.presets` are marked on the error-versus-time front.
- ``network``: the camber network of each ski against the beam model it learned, through the
  whole computation.
- ``shipped``: the shipped tables' own pixel-size error estimates over the partial-contact range
  (no solve; :mod:`app.evidence.accuracy_shipped`).

Results go to ``docs/bench/accuracy.json`` and charts ``docs/bench/accuracy-<stage>.png`` via
:func:`app.evidence.writer.write_stage`, which regenerates ``docs/benchmarks.md``.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

from skisnow.app.evidence.accuracy_common import (
    MICRO_E_EFF_PA,
    MICRO_METRICS,
    AccuracyConfig,
    convergence,
)
from skisnow.app.evidence.accuracy_e2e import bench_end_to_end, candidate_presets
from skisnow.app.evidence.accuracy_micro import bench_micro_grid
from skisnow.app.evidence.accuracy_network import bench_network
from skisnow.app.evidence.accuracy_shipped import bench_shipped
from skisnow.app.evidence.accuracy_table import bench_table
from skisnow.app.storage.common import provenance
from tqdm import tqdm

log = logging.getLogger(__name__)


def _work_items(cfg: AccuracyConfig) -> int:
    n = 0
    if "micro" in cfg.stages:
        n += len(cfg.micro_grinds) * len(cfg.micro_pressures_pa) * len(cfg.micro_sizes)
    if "table" in cfg.stages:
        n += len(cfg.table_grinds) * cfg.table_direct_points
    if "end-to-end" in cfg.stages:
        n += len(cfg.cases) * len(candidate_presets(cfg))
    if "network" in cfg.stages:
        n += len(cfg.network_skis) * len(cfg.network_loads_kg) * len(cfg.network_positions_mm)
    return n


def bench_accuracy(cfg: AccuracyConfig, progress: bool = True) -> dict:
    """Run the stages of ``cfg``; returns the JSON-ready result.

    Each stage's entry carries ``wall_time_s`` and ``measured`` (provenance and the config),
    so stages kept from an earlier run (``--stages``) still say when and how they were run.
    """
    data: dict = {"config": asdict(cfg), "micro_effective_modulus_pa": MICRO_E_EFF_PA}
    runners = {
        "micro": ("micro", "micro grid", bench_micro_grid),
        "table": ("table", "table vs direct", bench_table),
        "end-to-end": ("end_to_end", "macro grid / presets", bench_end_to_end),
        "network": ("network", "network vs beam", bench_network),
        "shipped": ("shipped", "shipped tables' estimates", bench_shipped),
    }
    with tqdm(total=_work_items(cfg), disable=not progress, desc="bench accuracy") as bar:
        for stage, (key, label, run) in runners.items():
            if stage not in cfg.stages:
                continue
            bar.set_postfix_str(label)
            t0 = time.perf_counter()
            data[key] = run(cfg, bar)
            data[key]["wall_time_s"] = time.perf_counter() - t0
            data[key]["measured"] = {**provenance(), "config": asdict(cfg)}
    return data


def keep_previous_stages(data: dict, previous: Path, stages_run: Sequence[str]) -> None:
    """Copy into ``data`` the stages of the ``previous`` run's JSON that this run left out
    (``--stages``), listed under ``kept_from_previous_run``; nothing if there is no such file.
    The micro stage's derived ``convergence`` follows the current classifier."""
    if not previous.is_file():
        return
    old = json.loads(previous.read_text())
    for stage in set(AccuracyConfig.stages) - set(stages_run):
        key = stage.replace("-", "_")
        if key in old:
            data[key] = old[key]
            if key == "micro":  # derived fields follow the current classifier
                for series in data[key]["series"]:
                    series["convergence"] = {
                        m: convergence([r[m] for r in series["rows"]]) for m in MICRO_METRICS
                    }
            data.setdefault("kept_from_previous_run", []).append(stage)
