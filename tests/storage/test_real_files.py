"""Every format skisnow reads, pinned by a real file (issue #30): grid, pixel size [m], and Sq,
Sa [m] of the measured points (plane removed); and every real file refused, with its reason.

The files are in tests/data/topography (sources and licences in its README.md; large ones
xz-compressed). The pinned values were cross-checked when pinned against SurfaceTopography's
own reading of the same files (grid, pixel, Sq and Sa equal to 1e-12; the .x3p, .npy and xyz
files are read by other code). A library upgrade that changes a reading fails here.
"""

from __future__ import annotations

import lzma
from pathlib import Path

import pytest
from skisnow.app.storage.topography import read_measured_topography, read_raw_topography
from skisnow.app.storage.topography_formats import PROVEN_FORMATS
from skisnow.solvers.errors import InputError

DATA = Path(__file__).resolve().parents[1] / "data" / "topography"

#: file, options, format, grid (x, y) as read, pixel [m], Sq [m], Sa [m] of the measured points
PINS = [
    ("ISO5436-sample1.x3p", {}, "x3p", (4, 4), 0.016016, 0.440982433, 0.332089994),
    ("al3d-1.al3d.xz", {}, "al3d", (200, 296), 4.38027e-07, 2.89822103e-07, 2.30196108e-07),
    ("frt-1.frt.xz", {}, "frt", (500, 500), 2.4e-05, 4.39600558e-06, 9.40863532e-07),
    ("frt-2.frt.xz", {}, "frt", (150, 300), 0.0002, 8.71655022e-06, 1.07945434e-06),
    (
        "metropro-1.dat.xz",
        {},
        "metropro",
        (640, 480),
        1.09825203e-06,
        1.33349814e-08,
        1.11056948e-08,
    ),
    ("plu-1.plu.xz", {}, "plu", (768, 576), 1.66000009e-06, 1.82819558e-08, 1.46290384e-08),
    ("sdf-1.sdf", {}, "sdf", (7, 4), 1e-06, 1.02899294e-08, 7.90149235e-09),
    ("sur-2.sur.xz", {}, "sur", (563, 484), 3.48400022e-06, 1.71041392e-08, 1.16465832e-08),
    (
        "tmd-1.tmd.xz",
        {"height_unit": "mm"},
        "tmd",
        (300, 300),
        6.31886673e-05,
        7.43408795e-05,
        6.55952375e-05,
    ),
    (
        "tmd-1.tmd.xz",
        {"height_unit": "um"},
        "tmd",
        (300, 300),
        6.31886673e-08,
        7.43408795e-08,
        6.55952375e-08,
    ),
    ("matrix-4.txt.xz", {}, "text", (75, 305), 3.69862e-07, 7.3730593e-08, 6.22892823e-08),
    ("matrix-3.txt.xz", {}, "text", (256, 256), 3.90625e-08, 3.52229188e-08, 2.62280914e-08),
    ("txt_example.txt", {}, "text", (6, 3), 1.66666667e-07, 2.11965689e-08, 1.63227513e-08),
    ("xyz-2.txt", {"height_unit": "um"}, "xyz", (4, 4), 1e-06, 2.41142682e-07, 1.97675834e-07),
    (
        "example-2d.npy",
        {"pixel_size_um": 1, "height_unit": "um"},
        "npy",
        (2, 2),
        1e-06,
        5.25e-07,
        5.25e-07,
    ),
]

#: real files refused, with the reason the answer must name
REFUSED = [
    ("ISO5436-sample2.x3p", {}, "point_cloud, not a surface"),
    ("csv-1.csv", {"pixel_size_um": 1, "height_unit": "um"}, "line scan"),
    ("xy-4.txt.xz", {"pixel_size_um": 1, "height_unit": "um"}, "line scan"),
    ("opdx-3.opdx", {}, "line scan"),
    ("sur-3.sur.xz", {}, "too much of the map is unmeasured"),
    ("tmd-1.tmd.xz", {}, "do not state their unit"),
    ("frt-1.frt.xz", {"pixel_size_um": 1}, "own calibration; do not give pixel_size_um"),
    ("ISO5436-sample1.x3p", {"height_unit": "um"}, "own calibration; do not give height_unit"),
]


def load(file: str) -> tuple[bytes, str]:
    data = (DATA / file).read_bytes()
    if file.endswith(".xz"):
        return lzma.decompress(data), file[:-3]
    return data, file


@pytest.mark.parametrize(("file", "opts", "fmt", "grid", "px_m", "sq_m", "sa_m"), PINS)
def test_real_file_reading_is_pinned(file, opts, fmt, grid, px_m, sq_m, sa_m):
    data, name = load(file)
    raw = read_raw_topography(data, name=name, min_side=2, **opts)
    assert raw.format == fmt
    assert raw.heights_m.shape == grid
    assert raw.pixel_size_m == pytest.approx(px_m, rel=1e-9)
    measured = read_measured_topography(data, name=name, min_side=2, **opts)
    iso = measured.prepared.iso_measured  # what the upload answers
    assert iso["Sq_m"] == pytest.approx(sq_m, rel=1e-6)
    assert iso["Sa_m"] == pytest.approx(sa_m, rel=1e-6)
    assert (
        measured.prepared.measured_points + measured.prepared.unmeasured_points == grid[0] * grid[1]
    )


@pytest.mark.parametrize(("file", "opts", "reason"), REFUSED)
def test_real_file_refusals_name_their_reason(file, opts, reason):
    data, name = load(file)
    with pytest.raises(InputError, match=reason):
        read_measured_topography(data, name=name, min_side=2, **opts)


def test_every_proven_format_has_a_pinned_real_file():
    assert set(PROVEN_FORMATS) <= {fmt for _, _, fmt, *_ in PINS}


def test_the_frt_border_case_on_a_real_file():
    """The issue's FRT MicroProf map: 31 % unmeasured with stray pixels in the border. Sq over
    the measured points is 4.40 µm; the solver's map is the measured rectangle (the old fill
    gave 42.5 µm)."""
    data, name = load("frt-1.frt.xz")
    prep = read_measured_topography(data, name=name).prepared
    assert prep.unmeasured_points / 500**2 == pytest.approx(0.306, abs=0.001)
    assert prep.sq_measured_m == pytest.approx(4.40e-6, rel=1e-3)
    assert prep.sq_map_m < prep.sq_measured_m  # the strays are cut, not spread
    assert prep.filled_points <= 64
