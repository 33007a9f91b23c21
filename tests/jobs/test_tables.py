"""Table files and the build-tables job: round trip, corrupt files, resume after an interruption,
independence of the number of workers, stale checkpoints, manifest verification."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from skisnow.app.commands.build_tables import register
from skisnow.app.jobs.table_build import build_tables
from skisnow.app.jobs.table_settings import BuildSettings, checkpoint_key
from skisnow.app.storage.tables import (
    LOADED_DATASETS,
    SEPARATED_DATASETS,
    read_manifest,
    read_table,
    read_table_heights,
    table_data_sha256,
    verify_manifest,
    write_manifest,
)
from skisnow.solvers.errors import DataFileError, InputError
from skisnow.solvers.lookup import TABLE_SCHEMA
from skisnow.solvers.texture import Texture, self_affine_surface

PIXEL = 1e-6  # [m]
#: small grid for job tests: 12 points in 4 chunks of 3
SETTINGS = BuildSettings(points=12, ratio_min=1e-6, ratio_max=1e-1, chunk_size=3)
NUMERIC = [name for name, _, _ in LOADED_DATASETS + SEPARATED_DATASETS]


def _texture(name: str, seed: int, n: int = 64) -> Texture:
    rng = np.random.default_rng(seed)
    h = self_affine_surface((n, n), PIXEL, hurst=0.8, rms_height_m=1e-6, rng=rng)
    return Texture(h, PIXEL, name, source=f"synthetic seed {seed}")


def _assert_same_numbers(a, b):
    for name in NUMERIC:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.full_contact_pressure_ratio == b.full_contact_pressure_ratio
    assert a.unloaded_mean_gap_m == b.unloaded_mean_gap_m
    assert table_data_sha256(a) == table_data_sha256(b)


@pytest.fixture(scope="module")
def client():
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0"
    )
    with Client(cluster) as c:
        yield c
    cluster.close()


@pytest.fixture(scope="module")
def reference(tmp_path_factory, client):
    """An uninterrupted build of two textures."""
    out = tmp_path_factory.mktemp("reference")
    textures = [_texture("tex-a", 1), _texture("tex-b", 2)]
    paths = build_tables(textures, out, SETTINGS, client=client, progress=False)
    return out, paths, textures


def test_file_round_trip(reference):
    out, paths, textures = reference
    table = read_table(paths["tex-a"])
    assert table.name == "tex-a" and table.grid_shape == (64, 64)
    assert table.pixel_size_m == PIXEL
    np.testing.assert_allclose(table.pressure_ratio, SETTINGS.pressure_ratio, rtol=0)
    assert table.pressure_ratio.size == 12 and table.clearance_m.size == 64
    assert table.converged.all()
    heights, pixel = read_table_heights(paths["tex-a"])
    np.testing.assert_array_equal(heights, textures[0].heights_m)
    assert pixel == PIXEL
    with h5py.File(paths["tex-a"], "r") as f:
        assert f.attrs["schema"] == TABLE_SCHEMA
        for key in ("code_version", "git_commit", "command_line", "created_utc", "tol"):
            assert key in f.attrs
        params = json.loads(f.attrs["parameters_json"])
        assert params["tol"] == SETTINGS.tol and params["chunk_size"] == 3
        for group in ("loaded", "separated"):
            for name, ds in f[group].items():
                assert "units" in ds.attrs, name
        assert f["loaded/mean_reciprocal_gap_per_m"].attrs["gap_floor_m"] == 10e-9
        assert "iso_Sq_m" in f["texture"].attrs
    assert table.iso_parameters["Sq_m"] == pytest.approx(1e-6, rel=1e-6)
    # the manifest lists both files and verifies clean
    manifest = read_manifest(out)
    assert sorted(manifest["files"]) == ["tex-a.h5", "tex-b.h5"]
    assert verify_manifest(out) == []
    assert not (out / ".checkpoints" / "tex-a").exists()  # removed once the table is written


def test_resume_after_interruption_gives_the_same_table(tmp_path, reference, client):
    _, paths, textures = reference
    done = []

    def interrupt(name, index):
        done.append((name, index))
        if len(done) == 3:
            raise KeyboardInterrupt("simulated kill")

    with pytest.raises(KeyboardInterrupt):
        build_tables(
            textures, tmp_path, SETTINGS, client=client, progress=False, on_chunk_done=interrupt
        )
    assert not list(tmp_path.glob("*.h5"))  # no partial table file
    assert len(list((tmp_path / ".checkpoints").rglob("chunk-*.h5"))) == 3
    rerun = []
    new = build_tables(
        textures,
        tmp_path,
        SETTINGS,
        client=client,
        progress=False,
        on_chunk_done=lambda n, i: rerun.append((n, i)),
    )
    assert len(rerun) == 8 - 3  # finished chunks were not recomputed
    assert not set(rerun) & set(done)
    for name in ("tex-a", "tex-b"):
        _assert_same_numbers(read_table(new[name]), read_table(paths[name]))
    assert verify_manifest(tmp_path) == []


def test_worker_count_does_not_change_the_table(tmp_path, reference):
    """Process-based LocalClusters with 1 and 2 workers (and the threaded reference)."""
    _, paths, _ = reference
    tex = _texture("tex-a", 1)
    one = build_tables([tex], tmp_path / "one", SETTINGS, workers=1, progress=False)
    two = build_tables([tex], tmp_path / "two", SETTINGS, workers=2, progress=False)
    ref = read_table(paths["tex-a"])
    _assert_same_numbers(read_table(one["tex-a"]), ref)
    _assert_same_numbers(read_table(two["tex-a"]), ref)


def test_checkpoint_key_changes_with_every_input():
    tex = _texture("tex-a", 1)
    key = checkpoint_key(tex, SETTINGS)
    assert checkpoint_key(tex, SETTINGS) == key
    h = tex.heights_m.copy()
    h[3, 5] += 1e-12
    assert checkpoint_key(Texture(h, PIXEL, "tex-a"), SETTINGS) != key
    assert checkpoint_key(Texture(tex.heights_m, 2 * PIXEL, "tex-a"), SETTINGS) != key
    for change in ({"tol": 1e-7}, {"points": 13}, {"ratio_max": 0.2}, {"chunk_size": 4}):
        other = BuildSettings(**{**SETTINGS.__dict__, **change})
        assert checkpoint_key(tex, other) != key, change


def test_stale_checkpoints_are_not_reused(tmp_path, client):
    tex = _texture("tex-c", 3, n=32)
    s1 = BuildSettings(points=6, ratio_min=1e-4, ratio_max=1e-2, chunk_size=3)
    s2 = BuildSettings(points=6, ratio_min=1e-4, ratio_max=1e-2, chunk_size=3, tol=1e-7)
    calls = []

    def stop(name, index):
        calls.append(index)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        build_tables([tex], tmp_path, s1, client=client, progress=False, on_chunk_done=stop)
    calls.clear()
    build_tables(
        [tex],
        tmp_path,
        s2,
        client=client,
        progress=False,
        on_chunk_done=lambda name, index: calls.append(index),
    )
    assert sorted(calls) == [0, 1]  # both chunks recomputed under the new tolerance
    assert read_table(tmp_path / "tex-c.h5").tol == 1e-7


def test_corrupt_missing_and_foreign_files_raise_data_file_error(tmp_path, reference):
    _, paths, _ = reference
    with pytest.raises(DataFileError, match=r"nothere\.h5"):
        read_table(tmp_path / "nothere.h5")
    truncated = tmp_path / "truncated.h5"
    truncated.write_bytes(paths["tex-a"].read_bytes()[:2000])
    with pytest.raises(DataFileError, match=r"truncated\.h5"):
        read_table(truncated)
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f.attrs["schema"] = "someone.else/3"
    with pytest.raises(DataFileError, match="unsupported schema"):
        read_table(foreign)
    tampered = tmp_path / "tampered.h5"
    tampered.write_bytes(paths["tex-a"].read_bytes())
    with h5py.File(tampered, "r+") as f:
        f["loaded/real_contact_area_fraction"][2] *= 1.5
    with pytest.raises(DataFileError, match="data_sha256"):
        read_table(tampered)


def test_manifest_detects_modified_missing_and_unlisted_files(tmp_path, reference):
    out, _, _ = reference
    for name in ("tex-a.h5", "tex-b.h5"):
        (tmp_path / name).write_bytes((out / name).read_bytes())
    write_manifest(tmp_path)
    assert verify_manifest(tmp_path) == []
    data = bytearray((tmp_path / "tex-a.h5").read_bytes())
    data[-100] ^= 0xFF  # flip one byte
    (tmp_path / "tex-a.h5").write_bytes(bytes(data))
    problems = verify_manifest(tmp_path)
    assert len(problems) == 1 and "tex-a.h5: sha256" in problems[0]
    (tmp_path / "tex-b.h5").unlink()
    assert any(
        "tex-b.h5: listed in the manifest but missing" in p for p in verify_manifest(tmp_path)
    )
    (tmp_path / "manifest.json").unlink()
    assert "manifest not found" in verify_manifest(tmp_path)[0]


def test_build_rejects_bad_input(tmp_path):
    with pytest.raises(InputError, match="distinct"):
        build_tables([_texture("x", 1), _texture("x", 2)], tmp_path, SETTINGS, progress=False)
    with pytest.raises(InputError, match="file name"):
        build_tables([_texture("../x", 1)], tmp_path, SETTINGS, progress=False)
    with pytest.raises(InputError, match="chunk_size"):
        BuildSettings(chunk_size=0)
    with pytest.raises(InputError, match="ratio_min"):
        BuildSettings(ratio_min=1e-2, ratio_max=1e-8)


def test_cli_registers_build_tables():
    import argparse

    parser = argparse.ArgumentParser()
    register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["build-tables", "grind-1", "grind-2", "--out", "tables"])
    assert args.textures == ["grind-1", "grind-2"] and args.points == 48 and args.workers == 2
    assert callable(args.func)


def test_cli_reports_a_missing_texture_as_an_error(tmp_path, capsys):
    from skisnow.app.cli import main

    status = main(["build-tables", str(tmp_path / "no-such-texture.h5"), "--out", str(tmp_path)])
    assert status == 2
    assert "skisnow build-tables: error:" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.h5"))
