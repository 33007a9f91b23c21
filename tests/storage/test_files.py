"""Broken data files at start-up, and an interrupted table build (issue 6 §3).

- A truncated, corrupted (bytes flipped) or missing table or ski file, and a stale or missing
  manifest, each stop the service at start-up with :class:`solvers.errors.DataFileError` whose
  message names the file: from :func:`app.service.load_catalogue`, from the app's lifespan
  (``create_app``) and from ``skisnow serve`` (exit status 2, one line, before binding a port).
- The same damage behind a manifest that was updated to match (so the manifest check passes)
  is still caught by the readers: ``read_table`` by its ``data_sha256``, ``read_ski`` by its
  structure; a flipped byte either raises ``DataFileError`` naming the file or leaves the
  numbers that define the table unchanged (it hit padding or provenance text).
- A ``build-tables`` job killed after a random chunk resumes from its checkpoints to the same
  table: every dataset and every attribute that defines the table are byte-identical to an
  uninterrupted build, and so is ``data_sha256``. The HDF5 files themselves differ, by design,
  only in what records the run: ``created_utc``, ``build_time_s``, ``chunks_resumed`` and the
  wall times in ``/diagnostics/solve_time_s`` (compared here attribute by attribute).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from fastapi.testclient import TestClient
from skisnow.app import cli, service
from skisnow.app.jobs.table_build import build_tables
from skisnow.app.jobs.table_settings import BuildSettings
from skisnow.app.main import create_app
from skisnow.app.settings import Settings
from skisnow.app.storage.common import sha256_file
from skisnow.app.storage.skis import read_ski, write_ski_manifest
from skisnow.app.storage.tables import read_table, table_data_sha256, write_manifest, write_table
from skisnow.solvers.errors import DataFileError
from skisnow.solvers.texture import Texture, self_affine_surface

REPO = Path(__file__).resolve().parents[2]
SKI = REPO / "tables" / "skis" / "ski-a.h5"


# ------------------------------------------------------------------------ a small tables dir


@pytest.fixture(scope="module")
def good_dir(tmp_path_factory, small_table) -> Path:
    """A complete tables directory: one small table, one demo ski, both manifests."""
    d = tmp_path_factory.mktemp("tables-good")
    write_table(d / "tiny-grind.h5", small_table, heights_m=None)
    write_manifest(d)
    (d / "skis").mkdir()
    shutil.copy(SKI, d / "skis" / "ski-a.h5")
    write_ski_manifest(d / "skis")
    return d


@pytest.fixture
def tables(good_dir, tmp_path) -> Path:
    """A fresh copy of the good directory for one test to damage."""
    d = tmp_path / "tables"
    shutil.copytree(good_dir, d)
    return d


def _table(d: Path) -> Path:
    return d / "tiny-grind.h5"


def _ski(d: Path) -> Path:
    return d / "skis" / "ski-a.h5"


def _truncate(path: Path, keep: float = 0.5) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


def _flip(path: Path, offsets) -> None:
    data = bytearray(path.read_bytes())
    for off in offsets:
        data[off] ^= 0xFF
    path.write_bytes(bytes(data))


def _refresh_manifests(d: Path) -> None:
    """Make both manifests match the files on disk as they are now (sha256 and size)."""
    for manifest, listed in ((d / "manifest.json", d), (d / "skis" / "manifest.json", d / "skis")):
        data = json.loads(manifest.read_text())
        for name, entry in data["files"].items():
            entry["sha256"] = sha256_file(listed / name)
            entry["size_bytes"] = (listed / name).stat().st_size
        manifest.write_text(json.dumps(data))


def _data_offset(path: Path, dataset: str) -> tuple[int, int]:
    """(file offset, size in bytes) of a contiguous dataset's raw data."""
    with h5py.File(path, "r") as f:
        ds = f[dataset]
        offset = ds.id.get_offset()
        assert offset is not None, dataset
        return int(offset), int(ds.id.get_storage_size())


def _load_error(d: Path) -> str:
    with pytest.raises(DataFileError) as info:
        service.load_catalogue(d)
    return str(info.value)


def test_good_directory_loads(good_dir):
    cat = service.load_catalogue(good_dir)
    assert sorted(cat.grinds) == ["tiny-grind"] and sorted(cat.skis) == ["ski-a"]


