"""The ski job end to end of ``skisnow bench macro`` (app/evidence/ski_job.py): a real upload
through the app, timed, with the job's own stage times; and its section of docs/benchmarks.md."""

from __future__ import annotations

from skisnow.app.api.factory import create_api
from skisnow.app.evidence import ski_job

#: a network small enough for a test; its accuracy check fails on the coarse grid (limit 8 µm),
#: so the job serves the identified beam (the path the default network takes on 9 × 5 grids)
SMALL = {"train_epochs": 5, "train_lbfgs_epochs": 0, "train_ensemble": 1}


def test_the_job_bench_uploads_a_study_ski_and_splits_its_time():
    d = ski_job.bench_ski_job(create_api, (("race-classic", "coarse"),), overrides=SMALL)
    assert d["training"] == {**SMALL, "ski_max_test_rmse_um": 8.0}
    row = d["skis"]["race-classic-coarse-d0"]
    assert row["state"] == "done", row
    assert row["cases"] == 1 + 9 * 5
    assert row["profile_model"] == "identified_beam"
    assert "above the accuracy limit: not served" in row["message"]
    stages = row["stage_s"]
    assert list(stages) == ["training", "identification", "model_choice", "ski_file", "figures"]
    # the stages are the job's own split of the user's time (upload to done, 0.2 s polls)
    assert 0 < sum(stages.values()) <= row["time_s"] + 0.1
    lines = ski_job.render_md(d)
    assert lines[0] == "### Ski job end to end (issue #26)"
    assert any(line.startswith("| race-classic-coarse-d0 | 46 | done |") for line in lines)
    assert row["network_test_rmse_um"] > 8.0  # 5 epochs: far above the limit
    assert any(" (not served) | identified_beam |" in line for line in lines)
    assert "5 Adam + 0 L-BFGS epochs × 1 members" in "\n".join(lines)


def test_the_section_renders_a_failed_job_and_an_empty_run():
    assert ski_job.render_md({}) == []
    d = {
        "training": {"train_epochs": 4000, "train_lbfgs_epochs": 1500, "train_ensemble": 3},
        "skis": {
            "a-dense-d0": {
                "cases": 118,
                "state": "done",
                "time_s": 54.2,
                "stage_s": {
                    "training": 27.08,
                    "identification": 23.16,
                    "model_choice": 0.05,
                    "ski_file": 0.07,
                    "figures": 0.38,
                },
                "profile_model": "identified_beam",
                "network_test_rmse_um": 4.24,
                "load_avg_1min": [0.9, 1.7],
            },
            "b-coarse-d0": {"cases": 46, "state": "failed", "time_s": 15.1, "stage_s": {}},
        },
    }
    lines = ski_job.render_md(d)
    row = "| a-dense-d0 | 118 | done | 54 | 27 / 23 / 0.05 / 0.07 / 0.38 | 4.2 | identified_beam |"
    assert f"{row} 0.9 → 1.7 |" in lines
    assert "| b-coarse-d0 | 46 | failed | 15 | — / — / — / — / — | — | — | — |" in lines
    assert "network held-out RMSE [µm] (limit 8)" in "\n".join(lines)
