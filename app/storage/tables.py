"""Micro-scale table files (HDF5), their manifest, and the build checkpoints.

File layout of a table (schema ``skisnow.table/1``; docs/tables.md has the full list):

- root attributes: ``schema``, ``name``, ``pixel_size_m``, ``grid_shape``, ``effective_modulus_pa``,
  ``gap_floor_m``, ``tol``, ``full_contact_pressure_ratio``, ``full_contact_reached``,
  ``unloaded_mean_gap_m``, ``unloaded_mean_reciprocal_gap_per_m``, ``data_sha256`` and the
  provenance of :func:`app.storage.common.provenance` (code version, git commit, command line,
  creation time, parameters);
- ``/texture/heights_m`` [m] with the texture's ISO 25178 parameters as attributes;
- ``/loaded/*``: the table over the pressure ratio ``P_n/E'``;
- ``/loaded/*_error*``: per-point error estimates against the zero-pixel limit and
  ``/levels/*``: per-level values (tables of two or three levels only; optional, absent in
  tables built on one pixel size, which read with ``None`` estimates); ``/levels/adaptive_*``:
  the adaptive fourth level at the nodes that have it (optional);
- ``/separated/*``: ``⟨1/(h_0 + H)⟩`` over the clearance H;
- ``/diagnostics/solve_time_s``: wall time per point (not part of ``data_sha256``).

Every dataset carries ``units`` (UDUNITS spelling, ``"1"`` for dimensionless) and
``description`` attributes. ``data_sha256`` hashes every numeric dataset and numeric metadata
that define the table (not the time, command line or commit), so two builds of the same inputs
have the same ``data_sha256`` whatever the scheduling.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from pathlib import Path

import h5py
import numpy as np
from skisnow.solvers.errors import DataFileError
from skisnow.solvers.lookup import (
    ADAPTIVE_LEVEL_PREFIX,
    ERROR_FIELDS,
    LIGHT_LOAD_PREFIX,
    TABLE_SCHEMA,
    MicroTable,
)

from .common import atomic_path, provenance, read_json_manifest, sha256_file

__all__ = [
    "MANIFEST_NAME",
    "MANIFEST_SCHEMA",
    "read_checkpoint",
    "read_manifest",
    "read_table",
    "read_table_extras",
    "read_table_heights",
    "table_data_sha256",
    "verify_manifest",
    "write_checkpoint",
    "write_manifest",
    "write_table",
]

log = logging.getLogger(__name__)

MANIFEST_NAME = "manifest.json"
MANIFEST_SCHEMA = "skisnow.manifest/1"
CHECKPOINT_SCHEMA = "skisnow.table-chunk/1"

#: (dataset, units, description) of the /loaded group, in file order
LOADED_DATASETS = [
    ("pressure_ratio", "1", "nominal pressure over effective modulus P_n/E'"),
    ("real_contact_area_fraction", "1", "a_r = |omega_c|/|omega| (docs/physics.md eq. 3)"),
    ("mean_gap_m", "m", "mean gap over the cell (docs/physics.md eq. 4, H = 0)"),
    (
        "mean_reciprocal_gap_per_m",
        "1/m",
        "mean over the gap set of 1/max(h_n, h_c), h_c = attribute gap_floor_m (eq. 5, n = 0)",
    ),
    ("mean_reciprocal_gap_raw_per_m", "1/m", "mean over the gap set of 1/h_n, no floor"),
    ("iterations", "1", "solver iterations on the finest grid (0: not solved, full contact)"),
    ("residual", "1", "final solver residual (RMS gap on the contact set over RMS height)"),
    ("converged", "1", "solver met the tolerance"),
    ("full_contact", "1", "point at or above the full-contact ratio: exact a_r = 1, gap 0"),
]
#: (dataset, units, description) of the optional error estimates in /loaded
ERROR_DATASETS = [
    (
        "real_contact_area_fraction_error",
        "1",
        "estimated error of real_contact_area_fraction against the zero-pixel limit",
    ),
    ("mean_gap_error_m", "m", "estimated error of mean_gap_m against the zero-pixel limit"),
    (
        "mean_reciprocal_gap_error_per_m",
        "1/m",
        "estimated error of mean_reciprocal_gap_per_m against the zero-pixel limit",
    ),
]
#: units of the optional per-level datasets in /levels (first axis: level, coarse first)
LEVEL_UNITS = {
    "pixel_size_m": "m",
    "full_contact_pressure_ratio": "1",
    "real_contact_area_fraction": "1",
    "mean_gap_m": "m",
    "mean_reciprocal_gap_per_m": "1/m",
    "mean_reciprocal_gap_raw_per_m": "1/m",
    "iterations": "1",
    "converged": "1",
    "full_contact": "1",
    # three-level tables, per quantity q (solvers.lookup.combine_three_pixel_levels)
    **{f"observed_order_{q}": "1" for q in ERROR_FIELDS},
    **{f"three_level_estimate_{q}": "1" for q in ERROR_FIELDS},
    "residual": "1",
}


def _level_units(name: str) -> str:
    """Units of a /levels dataset; ``adaptive_*`` (the fourth level) and ``light_*`` (the
    light-load levels) as their base name."""
    prefix = _extra_level_prefix(name)
    if prefix:
        base = name[len(prefix) :]
        for prefix in ("previous_", "selected_by_"):
            base = base.removeprefix(prefix)
        errors = {err: units for err, units, _ in ERROR_DATASETS}
        if base in errors:
            return errors[base]
        return "1" if base in ("node", "pressure_ratio") else LEVEL_UNITS.get(base, "1")
    return LEVEL_UNITS.get(name, "1")


SEPARATED_DATASETS = [
    ("clearance_m", "m", "clearance H between the texture's highest point and the snow"),
    (
        "separated_mean_reciprocal_gap_per_m",
        "1/m",
        "<1/(h_0 + H)> over the whole cell, h_0 = max h - h (P = 0, n = 0)",
    ),
]
#: numeric scalar fields that define a table (hashed into data_sha256)
_SCALAR_FIELDS = [
    "pixel_size_m",
    "effective_modulus_pa",
    "gap_floor_m",
    "tol",
    "full_contact_pressure_ratio",
    "unloaded_mean_gap_m",
    "unloaded_mean_reciprocal_gap_per_m",
]
_TYPED_ATTRS = {"schema", "name", "grid_shape", "full_contact_reached", *_SCALAR_FIELDS}


def _extra_level_prefix(name: str) -> str:
    """The prefix of the extra levels' entries in /levels (fourth level, light loads) or ""."""
    for prefix in (ADAPTIVE_LEVEL_PREFIX, LIGHT_LOAD_PREFIX):
        if name.startswith(prefix):
            return prefix
    return ""


