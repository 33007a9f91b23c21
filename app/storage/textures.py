"""Texture files: raw height maps (.npy, .csv) in, self-describing HDF5 textures in and out.

Texture file format (schema ``skisnow.texture/1``, HDF5):

- dataset ``heights_m`` — float64 heights h* [m] (gzip + shuffle), attrs ``unit = "m"``,
  ``axis0 = "x, along the ski (groove direction)"``, ``axis1 = "y, across the ski"``,
  ``pixel_size_m``;
- root attrs: ``schema``, ``name``, ``source``, ``pixel_size_m`` [m], ``missing_fraction`` [-],
  ``detrend`` (what was removed from the source heights: ``plane``, ``mean`` or ``none``;
  files written before it existed read as ``mean`` when synthetic, ``plane`` otherwise, which
  is what the code of that time did), ``shape``, the ISO 25178 parameters of the heights
  (``iso_<name>``, SI, unit in the name, gradients on the periodic grid if ``periodic`` is
  true), ``periodic``, everything from
  :func:`app.storage.common.provenance`, and any ``extra_attrs`` of the writer (generator
  parameters and seed for synthetic textures).

Raw height maps are converted to metres at this edge (``height_unit``: m, mm, um/µm, nm) and
detrended by :func:`solvers.texture.level_heights` (``detrend``: the least-squares plane by
default, or the mean, or nothing; the choice is kept in :attr:`Texture.detrend`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py
import numpy as np
from skisnow.solvers.errors import DataFileError, InputError
from skisnow.solvers.texture import (
    Texture,
    check_detrend,
    combined_detrend,
    iso25178_parameters,
    level_heights,
)

from .common import NPY_READ_ERRORS, atomic_path, provenance, sha256_file, tables_dir
from .heightgrid import height_factor, parse_csv_grid, pixel_size_m

__all__ = [
    "SCHEMA",
    "SHIPPED_TEXTURES_DIR",
    "detrend_texture",
    "list_shipped_textures",
    "read_heightmap",
    "read_texture",
    "refined_texture",
    "write_texture",
]

SCHEMA = "skisnow.texture/1"

#: Directory of the shipped (synthetic) textures
SHIPPED_TEXTURES_DIR = tables_dir() / "textures"


def _read_csv(path: Path) -> np.ndarray:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(f"cannot read height map {path}: {exc}") from exc
    return parse_csv_grid(text, f"height map {path}")


def _read_npy(path: Path) -> np.ndarray:
    try:
        arr = np.load(path, allow_pickle=False)
    except NPY_READ_ERRORS as exc:
        raise DataFileError(f"cannot read height map {path}: {exc}") from exc
    if not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
        raise DataFileError(f"height map {path} holds {arr.dtype} values, not real numbers")
    return arr.astype(np.float64)


def read_heightmap(
    path, *, pixel_size_um: float, height_unit: str, detrend: str = "plane"
) -> Texture:
    """Read a raw height map (``.npy`` or ``.csv``), convert it to metres and detrend it.

    Parameters
    ----------
    path : str or os.PathLike
        ``.npy`` (no pickles) or ``.csv`` (comma or whitespace separated; NaN or an empty cell
        for a missing point; ``#`` comment lines) with axis 0 along the ski.
    pixel_size_um : float
        Pixel size [µm].
    height_unit : str
        Unit of the stored heights: "m", "mm", "um" (or "µm"), "nm".
    detrend : str
        What to remove before solving: "plane" (default), "mean" or "none"
        (:func:`solvers.texture.level_heights`); recorded in :attr:`Texture.detrend`.

    Returns
    -------
    Texture
        Detrended, filled texture named after the file stem.

    Raises
    ------
    InputError
        Unknown unit or detrend, bad pixel size, or a map
        :func:`solvers.texture.level_heights` refuses.
    DataFileError
        Missing, unreadable, truncated or non-numeric file (the message names the file).
    """
    factor = height_factor(height_unit)
    dx = pixel_size_m(pixel_size_um)
    detrend = check_detrend(detrend)
    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"height map {path} does not exist")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        raw = _read_npy(path)
    elif suffix in (".csv", ".txt"):
        raw = _read_csv(path)
    else:
        raise InputError(f"height map {path}: unsupported extension {suffix!r}; use .npy or .csv")
    if raw.ndim != 2:
        raise DataFileError(f"height map {path} is {raw.ndim}-D; a 2-D grid is needed")
    try:
        heights, missing = level_heights(raw * factor, dx, detrend=detrend)
    except InputError as exc:
        raise InputError(f"height map {path}: {exc}") from None
    source = f"{path.name} (sha256 {sha256_file(path)})"
    return Texture(heights, dx, path.stem, missing, source, detrend)


def write_texture(texture: Texture, path, *, extra_attrs: dict | None = None, periodic=False):
    """Write a texture to a self-describing HDF5 file, atomically.

    Parameters
    ----------
    texture : Texture
        The texture (heights in metres).
    path : str or os.PathLike
        Destination ``.h5`` file; replaced only once fully written.
    extra_attrs : dict, optional
        More root attributes (e.g. generator parameters and seed); non-scalar values are
        stored as JSON text.
    periodic : bool
        Whether the texture is periodic (ISO gradients wrap around); stored as an attribute.
    """
    h = np.asarray(texture.heights_m, dtype=np.float64)
    if h.ndim != 2 or not np.isfinite(h).all():
        raise InputError("texture.heights_m must be a finite 2-D array")
    iso = iso25178_parameters(h, texture.pixel_size_m, periodic=periodic)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        ds = f.create_dataset(
            "heights_m",
            data=h,
            compression="gzip",
            compression_opts=6,
            shuffle=True,
            chunks=(min(256, h.shape[0]), min(256, h.shape[1])),
        )
        ds.attrs["unit"] = "m"
        ds.attrs["axis0"] = "x, along the ski (groove direction)"
        ds.attrs["axis1"] = "y, across the ski"
        ds.attrs["pixel_size_m"] = float(texture.pixel_size_m)
        attrs = f.attrs
        attrs["schema"] = SCHEMA
        attrs["name"] = texture.name
        attrs["source"] = texture.source
        attrs["pixel_size_m"] = float(texture.pixel_size_m)
        attrs["missing_fraction"] = float(texture.missing_fraction)
        attrs["detrend"] = check_detrend(texture.detrend)
        attrs["shape"] = np.array(h.shape, dtype=np.int64)
        attrs["periodic"] = bool(periodic)
        for key, value in iso.items():
            attrs[f"iso_{key}"] = value
        for key, value in provenance().items():
            attrs[key] = value
        for key, value in (extra_attrs or {}).items():
            if isinstance(value, str | int | float | bool | np.number):
                attrs[key] = value
            else:
                attrs[key] = json.dumps(value, sort_keys=True, default=str)


def read_texture(path) -> Texture:
    """Read a texture written by :func:`write_texture` (schema ``skisnow.texture/1``).

    Raises
    ------
    DataFileError
        Missing file, not HDF5, wrong schema, or missing/invalid datasets (names the file).
    """
    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"texture file {path} does not exist")
    try:
        with h5py.File(path, "r") as f:
            schema = f.attrs.get("schema")
            if isinstance(schema, bytes):
                schema = schema.decode()
            if schema != SCHEMA:
                raise DataFileError(
                    f"texture file {path} has schema {schema!r}, expected {SCHEMA!r}"
                )
            if "heights_m" not in f:
                raise DataFileError(f"texture file {path} has no 'heights_m' dataset")
            heights = np.asarray(f["heights_m"][...], dtype=np.float64)
            unit = f["heights_m"].attrs.get("unit")
            pixel = float(f.attrs["pixel_size_m"])
            name = str(f.attrs.get("name", path.stem))
            source = str(f.attrs.get("source", str(path)))
            missing = float(f.attrs.get("missing_fraction", 0.0))
            detrend = f.attrs.get("detrend")
            if isinstance(detrend, bytes):
                detrend = detrend.decode()
    except DataFileError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise DataFileError(f"texture file {path} is unreadable or corrupt: {exc}") from exc
    if unit != "m":
        raise DataFileError(f"texture file {path}: heights_m unit is {unit!r}, expected 'm'")
    if heights.ndim != 2 or min(heights.shape) < 2 or not np.isfinite(heights).all():
        raise DataFileError(f"texture file {path}: heights_m is not a finite 2-D grid")
    if not (np.isfinite(pixel) and pixel > 0):
        raise DataFileError(f"texture file {path}: pixel_size_m is {pixel!r}")
    if detrend is None:  # written before the attribute: what the writers of the time did
        detrend = "mean" if source.startswith("synthetic") else "plane"
    else:
        detrend = str(detrend)
        try:
            check_detrend(detrend)
        except InputError as exc:
            raise DataFileError(f"texture file {path}: {exc}") from None
    return Texture(heights, pixel, name, missing, source, detrend)


def list_shipped_textures() -> list[str]:
    """Names of the shipped textures (``tables/textures/<name>.h5``), sorted."""
    if not SHIPPED_TEXTURES_DIR.is_dir():
        return []
    return sorted(p.stem for p in SHIPPED_TEXTURES_DIR.glob("*.h5"))


def detrend_texture(texture: Texture, detrend: str | None) -> Texture:
    """A stored texture with ``detrend`` applied to its heights (``None``: kept as it is).

    The result's :attr:`Texture.detrend` is the combination of the stored detrending and
    this one (:func:`solvers.texture.combined_detrend`); its source says what was done. When
    the stored detrending already includes this one (the mean of a levelled texture), the
    texture is returned unchanged.
    """
    if detrend is None or combined_detrend(texture.detrend, detrend) == texture.detrend:
        return texture  # nothing to do: the stored detrending already includes this one
    heights, _ = level_heights(texture.heights_m, texture.pixel_size_m, detrend=detrend)
    return Texture(
        heights,
        texture.pixel_size_m,
        texture.name,
        texture.missing_fraction,
        f"{texture.source}; detrend={detrend} applied to the stored heights",
        combined_detrend(texture.detrend, detrend),
    )


def refined_texture(spec: str | os.PathLike, refine: int = 2) -> Texture:
    """The same synthetic surface as a stored texture on a ``refine``× finer grid.

    Reads the generator, its parameters and seed from the texture file (shipped name or
    ``.h5``; written by ``scripts/make_grinds.py``) and calls
    :func:`solvers.texture.linear_grind` with ``refine``. Checked: the block average of the
    refined map reproduces the stored heights to 1e-3 of their RMS, so it is the same patch
    and the same draws.

    Raises
    ------
    InputError
        The texture is not synthetic (no generator recorded): a measured map cannot be
        refined, only coarsened (``build-tables --pixel-levels coarsen``).
    """
    from skisnow.solvers.texture import GrindParameters, linear_grind

    spec_str = os.fspath(spec)
    path = (
        SHIPPED_TEXTURES_DIR / f"{spec_str}.h5"
        if spec_str in list_shipped_textures()
        else Path(spec_str)
    )
    base = read_texture(path)
    with h5py.File(path, "r") as f:
        generator = f.attrs.get("generator")
        if generator is None:
            raise InputError(
                f"texture {base.name!r} records no generator: only synthetic textures can be "
                "refined (use --pixel-levels coarsen for a measured map)"
            )
        generator = generator.decode() if isinstance(generator, bytes) else str(generator)
        # the name files record (scripts/make_grinds.py), and the import path since the one
        # `skisnow` namespace
        if generator not in (
            "solvers.texture.linear_grind",
            "skisnow.solvers.texture.linear_grind",
        ):
            raise InputError(f"texture {base.name!r}: unknown generator {generator!r}")
        params = GrindParameters(**json.loads(f.attrs["generator_parameters_json"]))
        seed = int(f.attrs["generator_seed"])
    fine = linear_grind(base.heights_m.shape, base.pixel_size_m, params, seed, refine=refine)
    n0, n1 = base.heights_m.shape
    coarse = fine.reshape(n0, refine, n1, refine).mean(axis=(1, 3))
    rms = float(np.sqrt(np.mean(base.heights_m**2)))
    deviation = float(np.max(np.abs(coarse - base.heights_m)))
    if deviation > 1e-3 * rms:
        raise InputError(
            f"texture {base.name!r}: its generator does not reproduce the stored heights "
            f"(block average off by {deviation:.3g} m, RMS height {rms:.3g} m)"
        )
    return Texture(
        fine,
        base.pixel_size_m / refine,
        base.name,
        base.missing_fraction,
        f"{base.source}; refined {refine}x (same generator, parameters and seed)",
        detrend=base.detrend,
    )
