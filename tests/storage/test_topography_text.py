"""Text height files (app.storage.heightgrid.parse_text_topography via read_topography):
header rows, line scans, x y z point lists, Wyko and Gwyddion headers; and calibrated formats
refusing a calibration the user gives (issues #27 point 5 and #30 point 5)."""

from __future__ import annotations

import io

import numpy as np
import pytest
import x3pio
from skisnow.app.storage.topography import read_measured_topography, read_raw_topography
from skisnow.solvers.errors import InputError
from skisnow.solvers.texture import self_affine_surface

RAW = {"pixel_size_um": 1.0, "height_unit": "um"}


def grid_um(shape=(64, 64), seed=0) -> np.ndarray:
    h = self_affine_surface(
        shape, 1e-6, hurst=0.8, rms_height_m=2e-6, rng=np.random.default_rng(seed)
    )
    return h * 1e6


def csv_text(a: np.ndarray, sep=",") -> str:
    return "\n".join(sep.join(f"{v:.9g}" for v in row) for row in a) + "\n"


def test_a_row_of_x_positions_is_skipped_with_a_note():
    """#27: a height grid whose first row lists x positions was read as 65 × 64."""
    h = grid_um()
    text = csv_text(np.vstack([np.arange(64) * 0.5, h]))
    m = read_measured_topography(text.encode(), name="g.csv", **RAW)
    assert m.texture.shape == (64, 64)
    assert any("row 1" in n and "positions" in n for n in m.notes)
    plain = read_measured_topography(csv_text(h).encode(), name="g.csv", **RAW)
    assert m.prepared.iso_measured["Sa_m"] == pytest.approx(
        plain.prepared.iso_measured["Sa_m"], rel=1e-9
    )
    assert plain.notes == []
    # and a first column of y positions with it
    both = np.hstack([np.arange(65)[:, None] * 0.5, np.vstack([np.arange(64) * 0.5, h])])
    m2 = read_measured_topography(csv_text(both).encode(), name="g.csv", **RAW)
    assert m2.texture.shape == (64, 64) and len(m2.notes) == 2
    # a text header line is skipped with a note too
    m3 = read_measured_topography(("x,y,z heights\n" + csv_text(h)).encode(), name="g.csv", **RAW)
    assert m3.texture.shape == (64, 64) and "header" in m3.notes[0]


@pytest.mark.parametrize(
    "text",
    [
        "\n".join(f"{0.1 * i:.3f},{np.sin(i / 7):.5f}" for i in range(500)),
        "X_(microns),y1\n" + "\n".join(f"{0.1 * i:.3f},{np.sin(i):.5f}" for i in range(500)),
        "\n".join(f"{np.sin(i):.5f}" for i in range(500)),
    ],
    ids=["x z pairs", "with a header", "one column"],
)
def test_line_scans_are_refused_as_line_scans(text):
    with pytest.raises(InputError, match=r"a line scan.*a grind needs a 2-D map"):
        read_measured_topography(text.encode(), name="p.txt", **RAW)


def test_x3p_profile_is_refused_as_a_line_scan():
    buf = io.BytesIO()
    x3pio.write(buf, np.linspace(0, 1e-6, 50), x_scale=1e-6)
    with pytest.raises(InputError, match="line scan: a grind needs a 2-D map"):
        read_measured_topography(buf.getvalue(), name="line.x3p")


def test_xyz_point_list_on_a_grid_is_a_map():
    h = grid_um((20, 17), seed=1)
    i, j = np.indices(h.shape)
    order = np.random.default_rng(0).permutation(h.size)  # any order of the points
    pts = np.column_stack([2.5 * i.ravel(), 2.5 * j.ravel(), h.ravel()])[order]
    pts[5, 2] = np.nan
    text = "\n".join(" ".join(f"{v:.6f}" for v in p) for p in pts)
    raw = read_raw_topography(text.encode(), name="p.xyz", height_unit="um")
    assert raw.format == "xyz" and raw.heights_m.shape == (20, 17)
    assert raw.pixel_size_m == pytest.approx(2.5e-6)
    expect = h.copy()
    r, c = int(pts[5, 0] / 2.5 + 0.5), int(pts[5, 1] / 2.5 + 0.5)
    expect[r, c] = np.nan
    np.testing.assert_allclose(raw.heights_m, expect * 1e-6, atol=1e-12)
    with pytest.raises(InputError, match="own pixel size"):
        read_raw_topography(text.encode(), name="p.xyz", pixel_size_um=1, height_unit="um")
    with pytest.raises(InputError, match="height_unit"):
        read_raw_topography(text.encode(), name="p.xyz")
    scattered = pts.copy()
    scattered[:, 0] += np.random.default_rng(1).random(len(pts))
    text = "\n".join(" ".join(f"{v:.6f}" for v in p) for p in scattered)
    with pytest.raises(InputError, match="not on a regular square grid"):
        read_raw_topography(text.encode(), name="p.xyz", height_unit="um")


def test_wyko_text_matrix_reads_its_calibration():
    h = np.random.default_rng(2).normal(size=(30, 20))  # 30 rows (y) × 20 columns (x)
    text = (
        "h=30 w=20\npixel size=3.69862e-007 m\ndata unit=rad\n"
        "height conversion factor (-> m)=6.30079e-008\n" + csv_text(h, " ")
    )
    raw = read_raw_topography(text.encode(), name="wyko.txt")
    assert raw.heights_m.shape == (20, 30)  # axis 0 = x = the columns
    assert raw.pixel_size_m == pytest.approx(3.69862e-7)
    np.testing.assert_allclose(raw.heights_m, h.T * 6.30079e-8, rtol=1e-5)
    with pytest.raises(InputError, match="own calibration; do not give pixel_size_um"):
        read_raw_topography(text.encode(), name="wyko.txt", pixel_size_um=1)
    bad = text.replace("h=30", "h=31")
    with pytest.raises(InputError, match="h=31 w=20"):
        read_raw_topography(bad.encode(), name="wyko.txt")


def test_gwyddion_text_export_reads_its_calibration():
    h = np.random.default_rng(3).normal(size=(16, 32)) * 1e-7
    text = "# Channel: Z\n# Width: 64.0 µm\n# Height: 32.0 µm\n# Value units: m\n"
    raw = read_raw_topography((text + csv_text(h, "\t")).encode(), name="gwy.txt")
    assert raw.heights_m.shape == (32, 16) and raw.pixel_size_m == pytest.approx(2e-6)
    np.testing.assert_allclose(raw.heights_m, h.T, atol=1e-12)


def test_x3p_refuses_a_calibration_it_overrides():
    """#27: an .x3p silently ignored pixel_size_um and height_unit."""
    buf = io.BytesIO()
    x3pio.write(buf, grid_um((20, 20)) * 1e-6, x_scale=1e-6, y_scale=1e-6)
    for given in ({"pixel_size_um": 2.0}, {"height_unit": "nm"}):
        with pytest.raises(InputError, match=f"own calibration; do not give {next(iter(given))}"):
            read_raw_topography(buf.getvalue(), name="g.x3p", **given)
    assert read_raw_topography(buf.getvalue(), name="g.x3p").format == "x3p"
