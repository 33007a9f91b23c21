"""Identify an own-ski study's skis again with this checkout's identification and store the new
alternative beams in their ski files (issue #26: the variant starts,
:data:`solvers.identify.VARIANT_KNOT_SPACINGS_M`; docs/limits.md, "The rigid answers' unwarned
misses").

Each ski file of ``--work`` (``scripts/own_ski_study.py``'s per-ski cache, ``skis/*.h5``) is
identified again as its job identified it (:func:`app.path_pool.identify_with_pool` of
:func:`solvers.identify.identify_beam_checked`, the stored held-out cases). The chosen beam must
come out the same as the stored one (the identification is deterministic; a variant fit is only
chosen where the main fits stay above the noise, :func:`solvers.identify.variant_choice`): then
only the ``identified/alternatives`` group is replaced, the file written atomically with the
commit in its attributes, and the file as it was kept once under ``skis-before-reidentify/``. A
ski whose chosen beam differs is left as it was and reported (with the variant fit chosen, if
that is why: ``variant_chosen``, the main misfit it replaced and the held-out RMS).
``own_ski_study.py --rescore`` then asks the held-out cases again with the new alternatives.

Usage::

    python scripts/reidentify_study.py --work /path/to/work --out reidentify.json

About 40–60 s per ski on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import h5py
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app.path_pool import identify_with_pool  # noqa: E402
from skisnow.app.service.profiles import served_beam  # noqa: E402
from skisnow.app.storage import common  # noqa: E402
from skisnow.app.storage.skis import alternatives_to_dict, mean_profiles, read_ski  # noqa: E402
from skisnow.solvers.identify import identify_beam_checked  # noqa: E402

SCHEMA = "skisnow.reidentify-study/1"
BACKUP = "skis-before-reidentify"


def same_beam(a, b) -> bool:
    """Bitwise the same EI(X) and c(X) on the same nodes."""
    return bool(
        a.positions_m.shape == b.positions_m.shape
        and np.array_equal(a.bending_stiffness_nm2, b.bending_stiffness_nm2)
        and np.array_equal(a.unloaded_gap_m, b.unloaded_gap_m)
    )


def identify_as_its_job(record, **kwargs):
    """Identify a stored ski's beam again as its job did
    (:func:`app.path_pool.identify_with_pool` of :func:`solvers.identify.identify_beam_checked`
    on its mean profiles, the held-out cases stored with it); ``kwargs`` go to the
    identification. Returns (identification, held-out check)."""
    f, xf, y, _ = mean_profiles(record.measurements)
    held = np.asarray(record.identified["held_out_index"], dtype=int)
    return identify_with_pool(
        identify_beam_checked,
        record.measurements.positions_m,
        f,
        xf,
        y,
        held_out_index=held,
        **kwargs,
    )


def write_alternatives(path: Path, beams, commit: str) -> None:
    """Replace ``identified/alternatives`` of the ski file ``path`` (atomically: a copy is edited
    and renamed onto it); none left when ``beams`` is empty."""
    with common.atomic_path(path) as tmp:
        shutil.copyfile(path, tmp)
        with h5py.File(tmp, "r+") as f:
            grp = f["identified"]
            if "alternatives" in grp:
                del grp["alternatives"]
            if beams:
                d = alternatives_to_dict(beams)
                g = grp.create_group("alternatives")
                for k, v in d["attrs"].items():
                    g.attrs[k] = v
                for k in ("bending_stiffness_nm2", "unloaded_gap_m"):
                    g.create_dataset(k, data=d[k])
            grp.attrs["alternatives_reidentified_git_commit"] = commit


def reidentify(path: Path, backup_dir: Path, commit: str, **kwargs) -> dict:
    """One ski file: identified again, its alternatives replaced when the chosen beam is the
    stored one; a JSON-ready row. ``kwargs`` go to the identification (e.g.
    ``variant_knot_spacings_m``, to measure other variant starts)."""
    record = read_ski(path)
    stored = served_beam(record.identified)
    row = {"ski_file": str(path), "name": path.stem}
    if stored is None:
        return {**row, "outcome": "no served beam stored: left as it was"}
    stored_alts = (record.identified.get("alternatives") or {}).get("unloaded_gap_m")
    before = 0 if stored_alts is None else np.atleast_2d(stored_alts).shape[0]
    t0 = time.perf_counter()
    ident, check = identify_as_its_job(record, **kwargs)
    e = ident.extra
    row.update(
        time_s=round(time.perf_counter() - t0, 1),
        noise_m=float(ident.noise_m),
        held_out_rms_m=check.get("held_out_rms_m"),
        stored_held_out_rms_m=float(record.identified["attrs"].get("held_out_rms_m", np.nan)),
        variant_chosen=e.get("variant_chosen"),
        main_misfit_m=float(e.get("main_misfit_m", np.nan)),
        wall_starts_s=round(float(e.get("wall_starts_s", np.nan)), 1),
        wall_forward_s=round(float(e.get("wall_forward_s", np.nan)), 1),
        misfit_m=float(ident.misfit_m),
        alternatives_before=int(before),
        alternatives_after=len(ident.alternative_beams),
        main_alternatives=len(e.get("alternatives", [])),
        variant_alternatives=len(e.get("variant_alternatives", [])),
        variant_starts=[
            {k: v.get(k) for k in ("start", "device_misfit_m", "time_s", "used", "note")}
            for v in e.get("variant_starts", [])
        ],
        variant_candidates=[
            {
                k: c[k]
                for k in (
                    "start",
                    "coarse_spacing_m",
                    "misfit_m",
                    "converged",
                    "time_s",
                    "max_dc_middle_m",
                    "max_dlog_ei_middle",
                )
            }
            for c in e.get("variant_candidates", [])
        ],
    )
    if not (ident.ok and same_beam(ident.beam, stored)):
        return {**row, "outcome": "the chosen beam differs from the stored one: left as it was"}
    backup = backup_dir / path.name
    if not backup.exists():
        backup_dir.mkdir(parents=True, exist_ok=True)
        shutil.copy2(path, backup)
    write_alternatives(path, ident.alternative_beams, commit)
    return {**row, "outcome": "alternatives replaced"}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, required=True, help="own_ski_study.py --work folder")
    ap.add_argument("--out", type=Path, required=True, help="JSON report")
    ap.add_argument("--only", nargs="*", help="ski file stems (default: every ski)")
    ap.add_argument(
        "--variant-knot-spacings-m",
        type=float,
        nargs="+",
        help="variant starts' stiffness knot spacings [m] (default: the identification's, "
        "solvers.identify.VARIANT_KNOT_SPACINGS_M); to measure other variants",
    )
    ap.add_argument(
        "--variant-refit-knot-spacings-m",
        type=float,
        nargs="+",
        help="stiffness knot spacings [m] of forward fits warm-started from each variant "
        "start (solvers.identify.VARIANT_REFIT_KNOT_SPACINGS_M, default none); to measure them",
    )
    args = ap.parse_args(argv)
    kwargs = {}
    if args.variant_knot_spacings_m:
        kwargs["variant_knot_spacings_m"] = tuple(args.variant_knot_spacings_m)
    if args.variant_refit_knot_spacings_m:
        kwargs["variant_refit_knot_spacings_m"] = tuple(args.variant_refit_knot_spacings_m)
    commit = common.git_commit()
    files = sorted((args.work / "skis").glob("*.h5"))
    if args.only:
        files = [p for p in files if p.stem in set(args.only)]
    rows = []
    for i, path in enumerate(files, 1):
        row = reidentify(path, args.work / BACKUP, commit, **kwargs)
        rows.append(row)
        print(
            f"[{i}/{len(files)}] {row['name']}: {row['outcome']} "
            f"({row.get('time_s', 0):.0f} s, alternatives {row.get('alternatives_before')} → "
            f"{row.get('alternatives_after')})",
            flush=True,
        )
        doc = {
            "schema": SCHEMA,
            "provenance": common.provenance({"work": str(args.work), **kwargs}),
            "skis": rows,
        }
        with common.atomic_path(args.out) as tmp:
            tmp.write_text(json.dumps(doc, indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
