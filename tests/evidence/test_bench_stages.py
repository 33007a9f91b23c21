"""Smoke tests of `skisnow bench micro` and `bench macro` on small cases: structure, agreement."""

from __future__ import annotations

from pathlib import Path

import pytest
from skisnow.app.evidence import macro, micro, writer


def test_bench_micro_structure_and_agreement():
    pytest.importorskip("ContactMechanics")
    data = micro.bench_micro([32], 1, ["contactmechanics"], 32, 2, ["contactmechanics"])
    assert data["peers"] == ["contactmechanics"]
    ours = [r for r in data["runs"] if r["solver"] == "skisnow[scipy]"]
    peer = [r for r in data["runs"] if r["solver"] == "contactmechanics"]
    assert len(ours) == len(peer) == len(micro.PRESSURES_PA)
    for r in ours:
        assert r["converged"] and r["median_time_s"] > 0 and r["fft_pairs_finest"] > 0
    for r in peer:
        assert abs(r["contact_fraction_rel_diff_vs_skisnow"]) < 0.02
        assert abs(r["mean_gap_rel_diff_vs_skisnow"]) < 0.005
    table = data["table"]
    assert table["points"] == 2 and set(table["peers"]) == {"contactmechanics"}
    assert table["peers"]["contactmechanics"]["max_contact_fraction_rel_diff"] < 0.02
    lines = micro.render_md(data)
    # single cold peer runs at their own stopping criteria are not like-for-like (issue #13):
    # the page shows our rows only and points to the work-precision section for peers
    assert any(line.startswith("| 32 | 60 | skisnow[scipy] |") for line in lines)
    assert not any(line.startswith("| 32 |") and "contactmechanics" in line for line in lines)


def test_bench_macro_stage_renders():
    data = macro.bench_macro_stage(repeats=1, inference_calls=3, identification=False)
    assert set(data["skis"]) == {"ski-a", "ski-b"}
    assert "identification" not in data
    for r in data["skis"].values():
        assert r["default"]["converged"] and r["fine"]["converged"]
        assert abs(r["area_error"]) < 0.05
    lines = macro.render_md(data)
    assert sum("(default)" in line for line in lines) == 2
    assert all(0 < r["median_s"] < 1 for r in data["inference"].values())


@pytest.mark.parametrize("part", ["identification", "ski_job"])
def test_macro_rerun_only_keeps_the_other_parts(tmp_path, monkeypatch, part):
    """``bench macro --only-identification`` / ``--only-job``: the part is run again (here a
    stand-in: the real ones take minutes), every other part is the previous run's, and the page
    names each kept part with the run that measured it; without a previous run it says what to
    run."""
    import json

    from skisnow.solvers.errors import DataFileError

    prev = tmp_path / "macro.json"
    first = {"created_utc": "2026-11-26T15:29:16+00:00", "git_commit": "bd0184f0c140b2"}
    second = {"created_utc": "2026-11-29T07:22:10+00:00", "git_commit": "bf77bc48bf57aa"}
    # the older form of the note: one provenance for the parts kept by the identification rerun
    old = {
        "stage": "macro",
        "provenance": second,
        "skis": {"ski-a": {"x": 1}},
        "inference": {"ski-a": {"median_s": 1e-4}},
        "flexible": {"ski-a": {"y": 2}},
        "identification": {"skis": {"old": {}}},
        "kept_from_previous_run": {
            "parts": ["skis", "inference", "flexible"],
            "provenance": first,
        },
    }
    prev.write_text(json.dumps(old))
    fresh = {"skis": {"new": {}}}
    data = macro.rerun_only(prev, part, lambda: fresh)
    assert data[part] == fresh
    kept = [k for k in macro.PARTS if k in old and k != part]
    assert {k: data[k] for k in kept} == {k: old[k] for k in kept}
    parts = data["kept_from_previous_run"]["parts"]
    assert list(parts) == kept
    assert parts["skis"] == first  # kept twice: still the run that measured it
    if part == "ski_job":
        assert parts["identification"] == second
    monkeypatch.setattr(macro.identification_bench, "render_md", lambda d: ["IDENT"])
    monkeypatch.setattr(macro.ski_job_bench, "render_md", lambda d: ["JOB"])
    monkeypatch.setattr(macro, "_case_words", lambda: "case")
    monkeypatch.setattr(macro, "_profile_words", lambda d: "profile")
    text = "\n".join(_kept_lines(macro.render_md, data))
    assert (
        "skis, inference, flexible from the run of 2026-11-26T15:29:16+00:00 (commit bd0184f0c140)"
        in text
    )
    flag = macro.RERUNNABLE[part]
    assert f"run again here: {part.replace('_', ' ')} (`skisnow bench macro {flag}`)" in text
    # run again on its own output: the kept parts still date from the run that measured them
    prev.write_text(json.dumps({**data, "provenance": {"created_utc": "2026-12-07T08:57:02"}}))
    again = macro.rerun_only(prev, part, lambda: fresh)
    assert again["kept_from_previous_run"]["parts"]["skis"] == first
    with pytest.raises(DataFileError, match="bench macro"):
        macro.rerun_only(tmp_path / "missing.json", part, lambda: fresh)