def _dtype(name: str):
    prefix = _extra_level_prefix(name)
    if prefix:  # the extra levels' entries in /levels
        name = name[len(prefix) :]
        if name == "node":
            return np.int64
        if name.startswith("selected_by_"):
            return np.bool_
    if name == "iterations":
        return np.int64
    if name in ("converged", "full_contact"):
        return np.bool_
    return np.float64


def table_data_sha256(table: MicroTable) -> str:
    """sha256 over the numbers that define a table (arrays and numeric metadata).

    Scheduling, time, command line and commit do not enter, so two builds of the same inputs
    hash equal (the comparison used by tests and the manifest).
    """
    h = hashlib.sha256(TABLE_SCHEMA.encode())
    for name, _, _ in LOADED_DATASETS + SEPARATED_DATASETS:
        arr = np.ascontiguousarray(getattr(table, name), dtype=_dtype(name))
        h.update(f"{name}:{arr.dtype.str}:{arr.shape}".encode())
        h.update(arr.tobytes())
    for name in _SCALAR_FIELDS:
        h.update(f"{name}:{float(getattr(table, name))!r}".encode())
    h.update(f"grid_shape:{tuple(int(v) for v in table.grid_shape)}".encode())
    # optional two-level data: hashed only when present (one-level tables keep their hash)
    for name, _, _ in ERROR_DATASETS:
        if getattr(table, name) is not None:
            arr = np.ascontiguousarray(getattr(table, name), dtype=np.float64)
            h.update(f"{name}:{arr.dtype.str}:{arr.shape}".encode())
            h.update(arr.tobytes())
    for name, value in sorted((table.levels or {}).items()):
        arr = np.ascontiguousarray(value, dtype=_dtype(name))
        h.update(f"levels/{name}:{arr.dtype.str}:{arr.shape}".encode())
        h.update(arr.tobytes())
    return h.hexdigest()