# ------------------------------------------------------------- each damage, at start-up


def _damage_truncated_table(d):
    _truncate(_table(d))
    return "tiny-grind.h5"


def _damage_truncated_ski(d):
    _truncate(_ski(d), 0.3)
    return "ski-a.h5"


def _damage_flipped_table(d):
    off, size = _data_offset(_table(d), "loaded/real_contact_area_fraction")
    _flip(_table(d), [off + size // 2])
    return "tiny-grind.h5"


def _damage_flipped_ski(d):
    off, size = _data_offset(_ski(d), "network/layer0_weight")
    _flip(_ski(d), [off + size // 3])
    return "ski-a.h5"


def _damage_missing_table(d):
    _table(d).unlink()
    return "tiny-grind.h5"


def _damage_missing_ski(d):
    _ski(d).unlink()
    return "ski-a.h5"


def _damage_missing_manifest(d):
    (d / "manifest.json").unlink()
    return "manifest.json"


def _damage_missing_ski_manifest(d):
    (d / "skis" / "manifest.json").unlink()
    return "manifest.json"


def _damage_corrupt_manifest(d):
    _truncate(d / "manifest.json")
    return "manifest.json"


def _damage_stale_manifest(d):
    """The table was rebuilt (other numbers, valid file) but the manifest was not rewritten."""
    table = read_table(_table(d))
    table.unloaded_mean_gap_m *= 1.01
    write_table(_table(d), table)
    return "tiny-grind.h5"


def _damage_stale_ski_manifest(d):
    shutil.copy(REPO / "tables" / "skis" / "ski-b.h5", _ski(d))  # another valid ski file
    return "ski-a.h5"


DAMAGES = {
    "truncated-table": _damage_truncated_table,
    "truncated-ski": _damage_truncated_ski,
    "flipped-table": _damage_flipped_table,
    "flipped-ski": _damage_flipped_ski,
    "missing-table": _damage_missing_table,
    "missing-ski": _damage_missing_ski,
    "missing-manifest": _damage_missing_manifest,
    "missing-ski-manifest": _damage_missing_ski_manifest,
    "corrupt-manifest": _damage_corrupt_manifest,
    "stale-manifest": _damage_stale_manifest,
    "stale-ski-manifest": _damage_stale_ski_manifest,
}


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_damaged_file_stops_load_catalogue_naming_it(tables, damage):
    name = DAMAGES[damage](tables)
    message = _load_error(tables)
    assert name in message, message
    if damage.startswith("stale"):
        assert "manifest" in message


@pytest.mark.parametrize("damage", ["truncated-table", "flipped-ski", "stale-manifest"])
def test_damaged_file_stops_the_app_at_start_up(tables, damage):
    name = DAMAGES[damage](tables)
    app = create_app(Settings(tables_dir=tables, warm_up=False, data_dir=tables.parent / "data"))
    with pytest.raises(DataFileError, match=name.replace(".", r"\.")), TestClient(app):
        pass


@pytest.mark.parametrize("damage", ["missing-ski", "truncated-table"])
def test_damaged_file_stops_serve_before_binding(tables, damage, capsys, monkeypatch):
    name = DAMAGES[damage](tables)

    def no_server(*args, **kwargs):  # pragma: no cover - reached only if the check is missing
        raise AssertionError("uvicorn started despite a damaged file")

    monkeypatch.setattr("uvicorn.run", no_server)
    status = cli.main(["serve", "--tables-dir", str(tables), "--port", "1"])
    err = capsys.readouterr().err
    assert status == 2
    # one line saying what is checked (issue #28: the start said nothing), then the error
    last = err.rstrip("\n").splitlines()[-1]
    assert last.startswith("skisnow serve: error:") and name in last, err
    assert "Traceback" not in err and err.count("\n") <= 2, err


# ------------------------------------------- damage behind a manifest updated to match it


@pytest.mark.parametrize("keep", [0.0, 0.1, 0.5, 0.9, 0.999])
def test_truncated_files_behind_a_matching_manifest(tables, keep):
    _truncate(_table(tables), keep)
    _refresh_manifests(tables)
    assert "tiny-grind.h5" in _load_error(tables)
    _truncate(_ski(tables), keep)
    with pytest.raises(DataFileError, match=r"ski-a\.h5"):
        read_ski(_ski(tables))


def test_flipped_table_data_behind_a_matching_manifest(tables):
    for dataset in (
        "loaded/real_contact_area_fraction",
        "loaded/mean_reciprocal_gap_per_m",
        "separated/separated_mean_reciprocal_gap_per_m",
    ):
        path = _table(tables)
        original = path.read_bytes()
        off, size = _data_offset(path, dataset)
        _flip(path, [off + size - 3])
        _refresh_manifests(tables)
        message = _load_error(tables)
        assert "tiny-grind.h5" in message and "data_sha256" in message, message
        path.write_bytes(original)


def test_random_byte_flips_in_a_table_are_caught_or_harmless(tables, good_dir):
    """Flip one byte at 40 seeded random offsets: read_table raises DataFileError naming the
    file, or the numbers that define the table are unchanged (the byte was padding or text)."""
    reference = table_data_sha256(read_table(_table(good_dir)))
    original = _table(good_dir).read_bytes()
    rng = np.random.default_rng(20240601)
    outcomes = {"caught": 0, "harmless": 0}
    for off in rng.integers(0, len(original), 40):
        path = _table(tables)
        path.write_bytes(original)
        _flip(path, [int(off)])
        try:
            table = read_table(path)
        except DataFileError as exc:
            assert "tiny-grind.h5" in str(exc)
            outcomes["caught"] += 1
        else:
            assert table_data_sha256(table) == reference, off
            outcomes["harmless"] += 1
    assert outcomes["caught"] > 0, outcomes


def test_random_byte_flips_in_a_ski_file_raise_data_file_error_or_load(tables):
    """Ski files carry no checksum of their own (the manifest guards them); a damaged
    structure must still be a DataFileError naming the file, never another exception."""
    original = _ski(tables).read_bytes()
    with h5py.File(_ski(tables), "r") as f:
        heads = sorted({int(f[n].id.get_offset() or 0) for n in ("outline/width_m",)})
    rng = np.random.default_rng(7)
    offsets = [*rng.integers(0, 4096, 25), *rng.integers(0, len(original), 15), *heads]
    for off in offsets:
        _ski(tables).write_bytes(original)
        _flip(_ski(tables), [int(off)])
        try:
            read_ski(_ski(tables))
        except DataFileError as exc:
            assert "ski-a.h5" in str(exc)


# --------------------------------------------------------------- interrupted table build

PIXEL = 1e-6  # [m]
#: 10 points in 5 chunks of 2: small enough to build three times in a few seconds
BUILD = BuildSettings(points=10, ratio_min=1e-6, ratio_max=1e-1, chunk_size=2)
#: attributes that record the run, not the table (they differ between two builds by design)
RUN_ATTRS = {"created_utc", "build_time_s", "chunks_resumed"}
RUN_DATASETS = {"diagnostics/solve_time_s"}


def _build_texture() -> Texture:
    rng = np.random.default_rng(3)
    h = self_affine_surface((32, 32), PIXEL, hurst=0.8, rms_height_m=1e-6, rng=rng)
    return Texture(h, PIXEL, "tex-r", source="synthetic seed 3")


@pytest.fixture(scope="module")
def dask_client():
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    )
    with Client(cluster) as c:
        yield c
    cluster.close()


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory, dask_client) -> Path:
    out = tmp_path_factory.mktemp("build-reference")
    return build_tables([_build_texture()], out, BUILD, client=dask_client, progress=False)["tex-r"]


def _h5_content(path: Path) -> tuple[dict, dict]:
    """(attributes, datasets) of a whole file: {object path: {name: value}}, {path: bytes}."""
    attrs, data = {}, {}
    with h5py.File(path, "r") as f:

        def visit(name, obj):
            attrs[name] = {k: np.asarray(v).tobytes() for k, v in obj.attrs.items()}
            if isinstance(obj, h5py.Dataset):
                arr = obj[()]
                data[name] = (arr.dtype.str, arr.shape, np.asarray(arr).tobytes())

        attrs["/"] = {k: np.asarray(v).tobytes() for k, v in f.attrs.items()}
        f.visititems(visit)
    return attrs, data


@pytest.mark.parametrize("seed", [0, 1])
def test_build_interrupted_at_a_random_chunk_resumes_to_the_same_table(
    tmp_path, dask_client, uninterrupted, seed
):
    n_chunks = 5
    stop_after = int(np.random.default_rng(seed).integers(1, n_chunks))  # 1 … 4 chunks done
    done = []

    def kill(name, index):
        done.append(index)
        if len(done) == stop_after:
            raise KeyboardInterrupt(f"simulated kill after chunk {index}")

    with pytest.raises(KeyboardInterrupt):
        build_tables(
            [_build_texture()], tmp_path, BUILD, client=dask_client, progress=False,
            on_chunk_done=kill,
        )  # fmt: skip
    assert not (tmp_path / "tex-r.h5").exists()  # never a partial table
    assert len(list(tmp_path.rglob("chunk-*.h5"))) == stop_after
    again = []
    path = build_tables(
        [_build_texture()],
        tmp_path,
        BUILD,
        client=dask_client,
        progress=False,
        on_chunk_done=lambda name, index: again.append(index),
    )["tex-r"]
    assert sorted(done + again) == list(range(n_chunks))  # nothing computed twice

    a, b = read_table(path), read_table(uninterrupted)
    assert a.attrs["data_sha256"] == b.attrs["data_sha256"] == table_data_sha256(b)
    assert a.attrs["chunks_resumed"] == stop_after and b.attrs["chunks_resumed"] == 0
    attrs_a, data_a = _h5_content(path)
    attrs_b, data_b = _h5_content(uninterrupted)
    assert data_a.keys() == data_b.keys() and attrs_a.keys() == attrs_b.keys()
    for name in data_a.keys() - RUN_DATASETS:
        assert data_a[name] == data_b[name], name  # every array, byte for byte
    for obj in attrs_a:
        keys = attrs_a[obj].keys() - RUN_ATTRS
        assert keys == attrs_b[obj].keys() - RUN_ATTRS, obj
        for key in keys:
            assert attrs_a[obj][key] == attrs_b[obj][key], (obj, key)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["files"]["tex-r.h5"]["data_sha256"] == b.attrs["data_sha256"]
    assert not list(tmp_path.rglob("chunk-*.h5"))  # checkpoints removed once the table exists


def test_undecodable_text_in_a_ski_file_is_a_data_file_error(tables):
    """Regression: a flipped byte in a stored string (the ``sides`` "mean" in the global heap)
    made read_ski raise UnicodeDecodeError instead of DataFileError."""
    data = _ski(tables).read_bytes()
    hits, start = [], 0
    while (start := data.find(b"mean", start) + 1) > 0:
        hits.append(start)  # the "e" of each "mean"
    assert hits
    _flip(_ski(tables), hits)
    with pytest.raises(DataFileError, match=r"ski-a\.h5.*(decode|heap)"):
        read_ski(_ski(tables))


def test_atomic_writes_get_normal_file_permissions(tmp_path):
    """Files written through atomic_path are readable like any new file (not mkstemp's 0600)."""
    import os
    import stat

    from skisnow.app.storage.common import atomic_path

    target = tmp_path / "out.txt"
    with atomic_path(target) as tmp:
        tmp.write_text("x")
    mask = os.umask(0o022)
    os.umask(mask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~mask
    assert not list(tmp_path.glob(".out.txt.*.part"))


def test_study_json_is_written_whole_with_provenance_and_numpy_values(tmp_path):
    """A study's results: schema, provenance (its parameters recorded), the body; numpy
    scalars and arrays as numbers; compact on request; no temporary file left behind."""
    import json

    import numpy as np
    from skisnow.app.storage import common

    path = tmp_path / "sub" / "study.json"
    body = {"rows": [{"x": np.float64(1.5), "v": np.arange(3)}], "where": tmp_path}
    common.write_study_json(path, "skisnow.test/1", {"seed": 3}, body)
    doc = json.loads(path.read_text(encoding="utf-8"))
    assert doc["schema"] == "skisnow.test/1"
    assert json.loads(doc["provenance"]["parameters_json"]) == {"seed": 3}
    assert doc["rows"] == [{"x": 1.5, "v": [0, 1, 2]}] and doc["where"] == str(tmp_path)
    assert "\n" in path.read_text(encoding="utf-8")
    common.write_study_json(path, "skisnow.test/1", {}, {"rows": []}, indent=None)
    assert "\n" not in path.read_text(encoding="utf-8")
    assert sorted(p.name for p in path.parent.iterdir()) == ["study.json"]
