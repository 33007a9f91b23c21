"""The catalogue of skis and grinds the service answers for: shipped tables and demo skis
(:func:`load_catalogue`), each ski with its profile model, each grind with its micro table.

Imports: :mod:`app.service` siblings, ``storage``, ``solvers`` and the shared top-level modules.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from skisnow.app.service.profiles import (
    LOAD_EXTRAPOLATION_FACTOR,
    no_beam_reason,
    profile_model,
    served_beam,
)
from skisnow.app.storage.common import sha256_file
from skisnow.app.storage.skis import (
    SKI_MANIFEST,
    SkiRecord,
    read_ski,
    read_ski_manifest,
)
from skisnow.app.storage.tables import read_manifest, read_table
from skisnow.solvers.beam import BeamSki
from skisnow.solvers.errors import DataFileError, SkisnowError
from skisnow.solvers.flexible import FlexibleModel, prepare_flexible
from skisnow.solvers.lookup import MicroTable

log = logging.getLogger(__name__)


class UnknownItemError(LookupError):
    """A ski or grind name that the catalogue does not hold (HTTP 404)."""

    def __init__(self, kind: str, name: str, known: list[str]) -> None:
        super().__init__(f"unknown {kind} {name!r}; known: {', '.join(known) or 'none'}")
        self.kind = kind
        self.name = name
        self.known = known


class ModelUnavailableError(SkisnowError):
    """The requested ski model cannot be used for this ski (HTTP 422, the message says why)."""


#: ski models a request can ask for (docs/physics.md §4 step 3 and §4b)
SKI_MODELS = ("rigid", "flexible", "auto")
#: an identified beam answers loads up to this × the heaviest measured load (the one rule:
#: :class:`app.service.profiles.ProfileModel.load_range_n`; docs/camber-network.md)
BEAM_LOAD_FACTOR = LOAD_EXTRAPOLATION_FACTOR
#: ``auto`` answers with the rigid shape when every compared quantity is within this of the
#: flexible solve [-]
AUTO_RIGID_TOLERANCE = 0.02


@dataclass
class Grind:
    name: str
    path: Path
    sha256: str
    table: MicroTable


@dataclass
class Ski:
    name: str
    path: Path
    sha256: str
    record: SkiRecord
    _flexible: dict = field(default_factory=dict, repr=False)

    def beam(self) -> tuple[BeamSki | None, str]:
        """The ski's beam model and where it comes from; or (None, why there is none).

        A beam identified from the ski's camber measurements (docs/physics.md §4c) that passed the
        held-out check comes first: the demo skis and uploaded skis alike. A design beam stored
        with the ski (the demo skis' truth) is the fallback.
        """
        ident = self.record.identified
        beam = served_beam(ident)
        if beam is not None:
            a = ident["attrs"]
            held = float(a.get("held_out_rms_m", float("nan")))
            held_txt = (
                f", {a.get('held_out_cases', 0)} held-out cases {held * 1e6:.2f} µm RMS"
                if math.isfinite(held)
                else ""
            )
            return (
                beam,
                f"identified from the camber data (misfit {a['misfit_m'] * 1e6:.2f} µm against "
                f"device noise {a['noise_m'] * 1e6:.2f} µm{held_txt})",
            )
        if self.record.beam is not None:
            return (
                self.record.beam,
                "design beam stored with the ski (demo ski: its own beam)",
            )
        why = no_beam_reason(ident)
        return None, f"ski {self.name!r} has no beam model ({why}); use ski_model 'rigid'"

    @property
    def beam_is_design(self) -> bool:
        """The beam :meth:`beam` answers with is the design beam stored with the ski."""
        return served_beam(self.record.identified) is None and self.record.beam is not None

    def flexible_model(self, pixel_along_m: float, pixels_across: int) -> FlexibleModel:
        """The prepared flexible model on a preset's grid (built once per worker)."""
        key = (float(pixel_along_m), int(pixels_across))
        model = self._flexible.get(key)
        if model is None:
            beam, why = self.beam()
            if beam is None:
                raise ModelUnavailableError(why)
            outline = self.record.outline
            model = prepare_flexible(
                beam,
                outline.width_m,
                pixel_along_m=pixel_along_m,
                pixels_across=pixels_across,
                width_positions_m=outline.positions_m,
            )
            self._flexible[key] = model
        return model

    def _covered(self, lo_key: str, hi_key: str, measured: np.ndarray) -> tuple[float, float]:
        """The range of the measured load cases for an identified beam, else the network's
        trained range (attributes ``lo_key``, ``hi_key``), else the measured range."""
        net = self.record.network
        if profile_model(self.record).source != "identified_beam" and net and "attrs" in net:
            a = net["attrs"]
            lo, hi = a.get(lo_key), a.get(hi_key)
            if lo is not None and hi is not None:
                return float(lo), float(hi)
        v = np.asarray(measured, dtype=float)
        return float(v.min()), float(v.max())

    @property
    def load_range_n(self) -> tuple[float, float]:
        """Loads the ski's camber model covers [N]: the one rule of
        :attr:`app.service.profiles.ProfileModel.load_range_n` (an identified beam that passed
        answers up to :data:`BEAM_LOAD_FACTOR` × the heaviest measured load, whichever model
        serves inside; lighter loads than measured are refused)."""
        return profile_model(self.record).load_range_n

    @property
    def position_range_m(self) -> tuple[float, float]:
        """Load positions the ski's camber model covers [m]."""
        return self._covered(
            "load_position_min_m",
            "load_position_max_m",
            self.record.measurements.load_positions_m,
        )


@dataclass
class Catalogue:
    """Skis and grinds loaded once per worker and verified against their manifests."""

    tables_dir: Path
    skis: dict[str, Ski] = field(default_factory=dict)
    grinds: dict[str, Grind] = field(default_factory=dict)

    def ski(self, name: str) -> Ski:
        try:
            return self.skis[name]
        except KeyError:
            raise UnknownItemError("ski", name, sorted(self.skis)) from None

    def grind(self, name: str) -> Grind:
        try:
            return self.grinds[name]
        except KeyError:
            raise UnknownItemError("grind", name, sorted(self.grinds)) from None


def _verify(path: Path, expected_sha: str | None) -> str:
    if not path.is_file():
        raise DataFileError(f"file listed in the manifest is missing: {path}")
    sha = sha256_file(path)
    if expected_sha is not None and sha != expected_sha:
        raise DataFileError(f"{path}: sha256 {sha[:12]}… does not match the manifest")
    return sha


def load_catalogue(tables_dir: str | Path) -> Catalogue:
    """Load and verify every table (``tables_dir/*.h5``) and ski (``tables_dir/skis/*.h5``).

    Raises
    ------
    DataFileError
        A manifest or a file is missing, corrupt, or does not match its checksum; the message
        names the file.
    """
    tables_dir = Path(tables_dir)
    cat = Catalogue(tables_dir=tables_dir)
    manifest = read_manifest(tables_dir)
    for fname, entry in sorted(manifest["files"].items()):
        path = tables_dir / fname
        sha = _verify(path, entry.get("sha256"))
        table = read_table(path)
        cat.grinds[table.name] = Grind(table.name, path, sha, table)
    ski_dir = tables_dir / "skis"
    ski_manifest = read_ski_manifest(ski_dir)
    for fname, entry in sorted(ski_manifest["files"].items()):
        path = ski_dir / fname
        sha = _verify(path, entry.get("sha256"))
        record = read_ski(path)
        name = Path(fname).stem
        cat.skis[name] = Ski(name, path, sha, record)
    if not cat.grinds:
        raise DataFileError(f"no texture tables listed in {tables_dir / 'manifest.json'}")
    if not cat.skis:
        raise DataFileError(f"no skis listed in {ski_dir / SKI_MANIFEST}")
    return cat
