"""app/evidence: the one writer, no import circle, and prose that follows the numbers.

Renders from the stored ``docs/bench/*.json`` and from small synthetic records; no benchmark is
run (tests/test_bench_*.py and tests/evidence/test_report.py run the stages on small cases).
"""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import pytest
from skisnow.app.evidence import (
    accuracy_md,
    accuracy_md_micro,
    macro,
    paper_case,
    paper_case_md,
    writer,
)
from skisnow.app.storage.common import docs_dir

EVIDENCE = Path(writer.__file__).parent
BENCH_JSON = Path(__file__).resolve().parents[2] / "docs" / "bench"


def _imports(path: Path) -> set[str]:
    """Modules of app.evidence that ``path`` imports (any depth of the file)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module:
            if node.module == "skisnow.app.evidence":
                out |= {a.name for a in node.names}
            elif node.module.startswith("skisnow.app.evidence."):
                out.add(node.module.rsplit(".", 1)[1])
        elif isinstance(node, ast.Import):
            out |= {
                a.name.rsplit(".", 1)[1]
                for a in node.names
                if a.name.startswith("skisnow.app.evidence.")
            }
    return out


def test_no_import_circle_and_no_stage_imports_the_writer():
    graph = {p.stem: _imports(p) for p in EVIDENCE.glob("*.py") if p.stem != "__init__"}
    # the writer imports the stages' renderers; only the report's file step imports it
    assert [m for m, deps in graph.items() if "writer" in deps] == ["paper_case_write"]
    assert not any("commands" in deps for deps in graph.values())

    def reach(start: str, seen: set[str]) -> set[str]:
        for dep in graph.get(start, ()):
            if dep not in seen:
                seen.add(dep)
                reach(dep, seen)
        return seen

    cycles = [m for m in graph if m in reach(m, set())]
    assert cycles == []


def test_writer_writes_docs_where_the_storage_rule_says():
    """Never into site-packages: the writer's folder is storage.common.docs_dir()."""
    assert writer.DOCS == docs_dir()


def test_write_stage_writes_json_chart_and_page(tmp_path):
    seen = []
    path = writer.write_stage("custom", {"x": 1}, lambda d, p: seen.append(p), docs_dir=tmp_path)
    data = json.loads(path.read_text())
    assert path == tmp_path / "bench" / "custom.json"
    assert data["stage"] == "custom" and data["x"] == 1 and "provenance" in data
    assert seen == [tmp_path / "bench" / "custom.png"]
    assert "## custom" in (tmp_path / "benchmarks.md").read_text()


@pytest.mark.parametrize("stage", sorted(writer.STAGE_RENDERERS))
def test_every_stored_stage_renders(stage):
    path = BENCH_JSON / f"{stage}.json"
    if not path.is_file():
        pytest.skip(f"no stored {path.name}")
    lines = writer.STAGE_RENDERERS[stage](json.loads(path.read_text()))
    assert lines[0].startswith("## ")


def test_pixel_counting_sentence_states_the_counts_of_the_stored_run():
    d = json.loads((BENCH_JSON / "accuracy.json").read_text())
    text = "\n".join(accuracy_md_micro.table_section(d))
    for g in d["table"]["grinds"]:
        n_px = g["grid_shape"][0] * g["grid_shape"][1]
        at = [
            r["held_out_max_at"]["real_contact_area_fraction"]["real_contact_area_fraction"]
            for r in g["rows"]
            if "held_out_max_at" in r
        ]
        few = [a for a in at if a * n_px < accuracy_md_micro.FEW_PIXELS]
        line = next(x for x in text.splitlines() if x.startswith(f"{g['grind']}: the largest"))
        if few:
            assert f"touches on {max(few) * n_px:.0f} pixels or fewer" in line
        else:
            assert "pixel counting" not in line


def test_the_words_follow_the_numbers():
    assert accuracy_md._trend_words([0.17, 0.11, 0.05, 0.0, -0.05]) == "keeps falling"
    assert accuracy_md._trend_words([0.1, 0.2]) == "keeps rising"
    assert accuracy_md._trend_words([0.1, -0.2, 0.1]) == "keeps moving"
    assert accuracy_md._times_words(590) == "hundreds of times"
    assert accuracy_md._times_words(3.3) == "a few times"
    assert accuracy_md._percent_words(0.115) == "several per cent"
    assert accuracy_md._percent_words(0.004) == "less than a per cent"
    assert accuracy_md_micro._power_of_ten(10_000) == "10⁴"
    assert accuracy_md_micro._order_words(1.0, 2048) == "first order"
    assert accuracy_md_micro._order_words(None, 2048) == "the 2048² value"


