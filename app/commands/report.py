"""``skisnow report REPORT``: generated reports in ``docs/`` (:mod:`app.evidence`); today one,
``paper-case``."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from skisnow.app.evidence import writer
from skisnow.app.evidence.paper_case import (
    DOC_POROSITY,
    FIG_DIR,
    MD_NAME,
    PAPER_LOAD_KG,
    PAPER_POSITION_MM,
    PAPER_SNOW_MODULUS_MPA,
)
from skisnow.app.evidence.paper_case_write import write_paper_case
from skisnow.app.service import load_catalogue


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``report`` command with its ``paper-case`` subcommand."""
    p = subparsers.add_parser(
        "report",
        help="generated reports in docs/",
        description="Write reports that reproduce published studies with this project's code.",
    )
    sub = p.add_subparsers(dest="report", required=True, metavar="REPORT")
    pc = sub.add_parser(
        "paper-case",
        help="the published 2 skis × 2 grinds study (writes docs/paper-case.md)",
        description="Reproduce the 2 skis × 2 grinds study "
        f"({PAPER_LOAD_KG:g} kg at {PAPER_POSITION_MM:g} mm, "
        f"E_snow {PAPER_SNOW_MODULUS_MPA:g} MPa, "
        f"porosity {DOC_POROSITY:g}) and write OUT_DIR/{MD_NAME} with figures in "
        f"OUT_DIR/{FIG_DIR}/.",
    )
    pc.add_argument(
        "--out-dir", type=Path, default=writer.DOCS, help="output folder (default docs)"
    )
    pc.add_argument(
        "--tables-dir",
        type=Path,
        default=None,
        help="texture tables and skis (default: the service setting, tables/)",
    )
    pc.add_argument("--no-progress", action="store_true", help="no progress bar")
    pc.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    tables_dir = args.tables_dir
    if tables_dir is None:
        from skisnow.app.settings import Settings

        tables_dir = Settings().tables_dir
    t0 = time.perf_counter()
    cat = load_catalogue(tables_dir)
    md = write_paper_case(cat, args.out_dir, progress=not args.no_progress)
    print(f"wrote {md} and {md.parent / FIG_DIR}/ in {time.perf_counter() - t0:.1f} s")
    return 0
