"""Measured topography files (app.storage.topography) and periodisation (solvers.texture).

Files are written in the test: x3p of both revisions with x3pio, a Digital Surf .sur by hand
(512-byte header, int32 data, rows along y), zips by hand. The test map is non-square with a
known orientation: ``h[i, j] = a·i + b·j + bump`` with x = i (6 or more points) and y = j, so a
swapped axis order changes the shape and the gradient signs.
"""

from __future__ import annotations

import io
import json
import struct
import zipfile

import numpy as np
import pytest
import x3pio
from skisnow.app.storage.topography import detect_format, read_raw_topography, read_topography
from skisnow.solvers.errors import DataFileError, InputError
from skisnow.solvers.texture import PERIODISATION_METHODS, make_periodic

N_X, N_Y = 12, 7  # points along x (file axis x) and y
DX_M = 2e-6


def oriented_map() -> np.ndarray:
    """Heights [m] shaped (N_X, N_Y); a single high peak at x index 2, y index 5."""
    x = np.arange(N_X)[:, None]
    y = np.arange(N_Y)[None, :]
    h = 1e-7 * x + 3e-7 * y
    h[2, 5] += 5e-6
    return h


def x3p_bytes(h_xy: np.ndarray, revision, *, dx=DX_M, dy=DX_M) -> bytes:
    buf = io.BytesIO()
    # x3pio takes (rows, columns) = (y, x)
    x3pio.write(buf, h_xy.T, x_scale=dx, y_scale=dy, revision=revision)
    return buf.getvalue()


def sur_bytes(z_xy: np.ndarray, dx_um: float, dy_um: float, z_scale_um: float) -> bytes:
    """A minimal Digital Surf SUR file (PC byte order, 32-bit data, µm units)."""
    z_int = np.asarray(z_xy, dtype="<i4").T  # stored row-major with rows along y
    ny, nx = z_int.shape
    um = "µm".encode("latin-1")
    fields = [
        ("12s", b"DIGITAL SURF"), ("H", 0), ("H", 1), ("H", 1), ("H", 2),
        ("30s", b"test"), ("30s", b"skisnow"), ("H", 0), ("H", 0), ("H", 0), ("H", 0),
        ("H", 1), ("I", 0), ("I", 0), ("H", 32), ("i", int(z_int.min())),
        ("i", int(z_int.max())), ("i", nx), ("i", ny), ("I", nx * ny), ("f", dx_um),
        ("f", dy_um), ("f", z_scale_um), ("16s", b"X"), ("16s", b"Y"), ("16s", b"Z"),
        ("16s", um), ("16s", um), ("16s", um), ("16s", um), ("16s", um), ("16s", um),
        ("f", 1.0), ("f", 1.0), ("f", 1.0), ("H", 0), ("H", 0), ("H", 0), ("I", 0), ("I", 0),
        ("I", 0), ("H", 0), ("H", 0), ("H", 0), ("H", 1), ("H", 1), ("H", 2024), ("H", 0),
        ("f", 0.0), ("I", 0), ("I", 0), ("H", 0), ("H", 0), ("H", 0), ("128s", b""),
        ("f", 0.0), ("f", 0.0), ("f", 0.0), ("34s", b""),
    ]  # fmt: skip
    header = struct.pack("<" + "".join(f for f, _ in fields), *(v for _, v in fields))
    assert len(header) == 512
    return header + z_int.tobytes()


def peak_index(h: np.ndarray) -> tuple[int, int]:
    return tuple(int(v) for v in np.unravel_index(np.argmax(h), h.shape))


# --------------------------------------------------------------------------- x3p


