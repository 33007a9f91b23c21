"""Named accuracy presets of the end-to-end computation (``POST /v1/contact``, ``preset``).

A preset fixes the discretisation settings that a request can trade for time; everything else
(the physics, the solver tolerances) is the same for every preset. The micro-scale table is not
part of a preset: it is built offline at the texture's pixel size, which every answer reports
in ``provenance.preset.texture_pixel_size_um`` beside the preset and the macro pixel sizes.

The presets were chosen on the error-versus-time front of ``skisnow bench accuracy``
(docs/benchmarks.md, "Macro grid spacing and end to end"): each is the fastest grid on the front
whose errors against a 0.5 mm × 64-pixels-across reference (same table) stay within its
tolerance (:data:`app.bench_accuracy.PRESET_TOLERANCES`). ``max_rel_error`` is the largest
relative error measured there over the benchmark's cases, rounded up, of the apparent contact
area, total real contact area, average real contact pressure and total reciprocal separation;
tests use it as the documented agreement between presets. The minimum average separation is
not covered: where it sits in a short tip or tail contact it follows the edge-singular peak
pressure and does not converge with the macro grid (reported with the pixel size instead).
"""

from __future__ import annotations

from dataclasses import dataclass

from solvers.macro import DEFAULT_PIXEL_ACROSS, DEFAULT_PIXEL_ALONG_M

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
    """

    name: str
    pixel_along_m: float
    pixels_across: int
    max_rel_error: float
    description: str

    def provenance(self) -> dict:
        """The preset in technician units for an answer's provenance."""
        return {
            "name": self.name,
            "macro_pixel_along_mm": self.pixel_along_m * 1e3,
            "macro_pixels_across": self.pixels_across,
            "max_rel_error": self.max_rel_error,
        }


PRESETS: dict[str, Preset] = {
    "fast": Preset(
        "fast",
        pixel_along_m=8e-3,
        pixels_across=4,
        max_rel_error=0.12,
        description="8 mm × 4 across (11 mm): previews and sweeps, about 1.5× faster; the "
        "apparent area of short tip/tail contacts is off by up to ~12 %",
    ),
    "default": Preset(
        "default",
        pixel_along_m=DEFAULT_PIXEL_ALONG_M,
        pixels_across=DEFAULT_PIXEL_ACROSS,
        max_rel_error=0.025,
        description="4 mm × 8 across (5.5 mm): the default, within 2.5 % of the reference",
    ),
    "fine": Preset(
        "fine",
        pixel_along_m=1e-3,
        pixels_across=16,
        max_rel_error=0.01,
        description="1 mm × 16 across (2.75 mm): for comparisons closer than 1 %",
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
    from solvers.errors import InputError

    table = PRESETS if presets is None else presets
    try:
        return table[name]
    except (KeyError, TypeError):
        raise InputError(f"preset must be one of {', '.join(table)}, got {name!r}") from None