def test_macro_section_names_the_profile_model_the_run_used():
    flex = {"ski-a": {"profile_model": "network"}, "ski-b": {"profile_model": "network"}}
    assert macro._profile_words({"flexible": flex}) == "network profile"
    flex["ski-b"]["profile_model"] = "identified_beam"
    assert macro._profile_words({"flexible": flex}) == "profile from its profile model"


def _case_with_zones(zones: list[dict], sweep: list[dict]) -> paper_case.PaperCase:
    case = paper_case.PaperCase(porosity=0.5, sweep=sweep)
    case.results = {
        (s, g): {"apparent": {"zones": zones}} for s in paper_case.SKIS for g in paper_case.GRINDS
    }
    return case


def test_paper_case_soft_snow_clause_needs_a_second_piece():
    def row(e: float, pieces: int) -> dict:
        return {
            "snow_modulus_mpa": e,
            "error": None,
            "rear": {"pieces": pieces},
            "front": {"pieces": 1},
        }

    assert paper_case_md._ends_touch_at_soft_snow(_case_with_zones([], [row(20.0, 2)]))
    assert not paper_case_md._ends_touch_at_soft_snow(_case_with_zones([], [row(400.0, 2)]))
    assert not paper_case_md._ends_touch_at_soft_snow(_case_with_zones([], [row(20.0, 1)]))


def test_paper_case_words_come_from_the_constants():
    assert paper_case_md._paper_case_words() == (
        f"{paper_case.PAPER_LOAD_KG:g} kg at "
        + re.sub("-", "−", f"{paper_case.PAPER_POSITION_MM:g}")
        + " mm"
    )


def test_shipped_stage_reads_the_tables_own_estimates_in_the_range():
    """The ``shipped`` accuracy stage reports the largest stored a_r estimate over the range,
    and says whether the 3 % target is met (from the numbers, not canned)."""
    import numpy as np
    from skisnow.app.evidence.accuracy_common import AccuracyConfig
    from skisnow.app.evidence.accuracy_shipped import (
        SHIPPED_RANGE_A_R,
        bench_shipped,
        shipped_section,
    )
    from skisnow.app.storage.common import tables_dir
    from skisnow.app.storage.tables import read_table
    from skisnow.solvers.lookup import ESTIMATE_RANGE_A_R, LIGHT_LOAD_RANGE_A_R

    st = bench_shipped(AccuracyConfig(table_grinds=("grind-2",)))
    row = st["tables"][0]
    table = read_table(tables_dir() / "grind-2.h5")
    a = table.real_contact_area_fraction
    assert SHIPPED_RANGE_A_R == (LIGHT_LOAD_RANGE_A_R[0], ESTIMATE_RANGE_A_R[1])
    keep = (a >= SHIPPED_RANGE_A_R[0]) & (a <= SHIPPED_RANGE_A_R[1])
    expected = np.max(table.real_contact_area_fraction_error[keep] / a[keep])
    assert row["max_rel_estimate"]["real_contact_area_fraction"]["rel"] == expected
    assert row["nodes_in_range"] == int(keep.sum())
    assert row["light_load_node_ratios"] == table.pressure_ratio[table.light_load_nodes].tolist()
    text = "\n".join(shipped_section({"shipped": st}))
    assert ("met by every table" in text) == (expected <= 0.03)
    worse = {**st, "target_a_r_rel": expected / 2}
    assert "**not met**" in "\n".join(shipped_section({"shipped": worse}))


def test_gpu_stage_states_the_target_from_its_numbers():
    from skisnow.app.evidence import gpu_md

    def bench(speedup):
        phases = {"before_fine_cg_s": 0.4, "fine_cg_s": 0.07, "after_fine_cg_s": 0.5}
        cpu = {**phases, "fine_cg_s": 1.6}
        row = {
            "pixels": 4096**2,
            "torch": {"median_s": 1.0, "median_phases_s": phases, "repeats": [{}, {}]},
            "cpu": {"median_s": speedup, "median_phases_s": cpu},
            "speedup_cpu_over_torch": speedup,
            "agreement": {"contact_pixels_differing": 0, "delta_iterations_torch_minus_cpu": 0},
        }
        env = {"date_utc": "2026-11-27", "git_commit": "abc", "os_cpu_count": 16}
        return gpu_md.stage_from_bench({"results": [row], "environment": env}, "cmd")

    slow = "\n".join(gpu_md.render_md(bench(3.7)))
    assert "**3.7×, not met**" in slow and "| 4096² | 3.7 | 1 (2 runs) | 3.7× |" in slow
    assert "23× faster on the GPU" in slow
    assert "**25.0×, met**" in "\n".join(gpu_md.render_md(bench(25.0)))
    stage = bench(3.7)
    assert stage["stage"] == "gpu-micro" and stage["provenance"]["git_commit"] == "abc"
