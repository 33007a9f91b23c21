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
        (_csv([*GOOD[:2], "s1,mean,40,-160,-5,0.1"]), r"line 4: position_mm -5 is not greater"),
        (_csv([GOOD[0], "s1,mean,40,-160,-10,0.1"]), r"line 3: position_mm -10 .* written twice"),
        (
            _csv([*GOOD[:3], "s1,mean,60,-160,10,0.3", "s1,mean,60,-160,0,0.2"]),
            r"line 6: position_mm 0 is not greater .* the same way in every case",
        ),
        (_csv([GOOD[0], "s1,mean,40,-160,0,inf"]), r"line 3: column 'gap_mm' is 'inf': not a gap"),
        (_csv([GOOD[0], "s1,mean,40,-160,0,nan"]), r"unmeasured samples \(the first at line 3;"),
        (_csv([GOOD[0], "s1,mean,nan,-160,0,0.1"]), r"line 3: column 'load_kg' is 'nan': not all"),
        (_csv([GOOD[0], "s1,mean,40,-160,0,-0.2"]), r"line 3: gap_mm must be in \[-0.05, 50"),
        (
            _csv([*GOOD[:3], "s1,mean,60,-160,-10,0.3", "s1,mean,60,-160,5,0.2"]),
            r"line 5: case side=mean, load_kg=60, load_position_mm=-160 has 2 positions",
        ),
        (_csv(["s1,mean,250,-160,0,0.1"]), r"line 2: load_kg must be in \[0, 200\]"),
        (_csv(["s1,top,40,-160,0,0.1"]), r"line 2: side must be left, right or mean"),
        (_csv(["s1,mean,40,-160,1600,0.1"]), r"line 2: position_mm must be within"),
        (_csv([GOOD[0], "s2,mean,40,-160,0,0.1"]), r"line 3: ski_id 's2' differs"),
        (_csv(["s1,mean,40,-160,0"]), r"line 2: expected 6 columns, got 5$"),
        (_csv([*GOOD, "End of measurement"]), r"line 8: expected 6 columns, got 1: a note among"),
    ],
)
def test_csv_errors_are_precise(text, match):
    with pytest.raises(InputError, match=match):
        read_camber_csv(text)


def _one_case(beam):
    """One loaded case of ``beam`` (its unloaded gap as the profile) and a 2 m outline."""
    data = CamberData(
        "t",
        beam.positions_m,
        np.array([392.8]),
        np.array([-0.16]),
        ["mean"],
        beam.unloaded_gap_m[None, :],
    )
    return data, SkiOutline(2.0, 0.97, np.array([-0.97, 1.03]), np.array([0.044, 0.044]))


def test_ski_roundtrip_with_network(tmp_path):
    design = ClassicSkiDesign()
    beam = design.build(spacing_m=10e-3)
    data, outline = _one_case(beam)
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


def test_alternative_beams_round_trip_through_the_ski_file(tmp_path):
    """An identification's alternative beams are stored as ``identified/alternatives`` (one
    row per beam) and read back as beams on the identified beam's nodes; a file without them
    reads as none, one with rows of the wrong length is refused."""
    from dataclasses import replace

    from skisnow.app.storage.skis import (
        identified_alternatives,
        identified_to_dict,
        replace_ski_group,
    )
    from skisnow.solvers.identify import IdentifiedBeam

    beam = ClassicSkiDesign().build(spacing_m=10e-3)
    n = beam.positions_m.size
    other = replace(beam, bending_stiffness_nm2=1.2 * beam.bending_stiffness_nm2)
    third = replace(beam, unloaded_gap_m=beam.unloaded_gap_m + 2e-6)
    ident = IdentifiedBeam(
        beam=beam,
        ok=True,
        reason="",
        noise_m=3e-6,
        misfit_m=3e-6,
        case_misfit_m=np.full(2, 3e-6),
        stiffness_band_nm2=np.vstack([beam.bending_stiffness_nm2] * 2),
        camber_band_m=np.zeros(n),
        iterations=1,
        contact_passes=1,
        knots_m=np.linspace(beam.positions_m[0], beam.positions_m[-1], 5),
        log_compliance=np.zeros(5),
        log_compliance_covariance=np.eye(5),
        camber_sensitivity=np.zeros((n, 5)),
        camber_sd_m=np.zeros(n),
        alternative_beams=(other, third),
    )
    data, outline = _one_case(beam)
    path = tmp_path / "t.h5"
    write_ski(path, SkiRecord(data, outline, identified=identified_to_dict(ident)))
    back = identified_alternatives(read_ski(path).identified)
    assert len(back) == 2
    for got, want in zip(back, (other, third), strict=True):
        np.testing.assert_array_equal(got.positions_m, beam.positions_m)
        np.testing.assert_array_equal(got.bending_stiffness_nm2, want.bending_stiffness_nm2)
        np.testing.assert_array_equal(got.unloaded_gap_m, want.unloaded_gap_m)
    plain = identified_to_dict(replace(ident, alternative_beams=()))
    assert "alternatives" not in plain
    assert identified_alternatives(plain) == []
    failed = identified_to_dict(replace(ident, ok=False))
    assert identified_alternatives(failed) == []  # a failed identification serves nothing
    bad = identified_to_dict(ident)
    bad["alternatives"]["unloaded_gap_m"] = bad["alternatives"]["unloaded_gap_m"][:, :-1]
    replace_ski_group(path, "identified", bad)
    with pytest.raises(DataFileError, match="alternatives"):
        identified_alternatives(read_ski(path).identified)


