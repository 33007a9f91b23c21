"""Named accuracy presets of the end-to-end computation (``POST /v1/contact``, ``preset``).

A preset fixes the discretisation settings that a request can trade for time; everything else
(the physics, the solver tolerances) is the same for every preset. The micro-scale table is not
part of a preset: it is built offline at the texture's pixel size, which every answer reports
in ``provenance.preset.texture_pixel_size_um`` beside the preset and the macro pixel sizes.

The presets were chosen on the error-versus-time front of ``skisnow bench accuracy``
(docs/benchmarks.md, "Macro grid spacing and end to end"): each is the fastest grid on the front
whose errors against a 0.5 mm × 64-pixels-across reference (same table) stay within its
tolerance (:data:`app.evidence.accuracy_common.PRESET_TOLERANCES`). ``max_rel_error`` is the largest
relative error measured there over the benchmark's cases, rounded up, of the apparent contact
area, total real contact area, average real contact pressure and total reciprocal separation;
tests use it as the documented agreement between presets (the minimum average separation is
not in it: in a short tip or tail contact it follows the edge-singular peak pressure). What an
answer reports instead is ``grid_band``, the 90th percentile of the measured errors per
quantity (the minimum separation included); the error band (:func:`app.service.band.grid_component`)
scales it for the real area, real pressure and reciprocal separation and replaces it by
per-answer estimates for the apparent area and minimum separation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from skisnow.solvers.macro import DEFAULT_PIXEL_ACROSS, DEFAULT_PIXEL_ALONG_M

__all__ = ["DEFAULT_PRESET", "PRESETS", "Preset", "get_preset"]


@dataclass(frozen=True)
class Preset:
    """Discretisation settings of one named preset.

    Attributes
    ----------
    name : str
        Preset name as given in a request.
    pixel_along_m : float
        Macro BEM pixel size along the ski [m].
    pixels_across : int
        Macro BEM pixels across the ski's widest point [-].
    max_rel_error : float
        Largest relative error of the reported metrics against the converged reference,
        measured by ``skisnow bench accuracy`` [-].
    description : str
        One line for the docs and the OpenAPI schema.
    grid_band : dict
        Relative 90 % half-width of each reported quantity from the macro grid [-]: the 90th
        percentile of the absolute relative errors against the reference over the 12 cases of
        ``skisnow bench accuracy`` (docs/bench/accuracy.json, ``end_to_end``), rounded up;
        scaled into every answer's error band for the quantities without a per-answer
        estimate (:func:`app.service.band.grid_component`).
    """

    name: str
    pixel_along_m: float
    pixels_across: int
    max_rel_error: float
    description: str
    grid_band: dict = field(default_factory=dict)

    def provenance(self) -> dict:
        """The preset in technician units for an answer's provenance."""
        return {
            "name": self.name,
            "macro_pixel_along_mm": self.pixel_along_m * 1e3,
            "macro_pixels_across": self.pixels_across,
            "grid_band_90": dict(self.grid_band),
        }


def _band(apparent, real_area, pressure, min_sep, reciprocal) -> dict[str, float]:
    return {
        "apparent_contact_area": apparent,
        "total_real_contact_area": real_area,
        "average_real_contact_pressure": pressure,
        "min_average_separation": min_sep,
        "total_reciprocal_separation": reciprocal,
    }


PRESETS: dict[str, Preset] = {
    "fast": Preset(
        "fast",
        pixel_along_m=8e-3,
        pixels_across=4,
        max_rel_error=0.12,
        description="8 mm × 4 across (11 mm): previews and sweeps, about 1.3× faster; the "
        "apparent area of short tip/tail contacts is off by up to ~20 %",
        grid_band=_band(0.108, 0.015, 0.014, 0.068, 0.028),
    ),
    "default": Preset(
        "default",
        pixel_along_m=DEFAULT_PIXEL_ALONG_M,
        pixels_across=DEFAULT_PIXEL_ACROSS,
        max_rel_error=0.025,
        description="4 mm × 8 across (5.5 mm): the default; 90 % of the benchmark's cases "
        "within 1.6 % of the reference (minimum separation 6.5 %)",
        grid_band=_band(0.021, 0.009, 0.009, 0.053, 0.018),
    ),
    "fine": Preset(
        "fine",
        pixel_along_m=1e-3,
        pixels_across=16,
        max_rel_error=0.01,
        description="1 mm × 16 across (2.75 mm): for comparisons closer than 1 % (1.5 % for "
        "the apparent area of a short tip/tail contact)",
        grid_band=_band(0.008, 0.006, 0.006, 0.020, 0.008),
    ),
}

#: preset used when a request names none
DEFAULT_PRESET = "default"


def get_preset(name: str, presets: dict[str, Preset] | None = None) -> Preset:
    """The preset called ``name``.

    Raises
    ------
    solvers.errors.InputError
        Unknown name; the message names the field and the known presets.
    """
    from skisnow.solvers.errors import InputError

    table = PRESETS if presets is None else presets
    try:
        return table[name]
    except (KeyError, TypeError):
        raise InputError(f"preset must be one of {', '.join(table)}, got {name!r}") from None
