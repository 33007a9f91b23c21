"""``skisnow identify-ski``: the report, the held-out split, the JSON file, bad input, the
held-out errors stored with an identification (``--store``) or added to it later."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
from skisnow.app.cli import main
from skisnow.app.storage.skis import mean_profiles, read_camber_csv
from skisnow.solvers.beam import BeamSki, solve_beam_contact

REPO = Path(__file__).resolve().parents[2]


class _Bar:
    """Records what identify-ski shows on its progress bar (a stand-in for tqdm)."""

    shown: ClassVar[list[tuple[int, str]]] = []

    def __init__(self, **kwargs):
        self.n = 0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def set_postfix_str(self, text, refresh=True):
        _Bar.shown.append((self.n, text))


def test_identify_ski_from_csv(tmp_path, camber_csv, capsys, monkeypatch):
    import skisnow.app.commands.identify as identify_command

    monkeypatch.setattr(identify_command, "tqdm", _Bar)
    _Bar.shown = []
    csv_path = tmp_path / "ski.csv"
    csv_path.write_bytes(camber_csv)
    out = tmp_path / "report.json"
    code = main(["identify-ski", "--csv", str(csv_path), "--json", "--out", str(out)])
    rep = json.loads(capsys.readouterr().out)
    # the identification's progress reached the bar: the start, then the forward fits (one
    # after the other step by step, or side by side in worker processes: app/path_pool.py)
    percents = [n for n, _ in _Bar.shown]
    assert _Bar.shown[0][1].startswith("start:") and len(_Bar.shown) >= 3
    assert percents == sorted(percents) and 0 <= percents[0] and percents[-1] <= 100
    assert any("forward fit" in text for _, text in _Bar.shown)
    assert code == (0 if rep["identified"] else 1)
    assert rep["cases"] == 25 and rep["held_out_cases"] == 5
    assert 2.5 < rep["noise_um"] < 3.5  # the fixture's device noise is 3 µm
    assert rep["misfit_um"] > 0 and rep["held_out_vs_measured_rms_um"] > 0
    assert len(rep["stiffness"]) == 21
    for s in rep["stiffness"]:
        lo, hi = s["band_90_nm2"]
        assert lo <= s["ei_nm2"] <= hi
    saved = json.loads(out.read_text())
    assert saved["report"]["cases"] == 25 and "git_commit" in saved["provenance"]


def test_identify_ski_bad_holdout(tmp_path, camber_csv, capsys):
    csv_path = tmp_path / "ski.csv"
    csv_path.write_bytes(camber_csv)
    assert main(["identify-ski", "--csv", str(csv_path), "--holdout", "0.95"]) == 2
    assert "--holdout" in capsys.readouterr().err


def _small_ski_file(tmp_path, camber_csv) -> Path:
    """A ski file with the fixture's 25 camber cases (no identification yet)."""
    from skisnow.app.storage.skis import SkiRecord, read_camber_csv, read_ski, write_ski

    csv_path = tmp_path / "ski.csv"
    csv_path.write_bytes(camber_csv)
    demo = read_ski(REPO / "tables" / "skis" / "ski-a.h5")
    path = tmp_path / "skis" / "small.h5"
    write_ski(path, SkiRecord(read_camber_csv(csv_path), demo.outline, {"description": "test"}))
    return path


def _recomputed_held_out_errors(record) -> tuple[np.ndarray, np.ndarray]:
    """Held-out cases and their RMS error [m], predicted from the stored identified beam."""
    ident = record.identified
    f, xf, y, _ = mean_profiles(record.measurements)
    held = np.sort(np.asarray(ident["held_out_index"], dtype=int))
    beam = BeamSki(ident["positions_m"], ident["bending_stiffness_nm2"], ident["unloaded_gap_m"])
    # read at the measured nodes (a file sampled every 5 mm gets its beam on 1 mm nodes)
    x = record.measurements.positions_m
    gaps = np.stack(
        [np.interp(x, beam.positions_m, solve_beam_contact(beam, f[k], xf[k]).gap_m) for k in held]
    )
    return held, np.sqrt(np.mean((gaps - y[held]) ** 2, axis=1))


@pytest.mark.slow  # one identification of 25 cases: 35-70 s on 2 loaded cores
def test_store_keeps_the_held_out_errors(tmp_path, camber_csv, capsys):
    """``--store`` writes each held-out case's error with the identification (what the ski's
    page shows), equal to a recomputation from the stored beam."""
    from skisnow.app.service.profiles import HELD_OUT_ERRORS, HELD_OUT_STORED
    from skisnow.app.storage.skis import read_ski

    path = _small_ski_file(tmp_path, camber_csv)
    main(["identify-ski", "--ski", str(path), "--store", "--json"])
    capsys.readouterr()
    record = read_ski(path)
    held, expected = _recomputed_held_out_errors(record)
    group = record.identified[HELD_OUT_ERRORS]
    assert held.size == 5 and np.array_equal(group["case_index"], held)
    np.testing.assert_allclose(group["rms_error_m"], expected, rtol=1e-12, atol=0)
    assert group["attrs"]["source"] == HELD_OUT_STORED and group["attrs"]["units"] == "m"
    assert json.loads(group["attrs"]["parameters_json"])["store"] == "True"