@pytest.mark.parametrize("revision", list(x3pio.Revision))
def test_x3p_both_revisions_axis_order_and_units(revision):
    h = oriented_map()
    data = x3p_bytes(h, revision)
    assert detect_format(data[:512]) == "zip"
    raw = read_raw_topography(data, name="sample.x3p")
    assert raw.format == "x3p" and revision.name in raw.details
    assert raw.heights_m.shape == (N_X, N_Y)  # x along axis 0, as for every format
    np.testing.assert_allclose(raw.heights_m, h, rtol=0, atol=1e-15)
    assert raw.pixel_size_m == pytest.approx(DX_M, rel=1e-12)
    tex = read_topography(data, name="sample.x3p")
    assert tex.name == "sample" and tex.shape == (N_X, N_Y)
    assert peak_index(tex.heights_m) == (2, 5)
    assert abs(tex.heights_m.mean()) < 1e-18  # levelled
    assert "sha256" in tex.source and "x3p" in tex.source
    swapped = read_topography(data, name="sample.x3p", along_ski="y")
    assert swapped.shape == (N_Y, N_X) and peak_index(swapped.heights_m) == (5, 2)


def test_surfacetopography_agrees_on_the_old_revision_and_refuses_the_new():
    """The oracle: SurfaceTopography's own x3p reader (ISO 5436-2000 only) gives (nx, ny)."""
    from SurfaceTopography import read_topography as st_read

    h = oriented_map()
    top = st_read(io.BytesIO(x3p_bytes(h, x3pio.Revision.ISO5436_2000)))
    np.testing.assert_allclose(top.heights(), h, atol=1e-15)
    with pytest.raises(Exception):  # noqa: B017 - the library refuses it; we do not
        st_read(io.BytesIO(x3p_bytes(h, x3pio.Revision.ISO25178_72_2017_DAM1)))


def test_x3p_missing_points_non_square_pixels_and_profiles(tmp_path):
    h = oriented_map()
    h_nan = h.copy()
    h_nan[0, :3] = np.nan  # touches the edge: cut off, never filled
    h_nan[5, 3] = np.nan  # a small hole inside: filled
    tex = read_topography(x3p_bytes(h_nan, x3pio.Revision.ISO25178_72_2017_DAM1))
    assert tex.shape == (N_X - 1, N_Y)
    assert tex.missing_fraction == pytest.approx(1 / ((N_X - 1) * N_Y))
    assert np.isfinite(tex.heights_m).all()
    with pytest.raises(InputError, match="not square"):
        read_topography(x3p_bytes(h, x3pio.Revision.ISO5436_2000, dy=3e-6))
    all_nan = np.full((N_X, N_Y), np.nan)
    with pytest.raises(InputError, match="no valid point"):
        read_topography(x3p_bytes(all_nan, x3pio.Revision.ISO5436_2000))
    buf = io.BytesIO()
    x3pio.write(buf, np.linspace(0, 1e-6, 50), x_scale=1e-6)
    with pytest.raises(InputError, match="profile"):
        read_topography(buf.getvalue(), name="line.x3p")