def _json_safe(value):
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def write_table(
    path: str | os.PathLike,
    table: MicroTable,
    *,
    heights_m: np.ndarray | None = None,
    texture_attrs: dict | None = None,
    diagnostics: dict[str, np.ndarray] | None = None,
    parameters: dict | None = None,
) -> Path:
    """Write a table atomically (temporary file beside ``path``, renamed when complete).

    Parameters
    ----------
    path : path-like
        Destination ``.h5`` file.
    table : MicroTable
        The table; ``table.attrs`` are written as root attributes after the provenance.
    heights_m : ndarray, optional
        Texture heights [m] stored in ``/texture/heights_m``.
    texture_attrs : dict, optional
        Extra attributes of ``/texture`` (source, missing fraction, ...).
    diagnostics : dict of ndarray, optional
        Non-deterministic per-point data (e.g. ``solve_time_s``) for ``/diagnostics``.
    parameters : dict, optional
        Build parameters recorded by :func:`~app.storage.common.provenance`.

    Returns
    -------
    Path
        The final path.
    """
    path = Path(path)
    attrs = provenance(parameters)
    attrs.update({k: _json_safe(v) for k, v in table.attrs.items() if k not in _TYPED_ATTRS})
    with atomic_path(path) as tmp, h5py.File(tmp, "w", track_order=True) as f:
        for key, value in attrs.items():
            f.attrs[key] = value
        f.attrs["schema"] = TABLE_SCHEMA
        f.attrs["name"] = table.name
        f.attrs["grid_shape"] = np.asarray(table.grid_shape, dtype=np.int64)
        f.attrs["full_contact_reached"] = table.full_contact_reached
        for name in _SCALAR_FIELDS:
            f.attrs[name] = float(getattr(table, name))
        f.attrs["data_sha256"] = table_data_sha256(table)
        f.attrs["units_json"] = json.dumps(
            {
                "pixel_size_m": "m",
                "effective_modulus_pa": "Pa",
                "gap_floor_m": "m",
                "tol": "1",
                "full_contact_pressure_ratio": "1",
                "unloaded_mean_gap_m": "m",
                "unloaded_mean_reciprocal_gap_per_m": "1/m",
            }
        )
        tex = f.create_group("texture")
        tex.attrs["pixel_size_m"] = float(table.pixel_size_m)
        tex.attrs["axis_0"] = "x, along the ski (groove direction) [m]"
        tex.attrs["axis_1"] = "y, across the ski [m]"
        for key, value in (texture_attrs or {}).items():
            tex.attrs[key] = _json_safe(value)
        for key, value in table.iso_parameters.items():
            tex.attrs[f"iso_{key}"] = float(value)
        if heights_m is not None:
            ds = tex.create_dataset(
                "heights_m",
                data=np.asarray(heights_m, dtype=np.float64),
                compression="gzip",
                compression_opts=4,
                shuffle=True,
                track_times=False,
            )
            ds.attrs["units"] = "m"
            ds.attrs["description"] = "texture heights h*, levelled, peaks towards the snow"
        for group, specs in (("loaded", LOADED_DATASETS), ("separated", SEPARATED_DATASETS)):
            g = f.create_group(group)
            for name, units, description in specs:
                ds = g.create_dataset(
                    name,
                    data=np.asarray(getattr(table, name), dtype=_dtype(name)),
                    track_times=False,
                )
                ds.attrs["units"] = units
                ds.attrs["description"] = description
        for name, units, description in ERROR_DATASETS:
            if getattr(table, name) is not None:
                ds = f["loaded"].create_dataset(
                    name, data=np.asarray(getattr(table, name), np.float64), track_times=False
                )
                ds.attrs["units"] = units
                ds.attrs["description"] = description
        if table.levels:
            g = f.create_group("levels")
            g.attrs["description"] = (
                "per-level results of a table of several pixel levels (first axis: level, "
                "coarse first; observed_order_* and three_level_estimate_* per point); the "
                "/loaded values are their zero-pixel extrapolation. adaptive_*: the fourth "
                "level at half the finest pixel, at the nodes adaptive_node only (one value "
                "per node), which are recombined from their three finest levels "
                "(solvers.lookup.with_fourth_level). light_*: the light-load levels, each "
                "half the pixel of the one before (first axis: extra level, coarse first; "
                "second: the nodes light_node), at which the table is recombined from the "
                "three finest levels (solvers.lookup.with_light_load_levels)"
            )
            for name, value in table.levels.items():
                ds = g.create_dataset(
                    name, data=np.asarray(value, dtype=_dtype(name)), track_times=False
                )
                ds.attrs["units"] = _level_units(name)
        f["loaded/mean_reciprocal_gap_per_m"].attrs["gap_floor_m"] = float(table.gap_floor_m)
        f["separated"].attrs["unloaded_mean_gap_m"] = float(table.unloaded_mean_gap_m)
        diag = f.create_group("diagnostics")
        for name, arr in (diagnostics or {}).items():
            ds = diag.create_dataset(name, data=np.asarray(arr), track_times=False)
            ds.attrs["units"] = "s" if name.endswith("_s") else "1"
    return path


