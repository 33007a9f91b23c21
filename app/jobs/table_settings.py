"""Settings of a table build and the key of its checkpoints (:mod:`app.jobs.table_build`).

The key is a sha256 over everything a table point depends on: a stale checkpoint is never
reused. Imports ``storage`` and ``solvers``.
"""

from __future__ import annotations

import hashlib
import inspect
import re
from dataclasses import asdict, dataclass

import numpy as np
from skisnow.app.storage.common import code_version
from skisnow.app.storage.tables import (
    PIXEL_LEVEL_MODES,
)
from skisnow.solvers import elastic as _elastic
from skisnow.solvers import lookup as _lookup
from skisnow.solvers import micro as _micro
from skisnow.solvers.errors import InputError
from skisnow.solvers.lookup import (
    chunk_bounds,
    pressure_ratio_grid,
)
from skisnow.solvers.micro import DEFAULT_GAP_FLOOR_M
from skisnow.solvers.texture import Texture

__all__ = ["BuildSettings", "checkpoint_key", "solver_source_sha256"]

#: a texture name usable in file names
NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


@dataclass(frozen=True)
class BuildSettings:
    """Settings of a table build (every one recorded in the file).

    Attributes
    ----------
    points : int
        Points of the pressure-ratio grid [-].
    ratio_min, ratio_max : float
        Ends of the log grid of ``P_n / E'`` [-].
    chunk_size : int
        Consecutive grid points per task [-].
    tol : float
        Solver tolerance [-].
    max_iterations : int
        Solver iteration cap [-].
    gap_floor_m : float
        Gap floor h_c of the floored mean reciprocal gap [m].
    effective_modulus_pa : float
        E' of the solves [Pa] (results depend only on ``P_n / E'``).
    clearance_min_m, clearance_max_m : float
        Ends of the log grid of clearances of the separated curve [m].
    clearance_points : int
        Points of the clearance grid [-].
    pixel_levels : str
        ``"none"`` (the texture's grid only), ``"refine"`` (plus the same synthetic surface
        at half the pixel size), ``"refine3"`` (plus the surface at a half and a quarter of
        the pixel size) or ``"coarsen"`` (plus the texture at twice the pixel size); the
        levels are extrapolated to zero pixel size with a per-point error estimate.
    """

    points: int = 48
    ratio_min: float = 1e-8
    ratio_max: float = 1e-1
    chunk_size: int = 4
    tol: float = 1e-6
    max_iterations: int = 2000
    gap_floor_m: float = DEFAULT_GAP_FLOOR_M
    effective_modulus_pa: float = 1e8
    clearance_min_m: float = 1e-8
    clearance_max_m: float = 1e-2
    clearance_points: int = 64
    pixel_levels: str = "none"

    def __post_init__(self) -> None:
        if self.pixel_levels not in PIXEL_LEVEL_MODES:
            raise InputError(
                f"pixel_levels must be one of {PIXEL_LEVEL_MODES}, got {self.pixel_levels!r}"
            )
        pressure_ratio_grid(self.ratio_min, self.ratio_max, self.points)
        pressure_ratio_grid(self.clearance_min_m, self.clearance_max_m, self.clearance_points)
        chunk_bounds(self.points, self.chunk_size)
        for name in ("tol", "gap_floor_m", "effective_modulus_pa"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"{name} must be finite and > 0, got {value!r}")
        if int(self.max_iterations) != self.max_iterations or self.max_iterations < 1:
            raise InputError(f"max_iterations must be an integer >= 1, got {self.max_iterations}")

    @property
    def pressure_ratio(self) -> np.ndarray:
        """The grid of ``P_n / E'`` [-]."""
        return pressure_ratio_grid(self.ratio_min, self.ratio_max, self.points)

    @property
    def clearance_m(self) -> np.ndarray:
        """The clearance grid of the separated curve [m]."""
        return pressure_ratio_grid(
            self.clearance_min_m, self.clearance_max_m, self.clearance_points
        )


def solver_source_sha256() -> str:
    h = hashlib.sha256()
    for module in (_micro, _elastic):
        h.update(inspect.getsource(module).encode())
    h.update(inspect.getsource(_lookup.solve_table_chunk).encode())
    return h.hexdigest()


def checkpoint_key(texture: Texture, settings: BuildSettings) -> str:
    """Hash of everything a chunk result depends on (stale checkpoints never match)."""
    heights = np.ascontiguousarray(texture.heights_m, dtype=np.float64)
    h = hashlib.sha256()
    h.update(f"{heights.shape}".encode())
    h.update(heights.tobytes())
    h.update(f"{float(texture.pixel_size_m)!r}".encode())
    h.update(settings.pressure_ratio.tobytes())
    for key, value in sorted(asdict(settings).items()):
        h.update(f"{key}={value!r};".encode())
    h.update(code_version().encode())
    h.update(solver_source_sha256().encode())
    return h.hexdigest()
