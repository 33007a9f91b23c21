"""Realistic camber files through the upload and the whole ski job (issue #26: every realistic
file is accepted and ends done, or is refused at upload with what to change).

Each variant is a file a technician's device or spreadsheet writes: the example file of
``/upload`` (demo ski A, 9 loads × 5 positions every 5 mm, the unloaded profile) reworked as
the variant says, and one ski measured every 10/3 mm with its positions written rounded. Each
is posted to ``POST /v1/skis`` of an app with the service's default training (as
``own_ski_study.py`` builds it); an accepted one's job is waited for. Per variant: the answer
(202 or the refusal's status and message), the upload's notes, the job's end state, the
profile model served and the job's wall time.

    python scripts/realistic_camber_files.py --out docs/studies/realistic-camber-files.json \\
        --md docs/studies/realistic-camber-files.md

About 5 min on 2 cores.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import own_ski_study as st
from skisnow.app.storage import common
from skisnow.app.storage.skis import camber_csv_text
from skisnow.app.web.upload_page import example_camber_csv
from skisnow.solvers.ski_designs import get_design


def _rounded_grid_file(design: str = "random-701") -> str:
    """``design`` measured by the virtual device every 10/3 mm (9 × 5 cases and the unloaded
    profile, 3 µm noise, seed 11), its positions written to 0.01 mm."""
    spacing = st.SPACING_M
    try:
        st.SPACING_M = 1e-3 / 3
        truth = get_design(design).build(st.SPACING_M)
        data = st.camber_data(design, truth, "coarse", 11, True, 10 / 3)
    finally:
        st.SPACING_M = spacing
    lines = camber_csv_text(data).splitlines()
    p = lines[0].split(",").index("position_mm")
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[p] = f"{float(cells[p]):.2f}"
        out.append(",".join(cells))
    return "\n".join(out) + "\n"


def variants() -> dict[str, tuple[str, str, str]]:
    """name → (what it is, file name, text)."""
    lines = example_camber_csv().splitlines()
    hdr, rows = lines[0], [line.split(",") for line in lines[1:]]
    names = hdr.split(",")
    pos, gap, load, at, side = (
        names.index(c) for c in ("position_mm", "gap_mm", "load_kg", "load_position_mm", "side")
    )

    def text(rs, header=hdr) -> str:
        return "\n".join([header, *(",".join(r) for r in rs)]) + "\n"

    cases = list(dict.fromkeys((r[load], r[at]) for r in rows))
    positions = sorted({float(r[pos]) for r in rows})
    mid = positions[len(positions) // 2]
    v: dict[str, tuple[str, str, str]] = {
        "example": ("the example file as downloaded", "ski.csv", text(rows))
    }
    dust = [r[:] for r in rows]
    for r in dust:
        if (r[load], r[at]) in (cases[5], cases[20]) and float(r[pos]) in (mid, mid + 5):
            r[gap] = "NaN"
    v["dust-spots"] = ("readings lost mid-span in 2 cases (NaN)", "ski.csv", text(dust))
    rng = np.random.default_rng(3)
    sides = []
    for s in ("L", "R"):
        for r in rows:
            q = r[:]
            q[side] = s
            q[gap] = f"{float(r[gap]) + rng.normal(0, 0.002):.4f}"
            sides.append(q)
    for r in sides:
        if r[side] == "R" and (r[load], r[at]) == cases[12] and float(r[pos]) == mid:
            r[gap] = ""
    v["left-right-dust"] = (
        "sides L and R, a reading lost mid-span on R (empty)",
        "ski.csv",
        text(sides),
    )
    v["tip-first-skipped-step"] = (
        "listed from the tip, the device skipped the second-last position",
        "ski.csv",
        text([r for r in reversed(rows) if float(r[pos]) != positions[-2]]),
    )
    v["tip-out-of-range"] = (
        "the tip's last 3 samples '---' in every case",
        "ski.csv",
        text(
            [
                [*r[:gap], "---", *r[gap + 1 :]] if float(r[pos]) >= positions[-3] else r
                for r in rows
            ]
        ),
    )
    v["no-unloaded"] = (
        "without the unloaded profile",
        "ski.csv",
        text([r for r in rows if r[load] != "0"]),
    )
    v["rounded-10-3-mm"] = (
        "random-701 every 10/3 mm, positions written to 0.01 mm",
        "ski.csv",
        _rounded_grid_file(),
    )
    v["device-txt"] = (
        "columns apart by spaces, decimal commas, Load(kg)",
        "ski.txt",
        "  ".join(["ski_id", "side", "Load(kg)", "load_position(mm)", "position(mm)", "gap(mm)"])
        + "\n"
        + "\n".join("  ".join(c.replace(".", ",") for c in r) for r in rows)
        + "\n",
    )
    v["extra-columns"] = (
        "a temperature and a time stamp column",
        "ski.csv",
        text([[*r, "21.5", "2026-12-07T10:00"] for r in rows], hdr + ",temp_c,time"),
    )
    last = cases[-1]
    v["load-beyond-tip"] = (
        "a case's load position typed 1100 mm (beyond the last sample)",
        "ski.csv",
        text([[*r[:at], "1100", *r[at + 1 :]] if (r[load], r[at]) == last else r for r in rows]),
    )
    again = [r for r in rows if (r[load], r[at]) == last]
    v["case-twice"] = ("the last case measured twice", "ski.csv", text([*rows, *again]))
    off = {positions[57]: f"{positions[57] + 0.12:.2f}"}
    v["off-grid-position"] = (
        "one position 0.12 mm off the grid (written to 0.01 mm)",
        "ski.csv",
        text(
            [
                [*r[:pos], off.get(float(r[pos]), f"{float(r[pos]):.2f}"), *r[pos + 1 :]]
                for r in rows
            ]
        ),
    )
    wide = ["position_mm," + ",".join(f"{c[0]} kg @ {c[1]} mm" for c in cases[1:4])]
    v["one-column-per-case"] = (
        "a sheet with one column of gaps per load case",
        "ski.csv",
        "\n".join([*wide, "-970,1.2,1.1,1.0"]) + "\n",
    )
    v["workbook"] = ("the sheet sent as .xlsx", "ski.xlsx", text(rows))
    # passes started late (the first 1-3 rows not written) in 6 cases, one stopped early
    short = {cases[k]: (k % 3 + 1, 0) for k in range(2, 14, 2)} | {cases[30]: (0, 2)}
    ragged = []
    for key in cases:
        mine = [r for r in rows if (r[load], r[at]) == key]
        head, tail = short.get(key, (0, 0))
        ragged += mine[head : len(mine) - tail]
    v["late-starts"] = (
        "passes started late (1-3 rows not written) in 6 cases, one stopped early",
        "ski.csv",
        text(ragged),
    )
    v["device-notes"] = (
        "the device's notes before the header, without '#' (Device: …, Ski: …, Date: …)",
        "ski.csv",
        "Device: SkiFlex 3000\nSki: example\nDate: 2026-12-08\n\n" + text(rows),
    )
    v["other-header-names"] = (
        "the columns named Weight (kg), LoadPos(mm), Pos (mm), Height (mm)",
        "ski.csv",
        text(rows, "ski_id,side,Weight (kg),LoadPos(mm),Pos (mm),Height (mm)"),
    )
    v["shifted-case"] = (
        "one case's positions 2 mm off the others'",
        "ski.csv",
        text(
            [
                [*r[:pos], f"{float(r[pos]) + 2:g}", *r[pos + 1 :]]
                if (r[load], r[at]) == cases[7]
                else r
                for r in rows
            ]
        ),
    )
    twice = rows.index(next(r for r in rows if (r[load], r[at]) == cases[9])) + 40
    v["sample-twice"] = (
        "one sample written twice",
        "ski.csv",
        text([*rows[: twice + 1], rows[twice], *rows[twice + 1 :]]),
    )
    return v


def run(names: list[str] | None = None) -> dict:
    cat = st.shipped_catalogue()
    work = Path(tempfile.mkdtemp(prefix="realistic-"))
    res: dict = {}
    with st.make_client(cat, work, {}) as client:
        for name, (what, fname, content) in variants().items():
            if names and name not in names:
                continue
            t0 = time.perf_counter()
            r = client.post(
                "/v1/skis",
                files={"file": (fname, content.encode(), "text/csv")},
                data={"name": name, "length_mm": "2000", "width_mm": "44", "style": "classic"},
            )
            row = {"what": what, "status": r.status_code}
            if r.status_code != 202:
                row["detail"] = r.json().get("detail")
            else:
                job = r.json()["job"]
                row["notes"] = r.json()["data"]["notes"]
                while True:
                    j = client.get(f"/v1/jobs/{job}").json()
                    if j["state"] in ("done", "failed"):
                        break
                    time.sleep(0.5)
                item = client.get(f"/v1/skis/{name}").json()
                row |= {
                    "state": j["state"],
                    "error": j.get("error"),
                    "profile_model": (item.get("profile_model") or {}).get("name"),
                    "job_s": round(time.perf_counter() - t0, 1),
                }
            res[name] = row
            print(name, row.get("state") or row["status"], flush=True)
    return res


def write_md(res: dict, path: Path, prov: dict) -> None:
    lines = [
        "# Realistic camber files, upload to job end (issue #26)",
        "",
        f"_{prov['created_utc']}, commit {prov['git_commit'][:12]}: `{prov['command_line']}`_",
        "",
        "| file | what | answer | job | served | job time [s] |",
        "|---|---|---|---|---|---|",
    ]
    for name, r in res.items():
        answer = "202" if r["status"] == 202 else f"{r['status']}: {r['detail']}"
        lines.append(
            f"| {name} | {r['what']} | {answer} | {r.get('state', '–')} | "
            f"{r.get('profile_model') or '–'} | {r.get('job_s', '–')} |"
        )
    lines += ["", "Notes of the accepted files:", ""]
    for name, r in res.items():
        for note in r.get("notes", []):
            lines.append(f"- {name}: {note}")
    failed = {n: r["error"] for n, r in res.items() if r.get("state") == "failed"}
    if failed:
        lines += ["", "Failed jobs:", ""] + [f"- {n}: {e}" for n, e in failed.items()]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="+", help="these variants only")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--md", type=Path)
    args = ap.parse_args(argv)
    res = run(args.only)
    params = {"only": args.only}
    common.write_study_json(args.out, "skisnow.realistic-camber-files/1", params, {"files": res})
    if args.md:
        write_md(res, args.md, common.provenance(params))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
