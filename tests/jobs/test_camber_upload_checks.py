"""Upload-time checks of a ski's camber CSV (issue #26 point 5, docs/uploads.md): every
realistic file is accepted, or refused at upload with a message that says what to change.

The files are the issue's: a 5 × 5 grid, the unloaded 0 kg profile, positions in cm, gaps in
µm, a 33 MB file of 790 000 two-sample cases, a spreadsheet export; and a failed job's name,
which the next upload may take. The ski job itself is not run here (tests/jobs/test_uploads.py).
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from skisnow.app.jobs import uploads
from skisnow.app.storage.common import sha256_file
from skisnow.app.storage.skis import (
    CSV_COLUMNS,
    MAX_CAMBER_CASES,
    read_camber_csv,
    unloaded_mask,
)
from skisnow.app.web.upload_page import EXAMPLE_CSV_URL, example_camber_csv
from skisnow.solvers.errors import InputError
from test_uploads import is_problem, make_client, post_ski

REPO = Path(__file__).resolve().parents[2]
OUTLINE = {"length_mm": 2000.0, "width_mm": "44", "width_positions_mm": None}
MINIMUM_GRID = "measure at least 9 loads × 5 positions every ≤ 5 mm"


def check(text: str | bytes, **outline):
    data = text.encode() if isinstance(text, str) else text
    return uploads.check_ski_upload(data, "ski.csv", **{**OUTLINE, **outline})


def refused(text: str | bytes, **outline) -> str:
    with pytest.raises(InputError) as info:
        check(text, **outline)
    return str(info.value)


def rows_of(csv_bytes: bytes) -> tuple[str, list[list[str]]]:
    lines = csv_bytes.decode().splitlines()
    return lines[0], [line.split(",") for line in lines[1:]]


def with_unloaded(csv_bytes: bytes, sides=("mean",), load_position_mm="-160") -> str:
    """The CSV with an unloaded profile (0 kg, the first case's gaps less 0.1 mm as a
    stand-in) recorded first on each of ``sides``."""
    header, rows = rows_of(csv_bytes)
    first = [r for r in rows if r[2:4] == rows[0][2:4]]
    zero = []
    for side in sides:
        for r in first:
            zero.append([r[0], side, "0", load_position_mm, r[4], f"{float(r[5]) + 0.1:.4f}"])
    return "\n".join([header, *(",".join(r) for r in zero + rows)]) + "\n"


def test_the_smallest_grid_is_one_sentence_with_the_named_constants():
    assert uploads.minimum_grid_sentence().startswith(
        f"measure at least {uploads.MIN_GRID_LOADS} loads × "
        f"{uploads.MIN_GRID_LOAD_POSITIONS} positions every ≤ "
        f"{uploads.MAX_SAMPLE_SPACING_MM:g} mm"
    )
    assert uploads.minimum_grid_sentence().startswith(MINIMUM_GRID)


def test_a_5_by_5_grid_is_refused_at_upload_with_the_minimum_grid(camber_csv, upload_csv):
    message = refused(camber_csv)
    assert "5 loads × 5 load positions sampled every 5 mm" in message
    assert MINIMUM_GRID in message and "unloaded 0 kg profile" in message
    _, _, figures = check(upload_csv)  # 9 × 5 every 5 mm: accepted
    assert figures["load_cases"] == 45 and figures["unloaded_profile"] == []


def test_sampling_coarser_than_the_minimum_is_refused(upload_csv):
    header, rows = rows_of(upload_csv)
    xs = sorted({float(r[4]) for r in rows})
    every_2nd = {f"{x:g}" for x in xs[::2]}  # 10 mm
    text = "\n".join([header, *(",".join(r) for r in rows if r[4] in every_2nd)]) + "\n"
    message = refused(text)
    assert "9 loads × 5 load positions sampled every 10 mm" in message and MINIMUM_GRID in message


def test_the_unloaded_profile_is_accepted_as_one_case_with_no_load(upload_csv):
    text = with_unloaded(upload_csv, load_position_mm="-160")
    data, _, figures = check(text)
    assert figures["unloaded_profile"] == ["mean"] and figures["load_cases"] == 45
    assert figures["load_range_kg"] == [10.0, 90.0]
    mask = unloaded_mask(data)
    assert mask.tolist() == [True] + [False] * 45
    # its load position is ignored: stored as 0 (the convention x_F = 0 for F = 0)
    assert data.loads_n[0] == 0.0 and data.load_positions_m[0] == 0.0
    _, rows = rows_of(upload_csv)
    first = [float(r[5]) + 0.1 for r in rows if r[2:4] == rows[0][2:4]]
    np.testing.assert_allclose(data.profiles_m[0], np.round(first, 4) * 1e-3, rtol=0, atol=1e-12)
    # left and right unloaded profiles: one per side, averaged into one F = 0 case
    from skisnow.app.storage.skis import mean_profiles

    lr = read_camber_csv(with_unloaded(upload_csv, sides=("left", "right")))
    assert unloaded_mask(lr).sum() == 2
    f, xf, _, _ = mean_profiles(lr)
    assert (f == 0).sum() == 1 and xf[f == 0][0] == 0.0


def test_two_unloaded_profiles_of_one_side_are_refused_with_the_line(upload_csv):
    once = with_unloaded(upload_csv, load_position_mm="-160")
    lines = once.splitlines()
    n = sum(1 for line in lines if ",0,-160," in line)
    # a second one at another (ignored) load position
    second = [line.replace(",0,-160,", ",0,0,") for line in lines[1 : n + 1]]
    message = refused("\n".join([*lines[: n + 1], *second, *lines[n + 1 :]]) + "\n")
    assert message.startswith(f"line {n + 2}: a second unloaded profile (load_kg 0) of side mean")
    assert "first starts at line 2" in message
    # the same profile twice
    message = refused("\n".join([*lines[: n + 1], *lines[1 : n + 1], *lines[n + 1 :]]) + "\n")
    assert message.startswith(f"line {n + 2}: a second unloaded profile")
    # one per side is fine
    check(with_unloaded(upload_csv, sides=("mean",)))


def test_negative_loads_are_refused_with_the_line(upload_csv):
    header, rows = rows_of(upload_csv)
    rows[7][2] = "-20"
    message = refused("\n".join([header, *(",".join(r) for r in rows)]) + "\n")
    assert message == "line 9: load_kg must be > 0 (or 0 for the unloaded profile), got -20"


def test_positions_in_cm_are_refused_with_the_cm_hint(upload_csv):
    header, rows = rows_of(upload_csv)
    for r in rows:
        r[3], r[4] = f"{float(r[3]) / 10:g}", f"{float(r[4]) / 10:g}"
    message = refused("\n".join([header, *(",".join(r) for r in rows)]) + "\n")
    assert message.startswith("file: positions look like cm: the measured span 200 mm")
    assert "position_mm and load_position_mm are in mm" in message


@pytest.mark.parametrize(("factor", "unit"), [(25.4, "inches"), (1000.0, "m")])
def test_positions_in_inches_or_m_are_refused_with_the_conversion(upload_csv, factor, unit):
    header, rows = rows_of(upload_csv)
    for r in rows:
        r[3], r[4] = f"{float(r[3]) / factor:.6g}", f"{float(r[4]) / factor:.6g}"
    message = refused("\n".join([header, *(",".join(r) for r in rows)]) + "\n")
    assert message.startswith(f"file: positions look like {unit}: the measured span")
    assert f"about 1/{factor:g} of length_mm 2000" in message
    assert f"(multiply {unit} by {factor:g})" in message


def test_a_span_under_80_percent_of_the_length_is_refused_with_the_numbers(upload_csv):
    header, rows = rows_of(upload_csv)
    half = [r for r in rows if -500 <= float(r[4]) <= 500]  # 1000 mm of 2000 mm
    message = refused("\n".join([header, *(",".join(r) for r in half)]) + "\n")
    assert "the measured span 1000 mm covers 50 % of length_mm 2000" in message
    assert "at least 80 % of the ski's length (1600 mm)" in message


def test_gaps_in_um_are_refused_with_the_um_hint(upload_csv):
    header, rows = rows_of(upload_csv)
    for r in rows:
        r[5] = f"{float(r[5]) * 1000:.1f}"
    message = refused("\n".join([header, *(",".join(r) for r in rows)]) + "\n")
    assert message.startswith("line ")
    assert "values look like µm; gap_mm is in mm" in message


def test_the_790000_case_file_is_refused_by_the_case_cap(capsys):
    import time

    # the file: 790 000 cases of two samples each, 33 MB
    loads = np.repeat(np.round(np.linspace(1, 200, 1000), 3), 790)
    pos = np.tile(np.arange(-395, 395), 1000)
    body = "".join(
        f"s,mean,{f:g},{x},-1000,0.5\ns,mean,{f:g},{x},1000,0.5\n"
        for f, x in zip(loads, pos, strict=True)
    )
    data = (",".join(CSV_COLUMNS) + "\n" + body).encode()
    assert len(data) > 33e6
    t0 = time.perf_counter()
    message = refused(data)
    with capsys.disabled():
        print(
            f"\n790 000-case file ({len(data) / 1e6:.1f} MB) refused in "
            f"{time.perf_counter() - t0:.3f} s"
        )
    assert message.startswith(f"line {2 * MAX_CAMBER_CASES + 2}: more than {MAX_CAMBER_CASES}")
    assert "max_camber_cases" in message
    # the caps are the upload's: a file already accepted (the ski job reads the stored CSV
    # with the settings of its own process) is read without them
    head = data[: data.index(b"\n", 45 * 2 * (MAX_CAMBER_CASES + 1)) + 1]
    many = b"\n".join(head.split(b"\n")[: 2 * (MAX_CAMBER_CASES + 1) + 1]) + b"\n"
    assert read_camber_csv(many.decode()).loads_n.size == MAX_CAMBER_CASES + 1
    assert "more than 2000" in refused(many)
    # the row cap stops a file of few cases and many rows the same way
    rows = "".join(f"s,mean,40,0,{x},0.5\n" for x in range(-1500, 1501))
    message = refused(",".join(CSV_COLUMNS) + "\n" + rows, max_rows=1000)
    assert (
        message.startswith("line 1002: more than 1000 data rows") and "max_camber_rows" in message
    )


def _spreadsheet(neutral: str) -> str:
    """The neutral CSV as a spreadsheet exports it: `;`, decimal commas, capitalised headers in
    another order with spaces, a BOM, CRLF, an empty trailing column and trailing separators."""
    order = [5, 0, 2, 1, 4, 3]
    lines = neutral.splitlines()
    head = [c.capitalize() for c in lines[0].split(",")]
    out = ["\ufeff" + ";".join(f" {head[k]} " for k in order) + ";;"]
    for line in lines[1:]:
        cells = line.split(",")
        out.append(";".join(cells[k].replace(".", ",") for k in order) + ";;")
    return "\r\n".join(out) + "\r\n"


def test_a_spreadsheet_csv_reads_to_the_same_data_as_the_neutral_file(upload_csv):
    neutral = with_unloaded(upload_csv)
    sheet = _spreadsheet(neutral)
    assert sheet.count(";;") > 1000 and "0,1" in sheet and sheet.startswith("\ufeff Gap_mm ;")
    a, _, fig_a = check(neutral)
    b, _, fig_b = check(sheet)
    assert fig_a == fig_b
    assert a.ski_id == b.ski_id and a.sides == b.sides
    for name in ("positions_m", "loads_n", "load_positions_m", "profiles_m"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    # tab-separated, decimal points
    tabbed = neutral.replace(",", "\t")
    c = read_camber_csv(tabbed)
    np.testing.assert_array_equal(c.profiles_m, a.profiles_m)


def test_spreadsheet_problems_are_named(upload_csv):
    neutral = upload_csv.decode()
    lines = neutral.splitlines()
    # a device's extra column is not read, and the answer says so
    extra = "\n".join([lines[0] + ",Temp_C", *(line + ",-5" for line in lines[1:])]) + "\n"
    data, _, figures = check(extra)
    _same_data(data, check(upload_csv)[0])
    assert figures["columns_ignored"] == ["temp_c"]
    assert "columns not read: 'temp_c' (not camber data" in " ".join(figures["notes"])
    # ... but named when a needed column is missing (a misspelt one, say)
    misspelt = extra.replace("gap_mm", "gap_mn", 1)
    message = refused(misspelt)
    assert (
        "missing gap_mm; other column(s) 'gap_mn' (did you mean gap_mm?), 'temp_c' (remove"
        in message
    )
    # a value under no name is refused
    unnamed = "\n".join([lines[0] + ",", *(line + ",-5" for line in lines[1:])]) + "\n"
    assert "a value in column 7, which has no name in the header" in refused(unnamed)
    missing = "\n".join(line.rsplit(",", 1)[0] for line in lines) + "\n"
    assert "missing gap_mm" in refused(missing)
    sheet = _spreadsheet(neutral).splitlines()
    sheet[5] = sheet[5].replace(",", ".", 1)  # one number with a decimal point among commas
    assert re.match(
        r"line 6: column '\w+' is '[^']*': this file's decimal mark is ','",
        refused("\n".join(sheet) + "\n"),
    )


def _same_data(a, b) -> None:
    assert a.ski_id == b.ski_id and a.sides == b.sides
    for name in ("positions_m", "loads_n", "load_positions_m", "profiles_m"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@pytest.mark.parametrize(
    "header",
    [
        "Ski ID,Side,Load (kg),Load position (mm),Position (mm),Gap (mm)",
        "ski_id,side,load_kg [kg],load_position_mm [mm],position_mm [mm],gap_mm [mm]",
        "SKI-ID,Side,Load kg,Load-position mm,Position  mm,Gap.mm",
    ],
)
def test_headers_with_spaces_or_units_in_brackets_name_the_same_columns(upload_csv, header):
    neutral = upload_csv.decode()
    lines = neutral.splitlines()
    a, _, fig_a = check(neutral)
    b, _, fig_b = check("\n".join([header, *lines[1:]]) + "\n")
    assert fig_a == fig_b
    _same_data(a, b)


@pytest.mark.parametrize(
    "header",
    [
        "ski_id,side,Weight (kg),LoadPos(mm),Pos (mm),Height (mm)",
        "ski_id,side,mass_kg,load_pos_mm,x [mm],clearance_mm",
        "ski_id,side,F (kg),xF (mm),Distance (mm),Camber (mm)",
    ],
)
def test_columns_named_another_way_with_their_unit_are_read_and_said(upload_csv, header):
    neutral = upload_csv.decode()
    lines = neutral.splitlines()
    a, _, fig_a = check(neutral)
    b, _, fig_b = check("\n".join([header, *lines[1:]]) + "\n")
    _same_data(a, b)
    cells = [c.strip().lower() for c in header.split(",")[2:]]
    want = [f"{c!r} as {k}" for c, k in zip(cells, CSV_COLUMNS[2:], strict=True)]
    assert list(b.renamed_columns) == fig_b["columns_renamed"] == want
    assert fig_a["columns_renamed"] == []
    assert "columns read by another name: " + ", ".join(want) in fig_b["notes"]


def test_another_name_without_a_unit_is_refused_with_the_name_to_write(upload_csv):
    lines = upload_csv.decode().splitlines()
    header = lines[0].replace("gap_mm", "Gap").replace("position_mm", "Pos")
    header = header.replace("load_Pos", "load_position_mm")  # only the sample position
    message = refused("\n".join([header, *lines[1:]]) + "\n")
    assert "missing position_mm, gap_mm" in message
    assert "'pos' (no unit: name it position_mm if it is in mm)" in message
    assert "'gap' (no unit: name it gap_mm if it is in mm)" in message
    # another unit: the conversion, as for the column's own name
    header = lines[0].replace("gap_mm", "Height (µm)")
    message = refused("\n".join([header, *lines[1:]]) + "\n")
    assert "'height (µm)' (gap is read in mm as gap_mm: divide µm by 1000 for mm)" in message


def test_a_column_s_own_name_wins_over_another_name_of_it(upload_csv):
    neutral = upload_csv.decode()
    lines = neutral.splitlines()
    extra = "\n".join([lines[0] + ",Height (mm)", *(line + ",12.5" for line in lines[1:])])
    data, _, figures = check(extra + "\n")
    _same_data(data, check(neutral)[0])
    assert figures["columns_ignored"] == ["height (mm)"] and figures["columns_renamed"] == []
    # two other names of one column: refused, both named
    two = lines[0].replace("gap_mm", "Height (mm)") + ",Clearance (mm)"
    rows = [line + ",12.5" for line in lines[1:]]
    message = refused("\n".join([two, *rows]) + "\n")
    assert "repeated gap_mm ('height (mm)', 'clearance (mm)')" in message


@pytest.mark.parametrize(
    ("column", "name", "words"),
    [
        (
            2,
            "Load (N)",
            "'load (n)' (load is read in kg as load_kg: divide newtons by 9.82 for kg)",
        ),
        (5, "Gap (µm)", "'gap (µm)' (gap is read in mm as gap_mm: divide µm by 1000 for mm)"),
        (4, "position_cm", "'position_cm' (position is read in mm as position_mm: multiply cm"),
        (3, "load position [m]", "load_position is read in mm as load_position_mm: multiply m"),
    ],
)
def test_a_column_in_another_unit_is_refused_with_the_conversion(upload_csv, column, name, words):
    lines = upload_csv.decode().splitlines()
    header = lines[0].split(",")
    header[column] = name
    message = refused("\n".join([",".join(header), *lines[1:]]) + "\n")
    assert message.startswith("line 1: header must name the columns")
    assert f"missing {CSV_COLUMNS[column]}" in message and words in message


@pytest.mark.parametrize(
    ("encode", "encoding"),
    [
        (lambda t: t.encode("utf-16"), "UTF-16"),  # with its byte-order mark
        (lambda t: t.encode("utf-16-le"), "UTF-16"),  # "Unicode text" without one
        (lambda t: t.encode("utf-16-be"), "UTF-16"),
        (lambda t: t.encode("cp1252"), "Windows-1252"),
        (lambda t: "\ufeff".encode() + t.encode(), "UTF-8"),
    ],
)
def test_unicode_and_windows_text_files_read_to_the_same_data(
    upload_csv, tmp_path, encode, encoding
):
    # a name with letters outside ASCII, as a Windows spreadsheet saves it
    text = upload_csv.decode().replace("my-ski", "Åsarna µ-ski")
    a, _, fig_a = check(text)
    data = encode(text)
    b, _, fig_b = check(data)
    assert fig_b["text_encoding"] == encoding and fig_a["text_encoding"] == "UTF-8"
    assert {**fig_a, "text_encoding": encoding} == fig_b
    _same_data(a, b)
    assert b.ski_id == "Åsarna µ-ski"
    # the ski job reads the stored bytes (a path) the same way
    path = tmp_path / "ski.csv"
    path.write_bytes(data)
    _same_data(a, read_camber_csv(path))


def test_bytes_that_are_no_text_are_refused_with_what_to_save(upload_csv):
    from skisnow.app.errors import UnsupportedContentError

    for data in (b"\x00\x01binary", b"PK\x03\x04\x00\x00" + upload_csv[:200]):
        with pytest.raises(UnsupportedContentError, match="save it from the spreadsheet as CSV"):
            check(data)
    # a workbook by its name: how to save it
    for name in ("ski.xlsx", "Ski.ODS"):
        with pytest.raises(UnsupportedContentError, match="save the sheet as CSV"):
            uploads.check_ski_upload(upload_csv, name, **OUTLINE)
    with pytest.raises(UnsupportedContentError, match=r"neutral \.csv file \(or a device"):
        uploads.check_ski_upload(upload_csv, "ski.dat", **OUTLINE)


def test_values_in_other_units_or_conventions_are_refused_with_the_change(upload_csv):
    header, rows = rows_of(upload_csv)

    def text(rs) -> str:
        return "\n".join([header, *(",".join(r) for r in rs)]) + "\n"

    newtons = [[*r[:2], f"{float(r[2]) * 9.82:g}", *r[3:]] for r in rows]
    assert "loads above 200 kg look like newtons; load_kg is in kg (divide N by 9.82)" in refused(
        text(newtons)
    )
    heights = [[*r[:5], f"{-float(r[5]):.4f}"] for r in rows]
    message = refused(text(heights))
    assert message.startswith("line 2: gap_mm must be in [-0.05, 50.0]")
    assert "change the sign of the column" in message
    # positions from the tail of a 2 m ski: beyond ±1500 mm
    tail = [[*r[:3], f"{float(r[3]) + 1000:g}", f"{float(r[4]) + 1000:g}", r[5]] for r in rows]
    message = refused(text(tail))
    assert "must be within ±1500 mm" in message and "looks measured from the ski's end" in message
    # ... and of a 1.4 m junior ski: within ±1500 mm, all on one side of the balance point
    junior = [r for r in tail if float(r[4]) <= 1400]
    message = refused(text(junior), length_mm=1450.0)
    assert message.startswith("file: positions look measured from the tail: all of them (")
    assert "subtract the balance point's distance from the tail (about 725 mm" in message


def test_positions_listed_from_the_tip_read_as_the_same_samples(upload_csv):
    neutral = with_unloaded(upload_csv)
    lines = neutral.splitlines()
    header, rows = lines[0], lines[1:]
    cases: dict[str, list[str]] = {}
    for row in rows:
        cases.setdefault(",".join(row.split(",")[1:4]), []).append(row)
    tip_first = [row for case in cases.values() for row in reversed(case)]
    a, _, fig_a = check(neutral)
    b, _, fig_b = check("\n".join([header, *tip_first]) + "\n")
    _same_data(a, b)
    assert not a.read_descending and b.read_descending
    assert fig_a["positions_in_file"] == "increasing"
    assert fig_b["positions_in_file"] == "decreasing (read in increasing order)"
    assert {**fig_a, "positions_in_file": ""} == {**fig_b, "positions_in_file": ""}
    # one order for every case: a case listed the other way is refused with its line
    cases_list = list(cases.values())
    mixed = [*reversed(cases_list[0]), *(r for c in cases_list[1:] for r in c)]
    message = refused("\n".join([header, *mixed]) + "\n")
    assert re.match(r"line \d+: position_mm \S+ is not smaller than the previous position", message)
    assert "the same way in every case" in message
    # a second unloaded profile is still found when the file runs from the tip
    zero = [r for r in tip_first if r.split(",")[2] == "0"]
    message = refused("\n".join([header, *zero, *tip_first]) + "\n")
    assert "a second unloaded profile (load_kg 0) of side mean" in message


def test_an_empty_load_and_a_too_fine_sampling_are_refused_with_what_to_change(upload_csv):
    header, rows = rows_of(upload_csv)
    rows[20][2] = ""
    message = refused("\n".join([header, *(",".join(r) for r in rows)]) + "\n")
    assert message.startswith("line 22: column 'load_kg' is empty: every row needs its load_kg")
    # 0.25 mm sampling of one case: the row cap says to thin the positions
    fine = "".join(f"s,mean,40,0,{x / 4:g},0.5\n" for x in range(-4000, 4001))
    message = refused(",".join(CSV_COLUMNS) + "\n" + fine, max_rows=5000)
    assert "its first case has 5000 samples every 0.25 mm: every 1–5 mm is enough" in message


def _with_unmeasured(csv_bytes: bytes, where: dict[tuple[int, int], str]) -> tuple[str, list]:
    """The CSV with the gap of (case, sample) replaced by the token given (an unmeasured
    sample), and the rows as read."""
    header, rows = rows_of(csv_bytes)
    n = len([r for r in rows if r[2:4] == rows[0][2:4]])
    for (case, k), token in where.items():
        rows[case * n + k][5] = token
    return "\n".join([header, *(",".join(r) for r in rows)]) + "\n", rows


def test_unmeasured_gaps_drop_their_positions_from_every_case_and_say_so(upload_csv):
    """A device that lost the base writes no gap (empty, NaN, -, #N/A): every case keeps the
    longest stretch every case measured, nothing is filled in, and the answer says which
    positions went and what it cost (docs/macro.md "Unmeasured samples")."""
    plain, _, _ = check(upload_csv)
    n = plain.positions_m.size
    # the tip's last two samples out of range in every case; near the tail, readings lost in
    # three cases; one more near the tip
    where = {(c, k): "" for c in range(plain.loads_n.size) for k in (n - 2, n - 1)}
    where |= {(3, 0): "NaN", (7, 2): "#N/A", (8, 1): "-", (2, n - 4): " nan "}
    text, _ = _with_unmeasured(upload_csv, where)
    data, _, figures = check(text)
    keep = np.zeros(n, dtype=bool)
    keep[3 : n - 4] = True  # the longest stretch measured in every case
    np.testing.assert_array_equal(data.positions_m, plain.positions_m[keep])
    np.testing.assert_array_equal(data.profiles_m, plain.profiles_m[:, keep])  # as measured
    np.testing.assert_allclose(data.dropped_positions_mm, plain.positions_m[~keep] * 1e3)
    cases = plain.loads_n.size
    assert figures["unmeasured"] == {
        "choice": "drop",
        "samples": len(where),
        "samples_not_listed": 0,
        "positions_dropped_mm": list(data.dropped_positions_mm),
        "measured_samples_set_aside": 7 * cases - len(where),
        "positions_absent_mm": [],
        "cases_dropped": [],
    }
    assert figures["position_shift_mm"] == 0.0
    note = [t for t in figures["notes"] if "unmeasured samples" in t]
    assert len(note) == 1 and "dropped from every case" in note[0], figures["notes"]
    x_mm = plain.positions_m * 1e3
    assert f"({x_mm[0]:g} … {x_mm[2]:g} mm, {x_mm[n - 4]:g} … {x_mm[n - 1]:g} mm)" in note[0]
    # refused on request, at the first unmeasured sample's line
    message = refused(text, unmeasured="refuse")
    # (the first: case 0's sample n − 2, on line n of the file)
    assert message.startswith(f"line {n}: column 'gap_mm' is 'empty', an unmeasured sample")
    assert "unmeasured=drop" in message


def _with_positions(csv_bytes: bytes, position) -> str:
    """The CSV with every position_mm x replaced by ``position(x)`` (a string; None leaves the
    row out)."""
    header, rows = rows_of(csv_bytes)
    out = []
    for r in rows:
        text = position(float(r[4]))
        if text is not None:
            out.append(",".join([*r[:4], text, *r[5:]]))
    return "\n".join([header, *out]) + "\n"


@pytest.mark.parametrize(
    ("step_mm", "digits"), [(10 / 3, 2), (4.7625, 0), (4.7625, 1), (4.7625, 2)]
)
def test_positions_written_rounded_are_read_as_the_grid_they_round(upload_csv, step_mm, digits):
    """A device stepping 10/3 mm (or 3/16 in = 4.7625 mm) writes its positions rounded: they are
    read as the uniform grid they round, each within half its last digit, and said so; the
    gaps as written. The identification needs a uniform grid (it refused these in the job)."""
    plain, _, _ = check(upload_csv)
    step = plain.sample_spacing_mm
    exact = plain.positions_m * 1e3 * step_mm / step
    text = _with_positions(upload_csv, lambda x: f"{x * step_mm / step:.{digits}f}")
    data, _, figures = check(text, length_mm=round(float(np.ptp(exact)) / 0.95))
    written = np.array([float(f"{v:.{digits}f}") for v in exact])
    half = 0.5 * 10.0**-digits
    read = data.positions_m * 1e3  # a grid within half a digit of every written position
    np.testing.assert_allclose(read, written, rtol=0, atol=half * (1 + 1e-6))
    np.testing.assert_allclose(read, exact, rtol=0, atol=2 * half)
    dx = np.diff(data.positions_m)
    assert np.ptp(dx) <= 1e-6 * dx.mean()  # what identify_start asks of the grid
    np.testing.assert_array_equal(data.profiles_m, plain.profiles_m)  # the gaps as written
    shift = float(np.max(np.abs(written - read)))
    assert figures["position_shift_mm"] == pytest.approx(shift, abs=1e-9)
    assert 0 < shift <= half * (1 + 1e-6)
    note = [t for t in figures["notes"] if t.startswith("positions read as the uniform grid")]
    assert data.sample_spacing_mm == pytest.approx(step_mm, rel=1e-4)
    assert len(note) == 1 and f"{data.sample_spacing_mm:.6g} mm steps" in note[0], note


def test_positions_off_a_uniform_grid_are_refused_at_upload_with_the_line(upload_csv):
    """Positions an encoder read as they came (jitter beyond the written digits) are no
    uniform grid: refused at upload, naming the position, instead of failing in the job."""
    plain, _, _ = check(upload_csv)
    x_mm = plain.positions_m * 1e3
    shifted = {round(float(x_mm[57]), 6): f"{x_mm[57] + 0.12:.2f}"}
    text = _with_positions(upload_csv, lambda x: shifted.get(round(x, 6), f"{x:.2f}"))
    message = refused(text)
    # the first case's sample 57 (line 59, after the header and the unloaded case's first row)
    assert re.match(rf"line \d+: position_mm {x_mm[57] + 0.12:g} lies 0\.12 mm off the", message)
    assert "written to 0.01 mm" in message and "interpolate every case" in message
    # a step much smaller than the others: not a grid either
    step = float(x_mm[1] - x_mm[0])
    close = {round(float(x_mm[57]), 6): f"{x_mm[56] + 0.1 * step:g}"}
    message = refused(_with_positions(upload_csv, lambda x: close.get(round(x, 6), f"{x:g}")))
    assert re.match(rf"line \d+: position_mm {x_mm[56] + 0.1 * step:g} follows", message)
    assert "must be one uniform grid" in message


def test_positions_absent_from_every_case_are_unmeasured_samples(upload_csv):
    """A device that skipped a step lists no row at that position: the position is read as
    unmeasured in every case (near an end: dropped with the stretch; inside the span:
    refused as unmeasured samples are), named in the answer."""
    plain, _, _ = check(upload_csv)
    x_mm = plain.positions_m * 1e3
    n = x_mm.size
    tip = round(float(x_mm[n - 3]), 6)
    text = _with_positions(upload_csv, lambda x: None if round(x, 6) == tip else f"{x:g}")
    data, _, figures = check(text)
    np.testing.assert_array_equal(data.positions_m, plain.positions_m[: n - 3])
    np.testing.assert_array_equal(data.profiles_m, plain.profiles_m[:, : n - 3])
    assert data.absent_positions_mm == (x_mm[n - 3],)
    assert figures["unmeasured"]["positions_dropped_mm"] == list(x_mm[n - 3 :])
    assert figures["unmeasured"]["samples"] == 0
    note = [t for t in figures["notes"] if "absent from every case" in t]
    assert len(note) == 1 and "1 position of the grid absent" in note[0], figures["notes"]
    assert "refused (unmeasured=refuse)" in refused(text, unmeasured="refuse")
    middle = round(float(x_mm[n // 2]), 6)
    text = _with_positions(upload_csv, lambda x: None if round(x, 6) == middle else f"{x:g}")
    message = refused(text)
    assert f"absent from every case ({x_mm[n // 2]:g} mm)" in message
    assert "measure every case at every position of the grid" in message


def _case_rows(csv_bytes: bytes) -> tuple[str, dict]:
    header, rows = rows_of(csv_bytes)
    cases: dict = {}
    for r in rows:
        cases.setdefault(tuple(r[1:4]), []).append(r)
    return header, cases


def _joined(header: str, cases: dict) -> str:
    return "\n".join([header, *(",".join(r) for rows in cases.values() for r in rows)]) + "\n"


def test_rows_a_case_leaves_out_are_its_unmeasured_samples(upload_csv):
    """A device that started a pass late lists fewer rows in that case: the rows it leaves out
    of the others' grid are unmeasured samples (near an end: the positions go; inside the span:
    the case goes), said in the answer; unmeasured=refuse refuses them, naming the case."""
    plain, _, _ = check(upload_csv)
    header, cases = _case_rows(upload_csv)
    keys = list(cases)
    late = {k: rows[2:] if i == 3 else rows for i, (k, rows) in enumerate(cases.items())}
    data, _, figures = check(_joined(header, late))
    np.testing.assert_array_equal(data.positions_m, plain.positions_m[2:])
    np.testing.assert_array_equal(data.profiles_m, plain.profiles_m[:, 2:])
    assert data.omitted_samples == figures["unmeasured"]["samples_not_listed"] == 2
    assert figures["unmeasured"]["positions_dropped_mm"] == list(plain.positions_m[:2] * 1e3)
    assert any("2 samples of the grid not listed by their case" in t for t in figures["notes"])
    message = refused(_joined(header, late), unmeasured="refuse")
    assert "does not list 2 of the positions other cases list" in message
    assert message.startswith(f"line {2 + sum(len(cases[k]) for k in keys[:3])}: case ")
    # a pass at twice the step: rows left out inside the span cost the case
    header, coarse = _case_rows(_one_more_load(upload_csv))
    coarse[keys[3]] = coarse[keys[3]][::2]
    data, _, figures = check(_joined(header, coarse))
    side, load, at = keys[3]
    assert data.dropped_cases == (
        f"side={side}, load_kg={load}, load_position_mm={at} "
        f"(line {2 + sum(len(cases[k]) for k in keys[:3])})",
    )
    assert figures["unmeasured"]["samples_not_listed"] == len(cases[keys[3]]) // 2


def test_a_case_off_the_others_grid_or_of_a_few_rows_is_refused_naming_it(upload_csv):
    header, cases = _case_rows(upload_csv)
    keys = list(cases)
    shifted = dict(cases)
    shifted[keys[4]] = [[*r[:4], f"{float(r[4]) + 2:g}", r[5]] for r in cases[keys[4]]]
    message = refused(_joined(header, shifted))
    assert "all cases must share one sampling grid" in message
    assert f"load_kg={float(keys[4][1]):g}, load_position_mm={float(keys[4][2]):g}" in message
    typo = dict(cases)
    row = cases[keys[4]][100]
    typo[keys[4]] = [r for r in cases[keys[4]] if r is not row]
    typo[("mean", keys[4][1], "1000")] = [[*row[:3], "1000", *row[4:]]]
    message = refused(_joined(header, typo))
    assert "load_position_mm=1000 has 1 positions" in message
    assert "a case of a few rows: check its load_kg and load_position_mm" in message


def _one_more_load(csv_bytes: bytes) -> bytes:
    """The CSV with a tenth load level: the first load's cases again, 1 kg heavier (a grid
    above the smallest, for the checks that leave cases out; not a physical measurement)."""
    header, rows = rows_of(csv_bytes)
    first = rows[0][2]
    extra = [[*r[:2], f"{float(first) + 1:g}", *r[3:]] for r in rows if r[2] == first]
    return ("\n".join([header, *(",".join(r) for r in [*rows, *extra])]) + "\n").encode()


def test_a_reading_lost_inside_the_span_costs_its_case(upload_csv):
    """A reading lost in the middle of the span (a dust spot) would drop everything beyond it
    from every case; leaving that case out sets aside far fewer measured samples, so the case
    goes, named in the answer; the other cases keep every position. On the smallest grid
    that gets a served beam, a case left out leaves it below that grid: the answer says what
    that was measured to cost (docs/studies/case-loss-coarse.md)."""
    n = check(upload_csv)[0].positions_m.size
    _, _, figures = check(_with_unmeasured(upload_csv, {(4, n // 2): "NaN"})[0])
    note = [t for t in figures["notes"] if "after leaving out" in t]
    assert note == [
        "44 load cases after leaving out 1, fewer than the 45 of the smallest grid that gets a "
        "served beam (9 × 5; with 1 left out a beam was served on 29 of 30 measured files, "
        "docs/uploads.md): measuring it again is the surer way"
    ], figures["notes"]
    upload_csv = _one_more_load(upload_csv)
    plain, _, _ = check(upload_csv)
    n, cases = plain.positions_m.size, plain.loads_n.size
    text, _ = _with_unmeasured(upload_csv, {(4, n // 2): "NaN", (9, n // 3): ""})
    data, _, figures = check(text)
    kept = np.setdiff1d(np.arange(cases), [4, 9])
    np.testing.assert_array_equal(data.positions_m, plain.positions_m)
    np.testing.assert_array_equal(data.profiles_m, plain.profiles_m[kept])  # as measured
    np.testing.assert_array_equal(data.loads_n, plain.loads_n[kept])
    dropped = figures["unmeasured"]
    assert dropped["positions_dropped_mm"] == []
    assert dropped["measured_samples_set_aside"] == 2 * (n - 1)
    assert len(dropped["cases_dropped"]) == 2
    assert dropped["cases_dropped"][0] == (
        f"side=mean, load_kg={plain.loads_n[4] / 9.82:g}, load_position_mm="
        f"{plain.load_positions_m[4] * 1e3:g} (line {2 + 4 * n})"
    )
    note = [t for t in figures["notes"] if "unmeasured samples" in t]
    assert (
        len(note) == 1
        and "the 2 cases with an unmeasured sample inside it are left out" in (note[0])
    ), figures["notes"]
    assert not [t for t in figures["notes"] if "after leaving out" in t]  # 48 cases of 45
    # a case with no gap at all is left out too (it sets aside nothing measured)
    data, _, figures = check(_with_unmeasured(upload_csv, {(4, k): "" for k in range(n)})[0])
    assert data.loads_n.size == cases - 1
    assert figures["unmeasured"]["measured_samples_set_aside"] == 0


def test_a_case_left_out_takes_its_twin_on_the_other_side(upload_csv):
    """Left and right profiles of a load case are averaged: a case left out for a reading lost
    inside the span takes its twin with it, and the cases kept still pair up."""
    header, rows = rows_of(_one_more_load(upload_csv))
    n = check(upload_csv)[0].positions_m.size
    sides = [[r[0], side, *r[2:]] for side in ("left", "right") for r in rows]
    lost = len(rows) + 6 * n + n // 2  # the right side's seventh case, mid-span
    sides[lost][5] = "NaN"
    data, _, figures = check("\n".join([header, *(",".join(r) for r in sides)]) + "\n")
    left_out = figures["unmeasured"]["cases_dropped"]
    assert [c.split(",")[0] for c in left_out] == ["side=left", "side=right"], left_out
    assert (
        left_out[0].split(" (line")[0].split(", ", 1)[1]
        == (left_out[1].split(" (line")[0].split(", ", 1)[1])
    )
    assert data.loads_n.size == 2 * (len(rows) // n - 1)
    assert figures["measured_side"] == "left+right"


def test_unmeasured_gaps_that_would_cost_too_much_are_refused_with_the_case(upload_csv):
    plain, _, _ = check(upload_csv)
    n, cases = plain.positions_m.size, plain.loads_n.size
    # readings lost inside the span in more than 10 % of the cases: leaving them out, or
    # dropping everything beyond the losses, both cost too much
    lost = {(c, n // 2 + c): "NaN" for c in range(1, cases, 7)}
    assert len(lost) > 0.1 * cases
    message = refused(_with_unmeasured(upload_csv, lost)[0])
    assert "the least that keeps one uniform grid is the stretch" in message
    assert "more than 10 %" in message and "measure the cases with unmeasured" in message
    assert "the most in case side=mean" in message
    # no case with two neighbouring measured positions leaves no grid
    every_other = {(c, k): "" for c in range(cases) for k in range(0, n, 2)}
    assert "no two neighbouring positions are measured in any case" in refused(
        _with_unmeasured(upload_csv, every_other)[0]
    )
    # infinity is no reading
    text, _ = _with_unmeasured(upload_csv, {(4, 7): "inf"})
    assert "is 'inf': not a gap (an unmeasured sample is left empty or written NaN)" in refused(
        text
    )


def test_the_unmeasured_choice_is_a_form_field_kept_for_the_job(catalogue, tmp_path, upload_csv):
    plain, _, _ = check(upload_csv)
    text, _ = _with_unmeasured(upload_csv, {(2, 3): "NaN"})
    with make_client(catalogue, tmp_path) as client:
        r = post_ski(client, text.encode(), name="dropped", unmeasured="refuse")
        assert "unmeasured sample, refused" in is_problem(r, 422)["detail"]
        r = post_ski(client, text.encode(), name="dropped", unmeasured="fill")
        assert "unmeasured" in str(is_problem(r, 422))
        r = post_ski(client, text.encode(), name="dropped")
        assert r.status_code == 202, r.text[:500]
        # the fourth sample from the tail: the tail's first four positions go
        assert r.json()["data"]["unmeasured"]["positions_dropped_mm"] == pytest.approx(
            plain.positions_m[:4] * 1e3
        )
        item = client.get("/v1/skis/dropped").json()
        assert item["metadata"]["unmeasured"] == "drop"


def test_comment_lines_and_a_separator_line_are_read_past_with_the_file_s_line_numbers(
    upload_csv,
):
    neutral = upload_csv.decode()
    lines = neutral.splitlines()
    preamble = ["# device: camber rig 2, 2026-12-01", "", "#operator;  J. Doe"]
    a, _, _ = check(neutral)
    b, _, _ = check("\n".join([*preamble, *lines[:3], "# re-zeroed", *lines[3:]]) + "\n")
    _same_data(a, b)
    sheet = _spreadsheet(neutral).lstrip("\ufeff")
    c, _, _ = check("sep=;\r\n" + sheet)
    _same_data(a, c)
    # errors name the line of the file, comments counted
    rows = lines[1:]
    rows[4] = rows[4].rsplit(",", 1)[0] + ",x"
    message = refused("\n".join([*preamble, lines[0], *rows]) + "\n")
    assert message.startswith("line 9: column 'gap_mm' is not a number: 'x'")
    assert refused("\n".join([*preamble, "a,b"]) + "\n").startswith("line 4: header must")
    assert refused("# only a comment\n").startswith("line 1: no header line after the comments")


def test_a_device_s_lines_before_the_header_are_read_past_and_said(upload_csv):
    neutral = upload_csv.decode()
    notes = "Device: SkiFlex 3000\nSki; Fischer Speedmax 3D\nDate: 2026-12-01\n\n"
    data, _, figures = check(notes + neutral)
    _same_data(data, check(neutral)[0])
    said = ["Device: SkiFlex 3000", "Ski; Fischer Speedmax 3D", "Date: 2026-12-01"]
    assert list(data.preamble_lines) == figures["lines_before_header"] == said
    assert any(n.startswith("3 lines before the header read past (not") for n in figures["notes"])
    # a misspelt header after them: its own refusal, with its line
    message = refused(notes + neutral.replace("gap_mm", "gap_mn", 1))
    assert message.startswith("line 5: header must name the columns")
    assert "missing gap_mm; other column(s) 'gap_mn'" in message
    # no header before the data: the first line's refusal, read no further
    message = refused("\n".join(neutral.splitlines()[1:]) + "\n")
    assert message.startswith("line 1: header must name the columns")


@pytest.mark.parametrize(
    ("units", "refusal"),
    [
        ("-,-,kg,mm,mm,mm", None),
        (",,[kg],(mm),[mm],mm", None),
        (",,kg,mm,mm,µm", "gap_mm in 'µm' (gap is read in mm as gap_mm: divide µm by 1000 for mm)"),
        (",,N,mm,mm,mm", "load_kg in 'N' (load is read in kg as load_kg: divide newtons by 9.82"),
        (",,kg,cm,cm,mm", "load_position_mm in 'cm' (load_position is read in mm as"),
    ],
)
def test_a_row_of_units_under_the_header_is_read_past_when_it_names_the_units(
    upload_csv, units, refusal
):
    lines = upload_csv.decode().splitlines()
    text = "\n".join([lines[0], units, *lines[1:]]) + "\n"
    if refusal is None:
        a, _, fig_a = check(upload_csv)
        b, _, fig_b = check(text)
        assert fig_a == fig_b
        _same_data(a, b)
    else:
        message = refused(text)
        assert message.startswith("line 2: a row of units gives ") and refusal in message
    # a first data row without numbers is no units row: its own check names it
    blank = "\n".join([lines[0], "my-ski,mean,,,,", *lines[1:]]) + "\n"
    assert refused(blank).startswith("line 2: column 'load_kg' is empty")


def test_the_example_csv_is_a_realistic_device_file_the_upload_accepts():
    text = example_camber_csv()
    data, _, figures = check(text)
    assert figures["load_cases"] == 45 and figures["unloaded_profile"] == ["mean"]
    assert figures["sample_spacing_mm"] == pytest.approx(5.0)
    assert unloaded_mask(data)[0] and unloaded_mask(data).sum() == 1  # the 0 kg profile first
    assert text.splitlines()[1].startswith("example-ski-a,mean,0,0,")


def test_the_example_csv_is_downloadable_from_the_upload_page(catalogue, tmp_path):
    with make_client(catalogue, tmp_path) as client:
        page = client.get("/upload").text
        assert f'href="{EXAMPLE_CSV_URL}"' in page and MINIMUM_GRID in page
        r = client.get(EXAMPLE_CSV_URL)
        assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
        assert "attachment" in r.headers["content-disposition"]
        assert r.text == example_camber_csv()


# --------------------------------------------------------------- failed items, delete


def _fail(client, job_id: str, error: str) -> str:
    """Fail a job as the runner does (its error, the item failed, its files removed)."""
    state = client.app.state.uploads
    job = state.db.job(job_id)
    state.db.update_job(job_id, state="failed", error=error)
    state.db.update_item(job.item_id, state="failed", file_path=None, sha256=None)
    state.layout.remove_item_files(job.item_id)
    return job.item_id


def test_a_failed_job_frees_its_name_and_is_listed_with_its_reason(catalogue, tmp_path, upload_csv):
    with make_client(catalogue, tmp_path) as client:
        client.app.state.uploads.runner.stop()  # the jobs stay queued: failed by hand
        r = post_ski(client, upload_csv, name="again")
        assert r.status_code == 202, r.text[:300]
        old = _fail(client, r.json()["job"], "accuracy check failed: 50 µm, limit 8 µm")
        listed = client.get("/v1/skis").json()
        assert listed["failed"] == [
            {
                "name": "again",
                "reason": "accuracy check failed: 50 µm, limit 8 µm",
                "job": r.json()["job"],
                "failed_at": listed["failed"][0]["failed_at"],
            }
        ]
        assert client.get("/v1/grinds").json()["failed"] == []
        page = client.get("/upload").text
        assert "accuracy check failed: 50 µm, limit 8 µm" in page
        assert 'data-delete="/v1/skis/again"' in page
        # its page says why and has a delete button
        ski_page = client.get("/skis/again")
        assert ski_page.status_code == 404
        assert "Its job failed: accuracy check failed: 50 µm, limit 8 µm" in ski_page.text
        assert 'id="delete-ski" data-delete="/v1/skis/again"' in ski_page.text
        # a refused re-upload leaves the failed item as it was
        is_problem(post_ski(client, upload_csv[:2000], name="again"), 422)
        assert client.get("/v1/skis/again").json()["id"] == old
        # the same name again: accepted, it replaces the failed item
        r = post_ski(client, upload_csv, name="again")
        assert r.status_code == 202, r.text[:300]
        new = client.get("/v1/skis/again").json()
        assert new["id"] != old and new["state"] == "pending"
        assert client.app.state.uploads.db.item(old) is None
        assert client.get("/v1/skis").json()["failed"] == []
        # a name that is not failed stays taken
        is_problem(post_ski(client, upload_csv, name="again"), 409)


def test_another_teams_failed_item_keeps_its_name(catalogue, tmp_path, upload_csv):
    tokens = {"token-a": "team-a", "token-b": "team-b"}
    a, b = ({"Authorization": f"Bearer {t}"} for t in tokens)
    with make_client(catalogue, tmp_path, team_tokens=tokens) as client:
        client.app.state.uploads.runner.stop()
        r = post_ski(client, upload_csv, name="theirs", headers=a)
        assert r.status_code == 202, r.text[:300]
        _fail(client, r.json()["job"], "beam failed")
        assert client.get("/v1/skis", headers=b).json()["failed"] == []
        assert client.get("/v1/skis", headers=a).json()["failed"][0]["name"] == "theirs"
        is_problem(post_ski(client, upload_csv, name="theirs", headers=b), 409)
        assert post_ski(client, upload_csv, name="theirs", headers=a).status_code == 202


def test_the_upload_and_ski_pages_have_delete_buttons(catalogue, tmp_path):
    with make_client(catalogue, tmp_path) as client:
        state = client.app.state.uploads
        # an uploaded, ready ski (a copy of demo ski A's file, as a finished job leaves it)
        item = state.db.add_item("ski", "mine", metadata={})
        path = state.layout.ski_file(item.id)
        path.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(REPO / "tables" / "skis" / "ski-a.h5", path)
        state.db.update_item(item.id, state="ready", file_path=str(path), sha256=sha256_file(path))
        state.live.sync()
        page = client.get("/skis/mine")
        assert page.status_code == 200
        assert 'id="delete-ski" data-delete="/v1/skis/mine"' in page.text
        assert 'method: "DELETE"' in page.text  # the script that sends it
        # a shipped ski is read-only: no button
        assert "data-delete" not in client.get("/skis/ski-a").text.split("<script>")[0]
        # the upload page: a delete button in each job panel for a failed job, and the script
        upload = client.get("/upload").text
        assert 'id="ski-delete-failed"' in upload and 'id="grind-delete-failed"' in upload
        assert 'method: "DELETE"' in upload
        # the route the buttons call, from the page's origin (the write guard lets it through)
        origin = {"Origin": "http://testserver"}
        assert client.delete("/v1/skis/mine", headers=origin).status_code == 204
        assert client.get("/skis/mine").status_code == 404


def test_the_caps_are_settings_of_the_upload_route(catalogue, tmp_path, upload_csv):
    with make_client(catalogue, tmp_path, max_camber_cases=40) as client:
        body = is_problem(post_ski(client, upload_csv, name="capped"), 422)
        assert body["detail"].startswith("line ") and "more than 40 load cases" in body["detail"]
        assert client.get("/v1/skis/capped").status_code == 404  # nothing kept
    with make_client(catalogue, tmp_path, max_camber_rows=1000) as client:
        body = is_problem(post_ski(client, upload_csv, name="capped"), 422)
        assert body["detail"].startswith("line 1002: more than 1000 data rows")


def _shifted(csv_bytes: bytes, offset_mm: float) -> str:
    """The CSV with every gap ``offset_mm`` larger: a device zeroed off the flat."""
    header, rows = rows_of(csv_bytes)
    shifted = [[*r[:5], f"{float(r[5]) + offset_mm:.4f}"] for r in rows]
    return "\n".join([header, *(",".join(r) for r in shifted)]) + "\n"


def test_a_device_zeroed_below_the_flat_is_refused_with_the_offset(upload_csv):
    """Every load case of a ski pressed on the flat touches it (docs/studies/zero-offset.json:
    310 designs, no case's smallest gap above 0.71 µm at the sparsest accepted sampling)."""
    data, _, _ = check(upload_csv)
    smallest = data.profiles_m.min(axis=1)
    assert np.all(smallest < 1e-6)  # the file as measured touches in every case
    check(_shifted(upload_csv, 0.01))  # within the limit (0.02 mm): accepted
    message = refused(_shifted(upload_csv, 0.05))
    assert message.startswith("file: the base never touches the flat: on side mean")
    got = float(re.search(r"looks set about ([0-9.]+) mm below the flat", message).group(1))
    assert got == pytest.approx(0.05 + np.median(smallest) * 1e3, abs=1.5e-3)
    assert "of 45 cases" in message and "zero it on the flat and measure again" in message


def test_the_zero_offset_limit_is_the_study_s():
    """The limit as scripts/zero_offset_study.py measured it: no false alarm on its 310 designs
    with the device zeroed, every design flagged from a 0.03 mm offset on."""
    import json

    study = json.loads((REPO / "docs" / "studies" / "zero-offset.json").read_text())
    assert study["limit_mm"] == uploads.ZERO_OFFSET_LIMIT_MM
    assert study["designs"] == len(study["rows"]) >= 300
    assert study["flagged_per_offset_mm"]["0"] == 0
    assert study["flagged_per_offset_mm"]["0.03"] == study["designs"]
    assert study["largest_case_minimum_mm"] < 0.1 * uploads.ZERO_OFFSET_LIMIT_MM


def test_a_device_zeroed_above_the_flat_is_not_told_to_change_the_sign(upload_csv):
    """A camber whose touching part reads below −0.05 mm is a zero above the flat; a column with
    every gap ≤ 0 is one of the opposite sign: each refusal says its own change."""
    header, rows = rows_of(upload_csv)
    low = min(float(r[5]) for r in rows)
    message = refused(_shifted(upload_csv, -0.1))
    assert "the device's zero looks set about" in message and "change the sign" not in message
    got = float(re.search(r"reads down to (-[0-9.]+) mm", message).group(1))
    assert got == pytest.approx(low - 0.1, abs=1e-4)
    first = next(i for i, r in enumerate(rows) if float(r[5]) - 0.1 < -0.05)
    assert message.startswith(f"line {first + 2}: gap_mm must be in [-0.05, 50.0]")
    heights = [[*r[:5], f"{-float(r[5]):.4f}"] for r in rows]
    text = "\n".join([header, *(",".join(r) for r in heights)]) + "\n"
    message = refused(text)
    assert "change the sign of the column" in message and "zero" not in message


@pytest.mark.parametrize("name", ["Load (kgf)", "load_kgf", "Load kp", "LOAD [KP]"])
def test_loads_in_kilogram_force_read_as_kg_and_say_so(upload_csv, name):
    """kgf (kp) is the weight of one kg: the numbers are the kg values, none is changed."""
    header, rows = rows_of(upload_csv)
    cells = header.split(",")
    cells[cells.index("load_kg")] = name
    text = "\n".join([",".join(cells), *(",".join(r) for r in rows)]) + "\n"
    data, _, figures = check(text)
    plain, _, plain_figures = check(upload_csv)
    assert figures["load_unit_in_file"] == data.load_unit_in_file
    assert data.load_unit_in_file in ("kgf", "kp") and plain.load_unit_in_file == "kg"
    assert plain_figures["load_unit_in_file"] == "kg"
    np.testing.assert_array_equal(data.loads_n, plain.loads_n)
    units = "\n".join([header, "-,-,kgf,mm,mm,mm", *(",".join(r) for r in rows)]) + "\n"
    np.testing.assert_array_equal(check(units)[0].loads_n, plain.loads_n)


def test_a_file_without_ski_id_and_side_reads_as_the_upload_s_ski_on_side_mean(
    upload_csv, tmp_path
):
    """A device that measures one ski along its middle writes neither column: the ski is the
    upload's name (a path's stem on the command line), the side ``mean``; the answer says so."""
    header, rows = rows_of(upload_csv)
    text = "\n".join(
        ["Load (kg);Load position (mm);Position (mm);Gap (mm)"]
        + [";".join(r[2:]).replace(".", ",") for r in rows]
    )
    data, _, figures = uploads.check_ski_upload(
        text.encode(), "ski.csv", **OUTLINE, default_ski_id="my-ski"
    )
    plain, _, _ = check(upload_csv)
    assert data.ski_id == "my-ski" and data.sides == plain.sides == ["mean"] * len(plain.sides)
    np.testing.assert_array_equal(data.profiles_m, plain.profiles_m)
    np.testing.assert_array_equal(data.loads_n, plain.loads_n)
    assert figures["columns_not_in_file"] == ["ski_id=my-ski", "side=mean"]
    assert check(upload_csv)[2]["columns_not_in_file"] == []
    path = tmp_path / "shop-7.csv"
    path.write_text(text + "\n")
    assert read_camber_csv(path).ski_id == "shop-7"
    # side given, ski_id not: only the one defaulted
    with_side = "\n".join([header.split(",", 1)[1], *(",".join(r[1:]) for r in rows)]) + "\n"
    assert read_camber_csv(with_side).defaulted_columns == ("ski_id=ski",)
    # a required column left out is still refused by name
    message = refused(
        "\n".join([",".join(header.split(",")[:-1])] + [",".join(r[:-1]) for r in rows])
    )
    assert "missing gap_mm" in message and "ski_id and side may be left out" in message


def test_a_mac_spreadsheet_s_csv_with_lone_cr_line_ends_is_accepted(upload_csv):
    """Excel's "CSV (Macintosh)" ends its lines with a lone CR."""
    mac, _, _ = check(upload_csv.replace(b"\n", b"\r"))
    plain, _, _ = check(upload_csv)
    np.testing.assert_array_equal(mac.profiles_m, plain.profiles_m)
    np.testing.assert_array_equal(mac.loads_n, plain.loads_n)


def test_the_spacing_accuracy_is_the_spacing_study_s():
    """uploads.SPACING_ACCURACY (stated at upload) is what the spacing studies measured: the
    same four designs and draws at 1, 2 and 5 mm (docs/studies/own-ski-spacing-*)."""
    import json

    seeds = None
    for mm, ((lo, hi), rigid, flexible) in uploads.SPACING_ACCURACY.items():
        name = f"own-ski-spacing-{mm:g}mm-random-601-604.json"
        study = json.loads((REPO / "docs" / "studies" / name).read_text())
        assert study["settings"]["csv_spacing_mm"] == mm
        dense = [s for s in study["skis"] if s["grid"] == "dense"]
        rms = [s["served"]["profile_rms_um"] for s in dense]
        # rounded outwards to 0.01 µm
        assert (lo, hi) == (np.floor(min(rms) * 100) / 100, np.ceil(max(rms) * 100) / 100)
        models = study["summary"]["dense"]["models"]
        assert rigid == round(models["rigid"]["all"]["share_within_3pct"], 3)
        assert flexible == round(models["flexible"]["all"]["share_within_3pct"], 3)
        drawn = sorted((s["design"], json.dumps(s["seeds"], sort_keys=True)) for s in dense)
        assert seeds is None or drawn == seeds  # the same skis measured at each spacing
        seeds = drawn
    assert uploads.RECOMMENDED_SAMPLE_SPACING_MM in uploads.SPACING_ACCURACY
    assert max(uploads.SPACING_ACCURACY) == uploads.MAX_SAMPLE_SPACING_MM
    # and the 9 × 5 grid's shares (the same study's coarse grid)
    from skisnow.app.service.band_calibration import SPACING_ACCURACY_COARSE_GRID

    for mm, (rigid, flexible) in SPACING_ACCURACY_COARSE_GRID.items():
        name = f"own-ski-spacing-{mm:g}mm-random-601-604.json"
        models = json.loads((REPO / "docs" / "studies" / name).read_text())["summary"]["coarse"]
        assert rigid == round(models["models"]["rigid"]["all"]["share_within_3pct"], 3)
        assert flexible == round(models["models"]["flexible"]["all"]["share_within_3pct"], 3)


def test_a_file_sampled_coarser_than_1_mm_is_told_what_it_costs(upload_csv):
    """The upload answer's notes say what the sampling costs; at 1 mm there is no such note."""
    _, _, figures = check(upload_csv)  # every 5 mm
    assert figures["sample_spacing_mm"] == pytest.approx(5.0)
    note = next(n for n in figures["notes"] if n.startswith("samples every 5 mm"))
    assert "5 mm: profiles 0.29–0.78 µm" in note and "Measure every 1 mm" in note
    assert uploads.sampling_note(1.0) is None and uploads.sampling_note(2.0) is not None
    assert "samples every 1 mm give the most accurate answers" in uploads.minimum_grid_sentence()


def test_a_load_outside_the_measured_span_and_a_case_measured_twice_are_refused(upload_csv):
    """What the job would fail on later (the device model puts each load on a measured node
    between the ends), and a second pass of a case (with its line), are refused at upload."""
    header, rows = rows_of(upload_csv)
    plain, _, _ = check(upload_csv)
    x_mm = plain.positions_m * 1e3
    last = rows[-1][2:4]  # the last case's load_kg, load_position_mm
    first_line = 2 + next(i for i, r in enumerate(rows) if r[2:4] == last)
    for where in (x_mm[-1] + 70, x_mm[-1], x_mm[0] - 5):
        moved = [[*r[:3], f"{where:g}", *r[4:]] if r[2:4] == last else r for r in rows]
        message = refused("\n".join([header, *(",".join(r) for r in moved)]) + "\n")
        assert message.startswith(
            f"file: case side=mean, load_kg={float(last[0]):g}, load_position_mm={where:g} has "
            f"its load outside the measured span {x_mm[0]:g} … {x_mm[-1]:g} mm"
        ), message
    # the tip's last samples unmeasured everywhere: the span the cases keep is what counts
    n = x_mm.size
    gone = {(c, k): "" for c in range(plain.loads_n.size) for k in range(n - 4, n)}
    text, _ = _with_unmeasured(upload_csv, gone)
    moved_rows = [r.split(",") for r in text.splitlines()[1:]]
    where = x_mm[n - 2]
    moved = [[*r[:3], f"{where:g}", *r[4:]] if r[2:4] == last else r for r in moved_rows]
    message = refused("\n".join([header, *(",".join(r) for r in moved)]) + "\n")
    assert f"outside the measured span {x_mm[0]:g} … {x_mm[n - 5]:g} mm" in message
    # a case measured twice: its second pass
    again = [r for r in rows if r[2:4] == last]
    message = refused("\n".join([header, *(",".join(r) for r in [*rows, *again])]) + "\n")
    assert message.startswith(
        f"line {len(rows) + 2}: case side=mean, load_kg={float(last[0]):g}, load_position_mm="
        f"{float(last[1]):g} starts again at position_mm {x_mm[0]:g} (its first pass starts "
        f"at line {first_line}): a case measured twice"
    ), message
