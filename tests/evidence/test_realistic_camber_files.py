"""scripts/realistic_camber_files.py: its refusals run here (no job), and the committed study
(docs/studies/realistic-camber-files.json) holds issue #26's rule: every file accepted ends
done, or is refused at upload with what to change."""

from __future__ import annotations

import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import realistic_camber_files as rcf  # noqa: E402

REFUSED = {
    "load-beyond-tip": (422, "has its load outside the measured span"),
    "case-twice": (422, "a case measured twice"),
    "off-grid-position": (422, "lies 0.12 mm off the uniform grid"),
    "one-column-per-case": (422, "look like one column of gaps per load case"),
    "workbook": (415, "save the sheet as CSV"),
    "shifted-case": (422, "all cases must share one sampling grid"),
    "sample-twice": (422, "is written twice (the line before lists it too)"),
}


def test_the_files_the_upload_refuses_say_what_to_change(tmp_path):
    out, md = tmp_path / "r.json", tmp_path / "r.md"
    assert rcf.main(["--only", *REFUSED, "--out", str(out), "--md", str(md)]) == 0
    files = json.loads(out.read_text())["files"]
    assert set(files) == set(REFUSED)
    for name, (status, words) in REFUSED.items():
        assert files[name]["status"] == status, files[name]
        assert words in files[name]["detail"], files[name]
    assert "| workbook | the sheet sent as .xlsx | 415:" in md.read_text()


def test_the_committed_study_accepts_and_ends_done_or_refuses():
    files = json.loads((REPO / "docs/studies/realistic-camber-files.json").read_text())["files"]
    assert set(files) == set(rcf.variants())
    for name, row in files.items():
        if name in REFUSED:
            assert row["status"] == REFUSED[name][0], (name, row)
            continue
        assert row["status"] == 202, (name, row)
        if name == "dust-spots":
            # the minimum grid less 2 cases, a choice that misses its held-out check (the
            # upload's note says so: docs/uploads.md, "Cases left out of the smallest grid")
            assert row["state"] == "failed" and "held-out cases miss" in row["error"], row
            assert any("after leaving out 2" in n for n in row["notes"]), row["notes"]
            continue
        assert row["state"] == "done" and row["profile_model"] == "identified_beam", (name, row)
