"""Neutral camber CSV validation and the ski HDF5 round trip."""

import numpy as np
import pytest
from skisnow.app.storage.skis import (
    CamberData,
    SkiOutline,
    SkiRecord,
    read_camber_csv,
    read_ski,
    write_camber_csv,
    write_ski,
)
from skisnow.solvers.beam import ClassicSkiDesign
from skisnow.solvers.errors import DataFileError, InputError

HEADER = "ski_id,side,load_kg,load_position_mm,position_mm,gap_mm\n"


def _csv(rows):
    return HEADER + "".join(r + "\n" for r in rows)


GOOD = [
    "s1,mean,40,-160,-10,0.5",
    "s1,mean,40,-160,0,0.0",
    "s1,mean,40,-160,10,0.4",
    "s1,mean,60,-160,-10,0.3",
    "s1,mean,60,-160,0,-0.002",
    "s1,mean,60,-160,10,0.2",
]


def test_read_good_csv():
    d = read_camber_csv(_csv(GOOD))
    assert d.ski_id == "s1" and d.profiles_m.shape == (2, 3)
    np.testing.assert_allclose(d.positions_m, [-0.01, 0.0, 0.01])
    np.testing.assert_allclose(d.loads_n, [40 * 9.82, 60 * 9.82])
    assert d.profiles_m[1, 1] == pytest.approx(-2e-6)  # device noise kept as read


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("ski,side,load,pos,x,gap\n" + GOOD[0] + "\n", r"line 1: header must name the columns"),
        (_csv([GOOD[0], "s1,mean,40,-160,-20,0.1"]), r"line 3: position_mm -20.0 is not greater"),
        (_csv([GOOD[0], "s1,mean,40,-160,0,nan"]), r"line 3: column 'gap_mm' is 'nan'"),
        (_csv([GOOD[0], "s1,mean,40,-160,0,-0.2"]), r"line 3: gap_mm must be in \[-0.05, 50"),
        (
            _csv([*GOOD[:3], "s1,mean,60,-160,-10,0.3", "s1,mean,60,-160,5,0.2"]),
            r"line 5: case side=mean, load_kg=60, load_position_mm=-160 has 2 positions",
        ),
        (_csv(["s1,mean,250,-160,0,0.1"]), r"line 2: load_kg must be in \[0, 200\]"),
        (_csv(["s1,top,40,-160,0,0.1"]), r"line 2: side must be left, right or mean"),
        (_csv(["s1,mean,40,-160,1600,0.1"]), r"line 2: position_mm must be within"),
        (_csv([GOOD[0], "s2,mean,40,-160,0,0.1"]), r"line 3: ski_id 's2' differs"),
        (_csv(["s1,mean,40,-160,0"]), r"line 2: expected 6 columns"),
    ],
)
def test_csv_errors_are_precise(text, match):
    with pytest.raises(InputError, match=match):
        read_camber_csv(text)


def test_ski_roundtrip_with_network(tmp_path):
    design = ClassicSkiDesign()
    beam = design.build(spacing_m=10e-3)
    data = CamberData(
        "t",
        beam.positions_m,
        np.array([392.8]),
        np.array([-0.16]),
        ["mean"],
        beam.unloaded_gap_m[None, :],
    )
    outline = SkiOutline(2.0, 0.97, np.array([-0.97, 1.03]), np.array([0.044, 0.044]))
    net = {"w0": np.ones((3, 2)), "attrs": {"kind": "mlp"}, "norm": {"mean": np.zeros(2)}}
    write_ski(tmp_path / "t.h5", SkiRecord(data, outline, {"maker": "x"}, beam, {"a": 1}), net)
    back = read_ski(tmp_path / "t.h5")
    np.testing.assert_array_equal(back.measurements.profiles_m, data.profiles_m)
    np.testing.assert_array_equal(back.beam.bending_stiffness_nm2, beam.bending_stiffness_nm2)
    assert back.network["attrs"]["kind"] == "mlp"
    np.testing.assert_array_equal(back.network["norm"]["mean"], np.zeros(2))
    assert back.metadata["maker"] == "x" and back.beam_design == {"a": 1}
    write_camber_csv(tmp_path / "t.csv", data)
    again = read_camber_csv(tmp_path / "t.csv")
    np.testing.assert_allclose(again.profiles_m, data.profiles_m, atol=1e-7)
    with pytest.raises(DataFileError):
        read_ski(tmp_path / "missing.h5")
