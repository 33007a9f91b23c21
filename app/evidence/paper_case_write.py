"""``skisnow report paper-case`` writes: ``paper-case.md``, its figures and the JSON of the
numbers behind them, each atomically through :mod:`app.evidence.writer`."""

from __future__ import annotations

import json
import logging
import math
import time
from pathlib import Path

import numpy as np
from matplotlib import rc_context
from skisnow.app.evidence.paper_case import (
    _SVG_SALT,
    FIG_DIR,
    GRINDS,
    JSON_NAME,
    MD_NAME,
    PUBLISHED_APPARENT,
    PUBLISHED_ISO,
    PUBLISHED_REAR_SHARE,
    SKIS,
    PaperCase,
    compute_paper_case,
)
from skisnow.app.evidence.paper_case_figures import _figures
from skisnow.app.evidence.paper_case_findings import measure_findings
from skisnow.app.evidence.paper_case_md import render_markdown
from skisnow.app.evidence.writer import write_text as _write_text
from skisnow.app.service import Catalogue

log = logging.getLogger(__name__)


def _json_ready(case: PaperCase) -> dict:
    return {
        "schema": "skisnow.paper-case/1",
        "porosity": case.porosity,
        "results": [
            {k: v for k, v in case.results[(s, g)].items() if k not in ("timing_ms",)}
            for s in SKIS
            for g in GRINDS
        ],
        "load_checks": [
            {"ski": s, "grind": g, "by_load_kg": {f"{kg:g}": m for kg, m in by.items()}}
            for (s, g), by in case.load_checks.items()
        ],
        "flexible": [
            {
                "ski": s,
                "grind": g,
                **{k: v for k, v in r.items() if k not in ("timing_ms", "distributions")},
            }
            for (s, g), r in case.flexible.items()
        ],
        "zone_pressure_sweep": case.sweep,
        "real_area_curves_percent": case.curves,
        "findings": measure_findings(case),
        "published": {
            "apparent": PUBLISHED_APPARENT,
            "rear_share": PUBLISHED_REAR_SHARE,
            "iso": PUBLISHED_ISO,
        },
        "iso_ours": case.iso,
        "tables": case.tables,
        "skis": case.skis,
        "provenance": case.provenance,
        "elapsed_s": case.elapsed_s,
    }


def write_paper_case(
    cat: Catalogue, out_dir: str | Path, *, progress: bool = True, **kwargs
) -> Path:
    """Compute the paper case and write ``out_dir/paper-case.md``, its figures and JSON.

    Every file is written atomically. ``kwargs`` go to :func:`compute_paper_case`.

    Returns
    -------
    Path
        The markdown file.
    """
    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    case = compute_paper_case(cat, progress=progress, **kwargs)
    fig_dir = out_dir / FIG_DIR
    with rc_context({"svg.hashsalt": _SVG_SALT}):
        figs = _figures(case)
    case.elapsed_s = time.perf_counter() - t0  # computation and figures
    for name, _caption, svg in figs:
        _write_text(fig_dir / name, svg)
    _write_text(
        fig_dir / JSON_NAME,
        json.dumps(_finite_json(_json_ready(case)), indent=1, allow_nan=False) + "\n",
    )
    md = out_dir / MD_NAME
    text = render_markdown(case, [(n, c) for n, c, _ in figs], FIG_DIR)
    _write_text(md, text)
    return md


def _finite_json(obj):
    """``obj`` with NumPy scalars as Python numbers and NaN/inf as ``None`` (strict JSON)."""
    if isinstance(obj, dict):
        return {str(k): _finite_json(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite_json(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