def read_table(path: str | os.PathLike) -> MicroTable:
    """Read and validate a table file.

    Raises
    ------
    DataFileError
        The file is missing, truncated, corrupt, of another schema, or inconsistent; the
        message names the file.
    """
    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"table file not found: {path}")
    try:
        with h5py.File(path, "r") as f:
            schema = _json_safe(f.attrs.get("schema"))
            if schema != TABLE_SCHEMA:
                raise DataFileError(
                    f"{path}: unsupported schema {schema!r}, expected {TABLE_SCHEMA!r}"
                )
            fields = {
                name: np.asarray(f["loaded"][name][()], dtype=_dtype(name))
                for name, _, _ in LOADED_DATASETS
            }
            for name, _, _ in SEPARATED_DATASETS:
                fields[name] = np.asarray(f["separated"][name][()], dtype=np.float64)
            for name, _, _ in ERROR_DATASETS:  # absent in one-level (older) tables
                if name in f["loaded"]:
                    fields[name] = np.asarray(f["loaded"][name][()], dtype=np.float64)
            if "levels" in f:
                fields["levels"] = {
                    name: np.asarray(ds[()], dtype=_dtype(name)) for name, ds in f["levels"].items()
                }
            for name in _SCALAR_FIELDS:
                fields[name] = float(f.attrs[name])
            iso = {
                key[4:]: float(value)
                for key, value in f["texture"].attrs.items()
                if key.startswith("iso_")
            }
            attrs = {k: _json_safe(v) for k, v in f.attrs.items() if k not in _TYPED_ATTRS}
            table = MicroTable(
                name=str(_json_safe(f.attrs["name"])),
                grid_shape=tuple(int(v) for v in f.attrs["grid_shape"]),
                iso_parameters=iso,
                attrs=attrs,
                **fields,
            )
    except DataFileError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise DataFileError(f"{path}: unreadable or incomplete table file ({exc})") from exc
    stored = attrs.get("data_sha256")
    if stored is not None and stored != table_data_sha256(table):
        raise DataFileError(f"{path}: data_sha256 mismatch, the table data are corrupt")
    return table


def read_table_heights(path: str | os.PathLike) -> tuple[np.ndarray, float]:
    """The texture heights [m] and pixel size [m] stored in a table file."""
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            return np.asarray(f["texture/heights_m"][()]), float(f["texture"].attrs["pixel_size_m"])
    except (OSError, KeyError) as exc:
        raise DataFileError(f"{path}: no readable /texture/heights_m ({exc})") from exc


def read_table_extras(path: str | os.PathLike) -> tuple[dict, dict[str, np.ndarray]]:
    """What a table file holds beside its :class:`MicroTable`, to write it again unchanged.

    Returns
    -------
    (dict, dict of ndarray)
        The ``/texture`` attributes ``source``, ``missing_fraction``, ``detrend`` (those
        present), and the ``/diagnostics`` datasets (e.g. ``solve_time_s`` [s]).
    """
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            texture = {
                k: _json_safe(v)
                for k, v in f["texture"].attrs.items()
                if k in ("source", "missing_fraction", "detrend")
            }
            diagnostics = {
                name: np.asarray(ds[()]) for name, ds in f.get("diagnostics", {}).items()
            }
    except (OSError, KeyError) as exc:
        raise DataFileError(f"{path}: unreadable table file ({exc})") from exc
    return texture, diagnostics


# ---------------------------------------------------------------------------- manifest


def _table_schema_of(path: Path) -> str | None:
    try:
        with h5py.File(path, "r") as f:
            return _json_safe(f.attrs.get("schema"))
    except OSError:
        return None