def _kept_lines(render, data):
    """The rendered lines from the kept-parts note on (the tables above it need full rows)."""
    trimmed = {**data, "skis": {}, "inference": {}, "flexible": {}}
    return render(trimmed)


def test_benchmarks_md_renders_stages_and_skips_other_json(tmp_path):
    """docs/bench may hold files that are not stages; the page is still written (no KeyError)."""
    import json

    bench_dir = tmp_path / "bench"
    bench_dir.mkdir()
    stage = {
        "stage": "custom",
        "machine": {"cpus": 2},
        "provenance": {"created_utc": "2026-01-01", "git_commit": "abc", "command_line": "x"},
    }
    (bench_dir / "custom.json").write_text(json.dumps(stage))
    (bench_dir / "notes.json").write_text(json.dumps({"results": []}))
    out = writer.write_benchmarks_md(tmp_path)
    text = out.read_text()
    assert "## custom" in text and "on 2 cores" in text
    assert "notes" not in text


def _speed_run(checkout: str, default: bool, rps: float, p99: float, p50: float = 18.0) -> dict:
    return {
        "checkout": checkout,
        "workers": 2,
        "default_settings": default,
        "single_p50_ms": p50,
        "clients": 8,
        "throughput_rps": rps,
        "p50_ms": 90.0,
        "p99_ms": p99,
        "rss_mb_before": 1400.0,
        "rss_mb_after": 1700.0,
        "server_errors_5xx": 0,
        "load_average": [1.0, 1.5],
    }


def test_speed_stage_judges_the_default_settings_run_of_this_commit():
    from skisnow.app.evidence import speed_md

    runs = [
        _speed_run("baseline", True, 24.0, 555.0),  # the baseline's misses are not judged
        _speed_run("this", False, 51.0, 174.0),  # nor a run with explicit workers
        _speed_run("this", True, 73.1, 153.0),
    ]
    text = "\n".join(speed_md.render_md({"baseline": "abc1234", "pairs": [], "loadtest": runs}))
    assert "| `abc1234` | 2 (default) | 18.0 | 24.0 |" in text
    assert "8 clients 73.1 req/s against ≥ 60 (met) at p99 153 ms against ≤ 400 ms (met)" in text
    assert "The gain is" not in text  # no canned reading: the run's own note, when it has one
    noted = {"baseline": "abc1234", "pairs": [], "loadtest": runs, "note": "Slower: the band."}
    assert "\nSlower: the band.\n" in "\n".join(speed_md.render_md(noted))
    slow = [_speed_run("this", True, 59.9, 401.0, p50=30.5)]
    text = "\n".join(speed_md.render_md({"baseline": "abc1234", "pairs": [], "loadtest": slow}))
    assert text.count("**not met**") == 3


def test_speed_note_is_set_on_the_stored_run(tmp_path):
    """``speed_compare.py --set-note`` adds the reading to the stored run without measuring
    again: the measurement and its provenance stay, docs/benchmarks.md shows the note."""
    import importlib.util
    import json

    spec = importlib.util.spec_from_file_location(
        "speed_compare", Path(__file__).resolve().parents[2] / "scripts" / "speed_compare.py"
    )
    sc = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(sc)
    (tmp_path / "bench").mkdir()
    run = {
        "stage": "speed",
        "machine": {"cpus": 2},
        "provenance": {"git_commit": "abc1234"},
        "baseline": "def5678",
        "pairs": [],
        "loadtest": [_speed_run("this", True, 73.1, 153.0)],
    }
    (tmp_path / "bench" / "speed.json").write_text(json.dumps(run), encoding="utf-8")
    assert sc._set_note("Read me.", tmp_path) == 0
    stored = json.loads((tmp_path / "bench" / "speed.json").read_text(encoding="utf-8"))
    assert stored == {**run, "note": "Read me."}
    assert "\nRead me.\n" in (tmp_path / "benchmarks.md").read_text(encoding="utf-8")
