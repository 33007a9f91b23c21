"""``skisnow identify-ski``: the report, the held-out split, the JSON file, bad input."""

from __future__ import annotations

import json

from app.cli import main


def test_identify_ski_from_csv(tmp_path, camber_csv, capsys):
    csv_path = tmp_path / "ski.csv"
    csv_path.write_bytes(camber_csv)
    out = tmp_path / "report.json"
    code = main(["identify-ski", "--csv", str(csv_path), "--json", "--out", str(out)])
    rep = json.loads(capsys.readouterr().out)
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
