"""scripts/case_loss_study.py: its reduced run, and the upload's served counts held to the
committed study (docs/studies/case-loss-coarse.json)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import case_loss_study as cls  # noqa: E402


def test_a_reduced_run_identifies_with_and_without_a_case_left_out(tmp_path):
    out, md = tmp_path / "c.json", tmp_path / "c.md"
    assert (
        cls.main(
            ["--designs", "random-701", "--lose", "0", "1", "--out", str(out), "--md", str(md)]
        )
        == 0
    )
    doc = json.loads(out.read_text())
    assert doc["schema"] == "skisnow.case-loss/1" and doc["provenance"]["git_commit"]
    rows = doc["rows"]
    assert [r["cases_left_out"] for r in rows] == [0, 1]
    assert [r["loaded_cases"] for r in rows] == [45, 44]
    for r in rows:
        # the study's first ski: served both times, at the noise, its held-out profiles near
        # the truth (docs/studies/case-loss-coarse.md: 0.65 and 0.48 µm)
        assert r["served"], r
        assert 0.95 < r["misfit_over_noise"] < 1.05
        assert r["held_out_profile_error_um"] < 1.5
    assert "| 1 | 1 of 1 |" in md.read_text()


def test_the_upload_note_states_the_committed_study():
    from skisnow.app.jobs.uploads import CASE_LOSS_SERVED

    rows = json.loads((REPO / "docs/studies/case-loss-coarse.json").read_text())["rows"]
    complete = [r for r in rows if r["cases_left_out"] == 0]
    assert all(r["served"] for r in complete) and len(complete) == 24
    rows += json.loads((REPO / "docs/studies/case-loss-example.json").read_text())["rows"]
    # the end-to-end jobs of the realistic files that left cases out of the 9 × 5 grid
    files = json.loads((REPO / "docs/studies/realistic-camber-files.json").read_text())["files"]
    for row in files.values():
        for note in row.get("notes", []):
            if " load cases after leaving out " in note and row.get("state") is not None:
                k = int(note.split(" after leaving out ")[1].split(",")[0])
                rows.append({"cases_left_out": k, "served": row["state"] == "done"})
    for k, (served, skis) in CASE_LOSS_SERVED.items():
        these = [r for r in rows if r["cases_left_out"] == k]
        assert (sum(r["served"] for r in these), len(these)) == (served, skis), k