@pytest.mark.parametrize("eol", ["\r\n", "\r"], ids=["CRLF", "CR (a Mac spreadsheet)"])
def test_line_ends_of_windows_and_mac_spreadsheets_read_the_same(tmp_path, eol):
    """A lone CR ends a line as CRLF and LF do, in the text and in a file."""
    text = _csv(GOOD).replace("\n", eol)
    plain = read_camber_csv(_csv(GOOD))
    path = tmp_path / "mac.csv"
    path.write_bytes(text.encode())
    for source in (text + "\n", path):
        d = read_camber_csv(source)
        np.testing.assert_array_equal(d.profiles_m, plain.profiles_m)
        np.testing.assert_array_equal(d.positions_m, plain.positions_m)


def test_a_file_is_read_in_its_encoding_line_by_line(tmp_path, monkeypatch):
    """A path is read in the encoding the whole file shows (a Windows byte far past the start
    makes it Windows-1252), a chunk at a time, never held whole."""
    from skisnow.app.storage import skis

    monkeypatch.setattr(skis, "_CHUNK_BYTES", 64)  # many chunks on a small file
    rows = [r.replace("s1", "Åre") for r in GOOD]
    text = _csv(rows[:3]) + "# " + "x" * 500 + "\n" + "".join(r + "\n" for r in rows[3:])
    for encoding, name in (("utf-8", "utf-8-sig"), ("cp1252", "cp1252")):
        path = tmp_path / f"{encoding}.csv"
        path.write_bytes(text.encode(encoding))
        assert skis._file_codec(path) == name
        d = read_camber_csv(path)
        assert d.ski_id == "Åre" and d.profiles_m.shape == (2, 3)
    reads = []
    real_open = open

    def spy(path, *a, **k):  # the lines come from the open file, not a decoded copy
        fh = real_open(path, *a, **k)
        reads.append(k.get("encoding"))
        return fh

    monkeypatch.setattr("builtins.open", spy)
    read_camber_csv(tmp_path / "cp1252.csv")
    assert reads[-1] == "cp1252"
    bad = tmp_path / "bad.csv"
    bad.write_bytes(b"\xff\xfe" + b"a\x00\x00\xd8")  # UTF-16 with a lone surrogate
    with pytest.raises(DataFileError, match="is not utf-16 text"):
        read_camber_csv(bad)