def write_manifest(directory: str | os.PathLike) -> Path:
    """(Re)write ``manifest.json`` listing every table file at the top of ``directory``.

    Each entry: ``sha256`` and ``size_bytes`` of the file and its ``data_sha256``. Written
    atomically.
    """
    directory = Path(directory)
    files = {}
    for path in sorted(directory.glob("*.h5")):
        if _table_schema_of(path) != TABLE_SCHEMA:
            continue
        table = read_table(path)
        files[path.name] = {
            "name": table.name,
            "sha256": sha256_file(path),
            "size_bytes": path.stat().st_size,
            "data_sha256": table.attrs.get("data_sha256"),
            "grid_shape": list(table.grid_shape),
            "points": int(table.pressure_ratio.size),
        }
    manifest = {
        "schema": MANIFEST_SCHEMA,
        "table_schema": TABLE_SCHEMA,
        "code_version": provenance()["code_version"],
        "files": files,
    }
    final = directory / MANIFEST_NAME
    with atomic_path(final) as tmp:
        tmp.write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return final


def read_manifest(directory: str | os.PathLike) -> dict:
    """Read ``manifest.json`` of a table directory (DataFileError if missing or invalid)."""
    return read_json_manifest(
        Path(directory) / MANIFEST_NAME,
        MANIFEST_SCHEMA,
        hint=" (set SKISNOW_TABLES_DIR or --tables-dir to the folder of the texture tables)",
    )


def verify_manifest(directory: str | os.PathLike) -> list[str]:
    """Check every file of a table directory against its manifest.

    Returns
    -------
    list of str
        One human-readable problem per line (empty: everything matches): missing manifest,
        missing file, size or sha256 mismatch, table file not listed.
    """
    directory = Path(directory)
    try:
        manifest = read_manifest(directory)
    except DataFileError as exc:
        return [str(exc)]
    problems = []
    listed = manifest["files"]
    for name, entry in sorted(listed.items()):
        path = directory / name
        if not path.is_file():
            problems.append(f"{name}: listed in the manifest but missing")
            continue
        size = path.stat().st_size
        if size != entry.get("size_bytes"):
            problems.append(f"{name}: size {size} bytes, manifest says {entry.get('size_bytes')}")
        digest = sha256_file(path)
        if digest != entry.get("sha256"):
            problems.append(
                f"{name}: sha256 {digest[:12]}…, manifest says {str(entry.get('sha256'))[:12]}…"
            )
    for path in sorted(directory.glob("*.h5")):
        if path.name not in listed and _table_schema_of(path) == TABLE_SCHEMA:
            problems.append(f"{path.name}: table file not listed in the manifest")
    return problems


# ---------------------------------------------------------------------------- checkpoints


def write_checkpoint(path: str | os.PathLike, arrays: dict[str, np.ndarray], key: str) -> Path:
    """Write one finished chunk of a table build atomically (HDF5, one dataset per array)."""
    path = Path(path)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["schema"] = CHECKPOINT_SCHEMA
        f.attrs["key"] = key
        for name, arr in arrays.items():
            f.create_dataset(name, data=np.asarray(arr), track_times=False)
    return path


def read_checkpoint(path: str | os.PathLike, key: str) -> dict[str, np.ndarray] | None:
    """A chunk checkpoint's arrays, or None if absent, unreadable or of another key."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        with h5py.File(path, "r") as f:
            if _json_safe(f.attrs.get("schema")) != CHECKPOINT_SCHEMA:
                return None
            if _json_safe(f.attrs.get("key")) != key:
                return None
            return {name: np.asarray(ds[()]) for name, ds in f.items()}
    except (OSError, KeyError) as exc:
        log.warning("ignoring unreadable checkpoint %s (%s)", path, exc)
        return None


# ---------------------------------------------------------------------------- pixel levels
#: ``--pixel-levels`` choices
PIXEL_LEVEL_MODES = ("none", "refine", "refine3", "coarsen")
#: pixel-size ratio between successive levels of a table [-]
LEVEL_REFINEMENT = 2


def refinements(pixel_levels: str) -> list[int]:
    """Refinement factors of the finer levels of ``--pixel-levels`` (``refine3``: [2, 4])."""
    return {"refine": [LEVEL_REFINEMENT], "refine3": [LEVEL_REFINEMENT, LEVEL_REFINEMENT**2]}.get(
        pixel_levels, []
    )
