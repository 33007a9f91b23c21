"""Texture files: raw height maps, HDF5 round-trip, shipped grinds."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from skisnow.app.storage.textures import (
    SCHEMA,
    SHIPPED_TEXTURES_DIR,
    list_shipped_textures,
    read_heightmap,
    read_texture,
    write_texture,
)
from skisnow.app.storage.topography import load_texture
from skisnow.solvers.errors import DataFileError, InputError
from skisnow.solvers.texture import (
    GRIND_TARGETS,
    Texture,
    iso25178_parameters,
    level_heights,
    self_affine_surface,
    target_errors,
)


@pytest.fixture
def surface_um():
    rng = np.random.default_rng(11)
    return self_affine_surface((24, 30), 1e-6, hurst=0.8, rms_height_m=1.0, rng=rng)


@pytest.mark.parametrize(
    ("unit", "factor"), [("m", 1.0), ("mm", 1e-3), ("um", 1e-6), ("µm", 1e-6), ("nm", 1e-9)]
)
def test_npy_round_trip_with_units(tmp_path, surface_um, unit, factor):
    path = tmp_path / "map.npy"
    np.save(path, surface_um)
    tex = read_heightmap(path, pixel_size_um=1.5, height_unit=unit)
    expected, _ = level_heights(surface_um * factor, 1.5e-6)
    np.testing.assert_allclose(tex.heights_m, expected, rtol=1e-12, atol=1e-15 * factor)
    assert tex.pixel_size_m == pytest.approx(1.5e-6, rel=1e-15)
    assert tex.name == "map"
    assert tex.missing_fraction == 0


@pytest.mark.parametrize("sep", [",", " ", "\t"])
def test_csv_round_trip_with_missing(tmp_path, surface_um, sep):
    h = surface_um.copy()
    h[3, 4] = np.nan
    lines = ["# heights in um"]
    for row in h:
        cells = ["" if (np.isnan(v) and sep == ",") else repr(float(v)) for v in row]
        lines.append(sep.join(cells))
    path = tmp_path / "map.csv"
    path.write_text("\n".join(lines) + "\n")
    tex = read_heightmap(path, pixel_size_um=2.0, height_unit="um")
    expected, missing = level_heights(h * 1e-6, 2e-6)
    assert tex.missing_fraction == pytest.approx(missing) == pytest.approx(1 / h.size)
    np.testing.assert_allclose(tex.heights_m, expected, rtol=1e-12, atol=1e-20)


def test_raw_map_errors(tmp_path, surface_um):
    path = tmp_path / "map.npy"
    np.save(path, surface_um)
    with pytest.raises(InputError, match=r"height_unit must be one of m, mm, um"):
        read_heightmap(path, pixel_size_um=1.0, height_unit="inch")
    with pytest.raises(InputError, match="pixel_size_um"):
        read_heightmap(path, pixel_size_um=0.0, height_unit="um")
    with pytest.raises(DataFileError, match=r"missing\.npy"):
        read_heightmap(tmp_path / "missing.npy", pixel_size_um=1.0, height_unit="um")
    # truncated .npy
    trunc = tmp_path / "trunc.npy"
    trunc.write_bytes(path.read_bytes()[:200])
    with pytest.raises(DataFileError, match=r"trunc\.npy"):
        read_heightmap(trunc, pixel_size_um=1.0, height_unit="um")
    # pickled object array refused
    obj = tmp_path / "obj.npy"
    np.save(obj, np.array([[1, "a"]], dtype=object), allow_pickle=True)
    with pytest.raises(DataFileError, match=r"obj\.npy"):
        read_heightmap(obj, pixel_size_um=1.0, height_unit="um")
    # ragged / non-numeric csv
    ragged = tmp_path / "ragged.csv"
    ragged.write_text("1,2,3\n4,5\n")
    with pytest.raises(DataFileError, match=r"ragged\.csv"):
        read_heightmap(ragged, pixel_size_um=1.0, height_unit="um")
    words = tmp_path / "words.csv"
    words.write_text("1,2\n3,x\n")
    with pytest.raises(DataFileError, match=r"words.csv, line 2"):
        read_heightmap(words, pixel_size_um=1.0, height_unit="um")
    # levelling refusals name the file
    nan = tmp_path / "nan.npy"
    np.save(nan, np.full((4, 4), np.nan))
    with pytest.raises(InputError, match=r"nan.npy.*all NaN"):
        read_heightmap(nan, pixel_size_um=1.0, height_unit="um")


def test_texture_h5_round_trip(tmp_path, surface_um):
    tex = Texture(surface_um * 1e-6, 1.25e-6, "demo", 0.01, "unit test")
    path = tmp_path / "demo.h5"
    write_texture(tex, path, extra_attrs={"generator_seed": 4, "params": {"a": 1.0}})
    back = read_texture(path)
    np.testing.assert_array_equal(back.heights_m, tex.heights_m)
    assert back.heights_m.dtype == np.float64
    assert (back.pixel_size_m, back.name, back.missing_fraction, back.source) == (
        1.25e-6,
        "demo",
        0.01,
        "unit test",
    )
    with h5py.File(path) as f:
        assert f.attrs["schema"] == SCHEMA
        assert f["heights_m"].attrs["unit"] == "m"
        assert "along the ski" in f["heights_m"].attrs["axis0"]
        assert f.attrs["generator_seed"] == 4
        assert json.loads(f.attrs["params"]) == {"a": 1.0}
        for key in ("code_version", "git_commit", "command_line", "created_utc"):
            assert key in f.attrs
        iso = iso25178_parameters(tex.heights_m, tex.pixel_size_m)
        assert f.attrs["iso_Sq_m"] == pytest.approx(iso["Sq_m"], rel=1e-15)
    assert not list(tmp_path.glob(".*part"))  # atomic: no temporary left behind
    assert load_texture(path).name == "demo"


def test_read_texture_refuses_bad_files(tmp_path):
    with pytest.raises(DataFileError, match=r"nope\.h5"):
        read_texture(tmp_path / "nope.h5")
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not an hdf5 file")
    with pytest.raises(DataFileError, match=r"junk\.h5"):
        read_texture(junk)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f.attrs["schema"] = "something/else"
        f["heights_m"] = np.zeros((3, 3))
    with pytest.raises(DataFileError, match=r"other.h5.*schema"):
        read_texture(other)
    empty = tmp_path / "empty.h5"
    with h5py.File(empty, "w") as f:
        f.attrs["schema"] = SCHEMA
    with pytest.raises(DataFileError, match=r"empty.h5.*heights_m"):
        read_texture(empty)


def test_load_texture_dispatch(tmp_path, surface_um):
    path = tmp_path / "raw.npy"
    np.save(path, surface_um)
    with pytest.raises(InputError, match="pixel_size_um and height_unit must be given"):
        load_texture(str(path))
    with pytest.raises(InputError, match="height_unit must be given"):
        load_texture(path, pixel_size_um=1.0)
    assert load_texture(path, pixel_size_um=1.0, height_unit="nm").name == "raw"
    with pytest.raises(InputError, match="grind-1"):
        load_texture("grind-99")


def test_shipped_grinds_meet_the_tolerance_table():
    assert SHIPPED_TEXTURES_DIR.name == "textures"
    names = list_shipped_textures()
    assert {"grind-1", "grind-2"} <= set(names)
    for name in ("grind-1", "grind-2"):
        tex = load_texture(name)
        assert tex.shape == (1024, 1024)
        assert 1e-6 <= tex.pixel_size_m <= 2e-6
        achieved = iso25178_parameters(tex.heights_m, tex.pixel_size_m, periodic=True)
        errors = target_errors(achieved, GRIND_TARGETS[name])
        bad = {k: round(v, 2) for k, v in errors.items() if abs(v) > 1}
        assert not bad, f"{name}: parameters outside tolerance (units of tolerance): {bad}"
        with h5py.File(SHIPPED_TEXTURES_DIR / f"{name}.h5") as f:
            assert f.attrs["synthetic"]
            assert "generator_parameters_json" in f.attrs
            assert "generator_seed" in f.attrs
