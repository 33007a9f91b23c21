"""Ship the measured ski base of the ISO 5436-2 (x3p) reference implementation as the grind
``ski-base`` (issue #30): its texture in ``tables/textures/ski-base.h5`` and its table in
``tables/ski-base.h5`` (``tables/manifest.json`` rewritten).

Source: ``SkiInfiniteFocus.x3p`` of the openGPS sample files (Alicona InfiniteFocus, focus
variation, 1197 × 940 points at 3.68 µm, 2009), LGPL-3.0; see tables/LICENSES.md. Get it with::

    git clone https://github.com/aschet/x3p   # or the openGPS distribution
    python scripts/make_ski_base_grind.py \
        x3p/src/ISO5436_2_XML_Demo/samplefiles/SkiInfiniteFocus.x3p

The map goes through the upload's rules: the plane fitted to the measured points, the largest
well-measured rectangle (``solvers.measured.prepare_measured_map``), the default reduction to the
service's solve limit (block average, ``solvers.measured.reduce_map``: k = 3, 11.0 µm pixels),
then mirrored for the periodic solver, as an upload with the default options is. Builds on two
local Dask workers; a few CPU minutes (``--points`` sets the table's pressure points).
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
NAME = "ski-base"
#: the table's ``texture_provenance`` (GET /v1/grinds ``provenance``, the form's grind line)
PROVENANCE = (
    "measured: ski base, Alicona InfiniteFocus (focus variation), openGPS ISO 5436-2 sample "
    "file SkiInfiniteFocus.x3p, LGPL-3.0 (tables/LICENSES.md)"
)
SOURCE_URL = (
    "https://github.com/aschet/x3p/blob/master/src/ISO5436_2_XML_Demo/samplefiles/"
    "SkiInfiniteFocus.x3p"
)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("x3p", type=Path, help="SkiInfiniteFocus.x3p")
    p.add_argument("--out", type=Path, default=REPO / "tables", help="tables directory")
    p.add_argument("--points", type=int, default=48, help="pressure points of the table")
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)

    import h5py
    from skisnow.app.jobs.grind_job import _record_measured_iso
    from skisnow.app.jobs.table_build import build_tables
    from skisnow.app.jobs.table_settings import BuildSettings
    from skisnow.app.settings import Settings
    from skisnow.app.storage.tables import write_manifest
    from skisnow.app.storage.textures import write_texture
    from skisnow.app.storage.topography import read_measured_topography
    from skisnow.solvers.measured import reduce_map
    from skisnow.solvers.texture import make_periodic

    digest = hashlib.sha256(args.x3p.read_bytes()).hexdigest()
    measured = read_measured_topography(args.x3p)
    prep = measured.prepared
    tex = measured.texture
    reduced = reduce_map(
        tex.heights_m,
        tex.pixel_size_m,
        "block",
        max_solve_points=Settings().max_solve_grid_points,
        periodic="mirror",
    )
    provenance = (
        f"measured: Alicona InfiniteFocus (focus variation) map of a ski base, openGPS ISO "
        f"5436-2 sample file SkiInfiniteFocus.x3p ({SOURCE_URL}; LGPL-3.0; sha256 {digest}); "
        f"plane removed over the measured points; kept rows {prep.crop[0]}-{prep.crop[1]}, "
        f"columns {prep.crop[2]}-{prep.crop[3]} ({prep.unmeasured_points} unmeasured points "
        f"of the file, all at its edges, cut; {prep.filled_points} filled); reduced: "
        f"{'; '.join(reduced.notes)}"
    )
    texture = replace(
        tex,
        heights_m=reduced.heights_m,
        pixel_size_m=reduced.pixel_size_m,
        name=NAME,
        source=provenance,
    )
    iso = {f"iso_measured_{k}": v for k, v in prep.iso_measured.items()}
    textures_dir = args.out / "textures"
    textures_dir.mkdir(parents=True, exist_ok=True)
    write_texture(
        texture,
        textures_dir / f"{NAME}.h5",
        extra_attrs={"measured": True, "licence": "LGPL-3.0-or-later", **iso},
    )
    solve = replace(
        texture,
        heights_m=make_periodic(texture.heights_m, "mirror"),
        source=provenance + "; periodic=mirror",
    )
    print(
        f"{NAME}: {tex.shape} -> {texture.shape} at {texture.pixel_size_m * 1e6:.4g} µm, "
        f"solved on {solve.shape}; Sq of the measured points {prep.sq_measured_m * 1e6:.4g} µm",
        flush=True,
    )
    build_tables(
        [solve],
        args.out,
        BuildSettings(points=args.points),
        workers=args.workers,
        progress=False,
    )
    # the table's ISO 25178 parameters: those of the measured points, as for an upload
    _record_measured_iso(args.out / f"{NAME}.h5", prep.iso_measured)
    with h5py.File(args.out / f"{NAME}.h5", "r+") as f:
        f.attrs["texture_provenance"] = PROVENANCE
    write_manifest(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