def test_x3p_truncated_and_corrupt():
    data = x3p_bytes(oriented_map(), x3pio.Revision.ISO5436_2000)
    for cut in (len(data) // 2, len(data) - 10, 30):
        with pytest.raises(DataFileError, match=r"broken\.x3p"):
            read_topography(data[:cut], name="broken.x3p")
    flipped = bytearray(data)
    flipped[len(data) // 3] ^= 0xFF
    with pytest.raises((DataFileError, InputError)):
        read_topography(bytes(flipped), name="flipped.x3p")


# --------------------------------------------------------------------------- limits


def _zip(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, content in members.items():
            zf.writestr(name, content)
    return buf.getvalue()


def test_zip_bomb_refused_before_extraction():
    bomb = _zip({"main.xml": b"<x/>", "bindata/data.bin": b"\0" * (64 * 1024 * 1024)})
    assert len(bomb) < 200_000  # tiny on disk
    with pytest.raises(InputError, match=r"unpack to .* bytes.*zip bomb"):
        read_topography(bomb, name="bomb.x3p", max_pixels=1000)
    many = _zip({f"m{i}.txt": b"x" for i in range(100)} | {"main.xml": b"<x/>"})
    with pytest.raises(InputError, match="101 members"):
        read_topography(many, name="many.x3p")
    with pytest.raises(DataFileError, match=r"without main\.xml"):
        read_topography(_zip({"data.bin": b"123"}), name="other.zip")


def test_grid_size_caps():
    data = x3p_bytes(oriented_map(), x3pio.Revision.ISO5436_2000)
    with pytest.raises(InputError, match="max_pixels=50"):
        read_topography(data, max_pixels=50)
    with pytest.raises(InputError, match="at least 8 points"):
        read_topography(data, min_side=8)
    one_px = x3p_bytes(np.ones((1, 5)) * 1e-6, x3pio.Revision.ISO5436_2000)
    with pytest.raises(InputError, match="too small"):
        read_topography(one_px)
    with pytest.raises(InputError, match="larger than the limit 100 bytes"):
        read_topography(data, max_file_bytes=100)


def test_npy_csv_content_checks_and_no_pickles(tmp_path):
    h = oriented_map() * 1e6  # µm
    buf = io.BytesIO()
    np.save(buf, h)
    tex = read_topography(buf.getvalue(), name="grid.npy", pixel_size_um=2, height_unit="um")
    assert tex.shape == (N_X, N_Y) and peak_index(tex.heights_m) == (2, 5)
    # the content decides, not the name: an npy called .csv is read as npy
    wrong_name = tmp_path / "grid.csv"
    wrong_name.write_bytes(buf.getvalue())
    assert read_topography(wrong_name, pixel_size_um=2, height_unit="um").shape == (N_X, N_Y)
    obj = io.BytesIO()
    np.save(obj, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(InputError, match="pickles are never loaded"):
        read_topography(obj.getvalue(), name="evil.npy", pixel_size_um=1, height_unit="um")
    import pickle

    with pytest.raises(DataFileError, match="pickle"):
        read_topography(pickle.dumps({"a": 1}), name="evil.pkl")
    with pytest.raises(DataFileError, match="unknown content"):
        read_topography(b"\x00\x01\x02garbage" * 50, name="grind.x3p")
    with pytest.raises(DataFileError, match="empty"):
        read_topography(b"", name="empty.sur")
    csv = "\n".join(",".join(f"{v:.6g}" for v in row) for row in h).encode()
    tex = read_topography(csv, name="grid.csv", pixel_size_um=2, height_unit="um")
    assert peak_index(tex.heights_m) == (2, 5)
    with pytest.raises(DataFileError, match="rectangular"):
        read_topography(csv[: len(csv) // 2 + 3], name="cut.csv", pixel_size_um=2, height_unit="um")
    with pytest.raises(InputError, match="pixel_size_um and height_unit must be given"):
        read_topography(csv, name="grid.csv")


# --------------------------------------------------------------------------- instrument formats


def test_sur_axis_order_units_and_errors(tmp_path):
    z = np.round(oriented_map() / 1e-8).astype(np.int32)  # counts of 0.01 µm
    data = sur_bytes(z, 2.0, 2.0, 0.01)
    path = tmp_path / "scan.sur"
    path.write_bytes(data)
    raw = read_raw_topography(path)
    assert raw.format == "sur" and raw.heights_m.shape == (N_X, N_Y)
    np.testing.assert_allclose(raw.heights_m, z * 1e-8, rtol=1e-6)
    assert raw.pixel_size_m == pytest.approx(2e-6, rel=1e-6)
    tex = read_topography(path)
    assert tex.name == "scan" and peak_index(tex.heights_m) == (2, 5)
    with pytest.raises(InputError, match="own calibration"):
        read_topography(path, pixel_size_um=1.0)
    with pytest.raises(DataFileError, match=r"scan\.sur"):
        read_topography(data[:600], name="scan.sur")  # truncated inside the data
    with pytest.raises(InputError, match="max_pixels"):
        read_topography(path, max_pixels=20)  # checked from the header
    with pytest.raises(InputError, match="not square"):
        read_topography(sur_bytes(z, 2.0, 2.5, 0.01), name="rect.sur")


def test_cli_reads_instrument_files_with_periodisation(tmp_path, capsys):
    from skisnow.app.cli import main

    rng = np.random.default_rng(3)
    h = np.cumsum(rng.normal(size=(24, 20)), axis=0) * 2e-8  # rough, non-periodic
    path = tmp_path / "patch.x3p"
    path.write_bytes(x3p_bytes(h, x3pio.Revision.ISO25178_72_2017_DAM1))
    args = ["micro", str(path), "--nominal-pressure-kpa", "30", "--snow-modulus-mpa", "200"]
    results = {}
    for method in (None, *PERIODISATION_METHODS):
        extra = [] if method is None else ["--periodic", method]
        assert main([*args, *extra, "--json"]) == 0
        results[method] = json.loads(capsys.readouterr().out)
    assert results[None]["periodic"] == "mirror"  # default for measured maps
    assert results["mirror"]["solved_grid"] == [48, 40]
    assert results["window"]["solved_grid"] == [24, 20]
    for out in results.values():
        assert out["grid"] == [24, 20] and 0 < out["real_contact_area_fraction"] < 1


# --------------------------------------------------------------------------- make_periodic


def test_make_periodic_methods():
    rng = np.random.default_rng(0)
    h = rng.normal(size=(9, 6))
    m = make_periodic(h, "mirror")
    assert m.shape == (18, 12)
    np.testing.assert_array_equal(m[:9, :6], h)
    np.testing.assert_array_equal(m[9:, :6], h[::-1])
    np.testing.assert_array_equal(m[:, 6:], m[:, :6][:, ::-1])
    # continuous across the periodic seam: the wrap joins equal rows
    np.testing.assert_array_equal(m[0], m[-1])
    np.testing.assert_array_equal(m[:, 0], m[:, -1])
    w = make_periodic(h, "window", taper_fraction=0.25)
    assert w.shape == h.shape and abs(w.mean()) < 1e-12
    offset = w[0, 0]  # the window sets the edges to the mean plane, then the mean is removed
    np.testing.assert_allclose(w[0], offset, atol=1e-12)
    np.testing.assert_allclose(w[:, 0], offset, atol=1e-12)
    centre = (slice(3, 6), slice(2, 4))  # untapered: the heights shifted by the same offset
    np.testing.assert_allclose(w[centre], (h - h.mean())[centre] + offset, atol=1e-12)
    np.testing.assert_array_equal(make_periodic(h, "none"), h)
    with pytest.raises(InputError, match="method"):
        make_periodic(h, "tile")
    with pytest.raises(InputError, match="taper_fraction"):
        make_periodic(h, "window", taper_fraction=0.7)
    with pytest.raises(InputError, match="NaN"):
        make_periodic(np.full((3, 3), np.nan), "mirror")


def test_mirror_solve_equals_the_patch_statistics():
    """A mirror-tiled solve is symmetric: its quarter carries the same area and mean gap."""
    from skisnow.solvers.micro import solve_micro

    rng = np.random.default_rng(5)
    h = np.cumsum(rng.normal(size=(32, 24)), axis=1) * 5e-8
    m = make_periodic(h, "mirror")
    res = solve_micro(m, 1e-6, 2e5, 2e8, tol=1e-8)
    assert res.converged
    quarter = res.pressure_pa[:32, :24]
    np.testing.assert_allclose(res.pressure_pa[32:, :24], quarter[::-1], atol=1e-6 * 2e5)
    np.testing.assert_allclose(res.pressure_pa[:32, 24:], quarter[:, ::-1], atol=1e-6 * 2e5)
    assert (quarter > 0).mean() == pytest.approx(res.real_contact_area_fraction, abs=0.02)