def test_numbers_written_with_their_column_s_unit_read_others_are_refused_with_the_change():
    rows = [r.split(",") for r in GOOD]
    with_units = [f"{a},{b},{c} kg,{d} mm,{e}mm,{f} mm" for a, b, c, d, e, f in rows]
    d = read_camber_csv(_csv(with_units))
    plain = read_camber_csv(_csv(GOOD))
    np.testing.assert_array_equal(d.profiles_m, plain.profiles_m)
    np.testing.assert_array_equal(d.loads_n, plain.loads_n)
    semicolon = _csv([r.replace(",", ";").replace(".", ",") for r in with_units])
    semicolon = semicolon.replace(HEADER, HEADER.replace(",", ";"))
    np.testing.assert_array_equal(read_camber_csv(semicolon).profiles_m, plain.profiles_m)
    with pytest.raises(InputError, match=r"'500 µm' \(gap is read in mm as gap_mm: divide µm"):
        read_camber_csv(_csv(["s1,mean,40,-160,-10,500 µm"]))
    with pytest.raises(InputError, match=r"'392 N' \(load is read in kg as load_kg: divide new"):
        read_camber_csv(_csv(["s1,mean,392 N,-160,-10,0.5"]))
    with pytest.raises(InputError, match=r"column 'gap_mm' is not a number: '0.5 zz'"):
        read_camber_csv(_csv(["s1,mean,40,-160,-10,0.5 zz"]))


def test_a_text_file_with_columns_apart_by_spaces_reads_the_same():
    """A device's .txt export: the columns apart by runs of spaces or tabs and spaces, decimal
    commas allowed (one mark per file), the same numbers as the neutral CSV."""
    plain = read_camber_csv(_csv(GOOD))
    spaced = "Ski_ID   Side  Load(kg)  Load_Position(mm)  Position(mm)  Gap(mm)\n" + "".join(
        "   ".join(r.split(",")).replace(".", ",") + " \t\n" for r in GOOD
    )
    d = read_camber_csv(spaced)
    np.testing.assert_array_equal(d.profiles_m, plain.profiles_m)
    np.testing.assert_array_equal(d.positions_m, plain.positions_m)
    np.testing.assert_array_equal(d.loads_n, plain.loads_n)
    with pytest.raises(InputError, match=r"line 3: column 'gap_mm' is '0\.0': this file's decimal"):
        read_camber_csv(spaced.replace("0,0 ", "0.0 "))


def test_spreadsheet_and_dataframe_quirks_are_named_with_what_to_change():
    # a decimal comma quoted by a spreadsheet in a comma-separated file
    quoted = _csv(['s1,mean,40,-160,-10,"0,5"'])
    with pytest.raises(InputError, match=r"is '0,5': a decimal comma in a comma-separated file"):
        read_camber_csv(quoted)
    # pandas' to_csv without index=False: an unnamed first column of row numbers
    indexed = "," + HEADER + "".join(f"{k},{r}\n" for k, r in enumerate(GOOD))
    with pytest.raises(InputError, match=r"a row index as pandas' to_csv writes it"):
        read_camber_csv(indexed)


def test_sides_written_l_and_r_read_as_left_and_right():
    plain = read_camber_csv(_csv([r.replace(",mean,", ",left,") for r in GOOD]))
    short = read_camber_csv(_csv([r.replace(",mean,", ",L,") for r in GOOD]))
    assert short.sides == plain.sides == ["left", "left"]
    np.testing.assert_array_equal(short.profiles_m, plain.profiles_m)
    assert read_camber_csv(_csv([r.replace(",mean,", ",r,") for r in GOOD])).sides[0] == "right"


@pytest.mark.parametrize(
    "header",
    [
        "position_mm;40 kg @ -100 mm;60 kg @ -100 mm",
        "Position (mm),40kg,60kg,80kg",
        "x_mm,gap_40kg_-100mm,gap_60kg_-100mm",
        "position_mm,40,60",
    ],
)
def test_a_sheet_with_one_column_per_load_case_is_told_to_unpivot(header):
    """A spreadsheet layout with one column of gaps per load case (the load in the column's
    name) is refused with how to lay it out: one row per sample."""
    sep = ";" if ";" in header else ","
    with pytest.raises(InputError) as info:
        read_camber_csv(header + "\n" + sep.join(["-970"] + ["1"] * header.count(sep)) + "\n")
    message = str(info.value)
    assert "look like one column of gaps per load case" in message, message
    assert (
        "unpivot the sheet into columns load_kg, load_position_mm, position_mm, gap_mm" in message
    )
    # a header that names the load column is not told so
    with pytest.raises(InputError) as info:
        read_camber_csv("ski_id,side,load_kg,position_mm,gap_mm,temp_1n\n")
    assert "one column of gaps per load case" not in str(info.value)