def test_add_held_out_errors_to_an_older_file(tmp_path, capsys):
    """``--add-held-out-errors`` adds to an identification stored without them (here: a demo
    ski's, stripped) the errors the shipped file stores, changing nothing else, and says so in
    their provenance."""
    from skisnow.app.service.profiles import HELD_OUT_ADDED, HELD_OUT_ERRORS
    from skisnow.app.storage.skis import read_ski, replace_ski_group

    path = tmp_path / "ski-a.h5"
    shutil.copyfile(REPO / "tables" / "skis" / "ski-a.h5", path)
    stored = read_ski(path).identified
    older = {k: v for k, v in stored.items() if k != HELD_OUT_ERRORS}
    replace_ski_group(path, "identified", older)
    assert HELD_OUT_ERRORS not in read_ski(path).identified
    assert main(["identify-ski", "--ski", str(path), "--add-held-out-errors", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["held_out_cases"] == 85
    added = read_ski(path).identified
    np.testing.assert_allclose(
        added[HELD_OUT_ERRORS]["rms_error_m"],
        stored[HELD_OUT_ERRORS]["rms_error_m"],
        rtol=1e-9,  # stored by another machine, whose LAPACK rounds the beam solve differently
        atol=0,
    )
    assert np.array_equal(added[HELD_OUT_ERRORS]["case_index"], stored["held_out_index"])
    attrs = added[HELD_OUT_ERRORS]["attrs"]
    assert attrs["source"] == HELD_OUT_ADDED and attrs["units"] == "m"
    assert json.loads(attrs["parameters_json"])["add_held_out_errors"] == "True"
    assert rep["held_out_rms_um"] == pytest.approx(stored["attrs"]["held_out_rms_m"] * 1e6, 1e-12)

    # the identification itself is unchanged (its groups, such as the alternative beams, too)
    def same(a, b, key):
        if isinstance(b, dict):
            assert isinstance(a, dict) and a.keys() == b.keys(), key
            for k in b:
                if k == "attrs":
                    assert a[k] == b[k], (key, k)
                else:
                    same(a[k], b[k], (key, k))
        else:
            assert np.array_equal(a, b, equal_nan=True), key

    for key, value in older.items():
        if key != "attrs":
            same(added[key], value, key)
    assert added["attrs"] == older["attrs"]


def test_add_held_out_errors_needs_a_stored_identification(tmp_path, camber_csv, capsys):
    path = _small_ski_file(tmp_path, camber_csv)
    assert main(["identify-ski", "--ski", str(path), "--add-held-out-errors"]) == 2
    assert "no stored identification" in capsys.readouterr().err
    csv_path = tmp_path / "ski.csv"
    assert main(["identify-ski", "--csv", str(csv_path), "--add-held-out-errors"]) == 2
    assert "--add-held-out-errors needs --ski" in capsys.readouterr().err


def test_the_command_line_says_which_positions_unmeasured_samples_dropped(capsys):
    """A CSV given to ``skisnow identify --csv`` with unmeasured gaps is read as the upload
    reads it (their positions dropped from every case), and the command says so on stderr."""
    from skisnow.app.commands.identify import _say_reading_notes

    rows = [
        f"s,mean,{kg},-160,{x},{'NaN' if (kg, x) == (60, 20) else f'{0.1 + x / 1000:.4f}'}"
        for kg in (40, 60)
        for x in range(-20, 21)
    ]
    data = read_camber_csv(
        "ski_id,side,load_kg,load_position_mm,position_mm,gap_mm\n" + "\n".join(rows)
    )
    assert data.dropped_positions_mm == (20.0,)
    _say_reading_notes(data)
    err = capsys.readouterr().err
    assert err.startswith("note: 1 unmeasured samples (no gap)") and "(20 mm)" in err


def test_the_command_line_says_how_the_file_s_header_was_read(capsys):
    """A device's notes before the header and columns named another way are read by
    ``skisnow identify-ski --csv`` as by the upload, and said on stderr."""
    from skisnow.app.commands.identify import _say_reading_notes

    rows = [f"s,mean,{kg},-160,{x},{0.1 + x / 1000:.4f}" for kg in (40, 60) for x in range(-20, 21)]
    data = read_camber_csv(
        "Device: SkiFlex 3000\nski_id,side,Weight (kg),LoadPos(mm),Pos (mm),Height (mm)\n"
        + "\n".join(rows)
    )
    assert data.profiles_m.shape == (2, 41)
    _say_reading_notes(data)
    err = capsys.readouterr().err.splitlines()
    assert (
        err[0]
        == "note: 1 line before the header read past (not camber data): 'Device: SkiFlex 3000'"
    )
    assert err[1].startswith("note: columns read by another name: 'weight (kg)' as load_kg, ")
