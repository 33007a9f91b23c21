"""The torch micro backend (issue #29 point 2) against the numpy/pyFFTW solver, on the CPU:
the same algorithm must give the same contact sets and iterations, and metrics within 1e-6.
Small grids (128², nested start with one coarse level; seconds in all)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from skisnow.solvers.errors import InputError
from skisnow.solvers.micro import solve_micro

torch = pytest.importorskip("torch")
from skisnow.solvers.micro_torch import TorchHalfSpace, solve_micro_torch  # noqa: E402

E_PA = 3e8
PIXEL_M = 1.5e-6
METRICS = ("real_contact_area_fraction", "mean_gap_m", "mean_reciprocal_gap_per_m")


def _texture(n: int = 128, seed: int = 3) -> np.ndarray:
    """A seeded self-affine random texture [m] (2 µm RMS, roll-off at a quarter of Nyquist)."""
    rng = np.random.default_rng(seed)
    qx, qy = np.fft.fftfreq(n)[:, None], np.fft.rfftfreq(n)[None, :]
    q = np.hypot(qx, qy)
    q[0, 0] = 1.0
    spec = (rng.normal(size=q.shape) + 1j * rng.normal(size=q.shape)) * q**-1.8
    spec[0, 0] = 0.0
    spec[q > 0.25] = 0.0
    h = np.fft.irfft2(spec, s=(n, n))
    return h * 2e-6 / h.std()


def _same(a, b):
    assert np.array_equal(a.pressure_pa > 0, b.pressure_pa > 0)
    assert a.iterations == b.iterations
    assert a.level_iterations == b.level_iterations
    assert a.converged and b.converged
    for k in METRICS:
        assert getattr(b, k) == pytest.approx(getattr(a, k), rel=1e-6, abs=0), k
    assert b.rigid_approach_m == pytest.approx(a.rigid_approach_m, rel=1e-6)
    assert np.max(np.abs(b.pressure_pa - a.pressure_pa)) <= 1e-6 * np.max(a.pressure_pa)


@pytest.mark.parametrize("ratio", [1e-4, 1e-3, 1e-2])
def test_torch_cpu_matches_the_numpy_solver(ratio):
    h = _texture()
    a = solve_micro(h, PIXEL_M, ratio * E_PA, E_PA)
    b = solve_micro_torch(h, PIXEL_M, ratio * E_PA, E_PA, device="cpu")
    assert len(a.level_iterations) == 2  # the nested start ran
    _same(a, b)


def test_torch_warm_started_chunk_matches_the_numpy_solver():
    """Rising pressures warm-started from the previous one, one half-space reused (what a
    table chunk does)."""
    h = _texture(seed=5)
    hs = TorchHalfSpace(h.shape, PIXEL_M, E_PA, "cpu")
    prev_a = prev_b = None
    for ratio in (2e-4, 5e-4, 1.2e-3):
        a = solve_micro(h, PIXEL_M, ratio * E_PA, E_PA, initial_pressure_pa=prev_a)
        b = solve_micro_torch(
            h, PIXEL_M, ratio * E_PA, E_PA, initial_pressure_pa=prev_b, halfspace=hs
        )
        _same(a, b)
        prev_a, prev_b = a.pressure_pa, b.pressure_pa


def test_torch_full_contact_and_zero_load_match():
    h = _texture(64)
    for p in (0.0, 10 * E_PA):
        a = solve_micro(h, PIXEL_M, p, E_PA)
        b = solve_micro_torch(h, PIXEL_M, p, E_PA)
        assert a.full_contact == b.full_contact
        np.testing.assert_allclose(b.pressure_pa, a.pressure_pa, rtol=1e-9, atol=1e-9 * E_PA)
        assert b.mean_gap_m == pytest.approx(a.mean_gap_m, rel=1e-9)


def test_bad_device_is_refused():
    with pytest.raises(InputError, match="device"):
        solve_micro_torch(_texture(64), PIXEL_M, 1e5, E_PA, device="tpu")
    if not torch.cuda.is_available():
        with pytest.raises(InputError, match="no CUDA GPU"):
            solve_micro_torch(_texture(64), PIXEL_M, 1e5, E_PA, device="cuda")


def test_the_service_and_the_micro_solver_do_not_import_torch():
    """torch only when a torch solve is asked for: not on the service's request path, not by
    the table build's module or the torch backend's own import."""
    code = (
        "import sys\n"
        "import skisnow.app.main as m\n"
        "m.app\n"
        "import skisnow.solvers.micro, skisnow.solvers.lookup, skisnow.solvers.micro_torch\n"
        "import skisnow.app.jobs\n"
        "print('torch' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stderr[-2000:]


def test_a_table_chunk_on_the_torch_backend_matches_the_cpu_chunk():
    """``build-tables --device cuda`` solves its chunks with the torch backend
    (:func:`solvers.lookup.solve_table_chunk`); here on the CPU ("torch-cpu")."""
    from skisnow.solvers.lookup import solve_table_chunk

    h = _texture(seed=7)
    kw = dict(
        effective_modulus_pa=E_PA,
        full_contact_pressure_ratio=1.0,
        tol=1e-6,
        max_iterations=2000,
        gap_floor_m=1e-8,
    )
    ratios = np.array([3e-4, 1e-3])
    a = solve_table_chunk(h, PIXEL_M, ratios, **kw)
    b = solve_table_chunk(h, PIXEL_M, ratios, device="torch-cpu", **kw)
    assert np.array_equal(a["iterations"], b["iterations"])
    for k in METRICS:
        np.testing.assert_allclose(b[k], a[k], rtol=1e-6, atol=0)
    with pytest.raises(InputError, match="device"):
        solve_table_chunk(h, PIXEL_M, ratios, device="gpu", **kw)


def test_build_tables_and_the_grind_job_take_a_device():
    from skisnow.app.cli import build_parser
    from skisnow.app.settings import Settings

    args = build_parser().parse_args(["build-tables", "grind-1", "--out", "x", "--device", "cuda"])
    assert args.device == "cuda"
    assert Settings().table_device == "cpu"
    assert Settings(table_device="cuda").table_device == "cuda"


def test_device_kernels_and_gap_statistics_equal_the_numpy_ones():
    """The half-space kernels built on the device are the numpy solver's to the last bits (the
    same operations; torch's vectorised square root on the CPU may round the last bit
    otherwise), and the gap statistics computed on the device equal
    :func:`solvers.micro._gap_statistics` (sums in another order: 1e-12)."""
    import torch
    from skisnow.solvers.elastic import PeriodicHalfSpace
    from skisnow.solvers.micro import _gap_statistics
    from skisnow.solvers.micro_torch import _gap_statistics_torch

    shape, dx, e = (96, 70), (1.5e-6, 2.0e-6), 3.4e8
    ours = TorchHalfSpace(shape, dx, e, "cpu")
    ref = PeriodicHalfSpace(shape, dx, e)
    for name, kernel in (("compliance", ref.compliance), ("stiffness", ref.stiffness)):
        np.testing.assert_allclose(ours._kernels[name, torch.float64].numpy(), kernel, rtol=1e-15)
    rng = np.random.default_rng(5)
    gap = np.abs(rng.normal(size=shape)) * 1e-6
    gap[rng.random(shape) < 0.05] = 0.0  # zero gaps in the gap set
    contact = rng.random(shape) < 0.3
    for floor in (1e-8, 5e-7):
        expect = _gap_statistics(gap, contact, floor)
        got = _gap_statistics_torch(torch.as_tensor(gap), torch.as_tensor(contact), floor)
        np.testing.assert_allclose(got, expect, rtol=1e-12)
    everything = np.ones(shape, bool)
    assert _gap_statistics_torch(torch.as_tensor(gap), torch.as_tensor(everything), 1e-8) == (
        _gap_statistics(gap, everything, 1e-8)
    )
