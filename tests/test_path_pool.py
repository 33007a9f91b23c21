"""app/path_pool.py: the identification's worker processes run one BLAS thread in every BLAS
library (numpy's and scipy's own OpenBLAS). Left at two, scipy's busy-waited against the other
worker and the two forward paths took 4x longer side by side than one after the other."""

import subprocess
import sys

from skisnow.app.path_pool import path_pool

#: the initialiser, then everything the identification loads; every BLAS then at one thread
_CHECK = (
    "from app.path_pool import _one_thread; _one_thread(); "
    "import scipy.linalg, scipy.sparse, solvers.identify; "
    "from threadpoolctl import threadpool_info; "
    "info = threadpool_info(); "
    "print(len(info), sorted({i['num_threads'] for i in info}))"
)


def test_worker_initialiser_limits_every_blas_to_one_thread():
    out = subprocess.run(
        [sys.executable, "-c", _CHECK], capture_output=True, text=True, check=True, timeout=120
    ).stdout.split(maxsplit=1)
    assert int(out[0]) >= 1
    assert out[1].strip() == "[1]"  # also the libraries loaded after the initialiser ran


def _threads(_):
    from threadpoolctl import threadpool_info

    return sorted({i["num_threads"] for i in threadpool_info()})


def test_pool_workers_run_one_thread_and_one_core_runs_here():
    with path_pool(2) as pmap:
        assert pmap is not None
        assert list(pmap(_threads, range(2))) == [[1], [1]]
    with path_pool(1) as pmap:
        assert pmap is None  # fewer than two workers: the paths run in the caller


def _small_identification_data():
    import numpy as np
    from skisnow.solvers.beam import OTHER_DESIGNS, measure_camber, measure_unloaded

    ski = OTHER_DESIGNS["stiff"].build(8e-3)
    f, xf, y = measure_camber(
        ski, np.linspace(10, 90, 4) * 9.82, np.linspace(-0.3, 0.1, 3), noise_m=3e-6, rng=11
    )
    y0 = measure_unloaded(ski, noise_m=3e-6, rng=12)
    return ski.positions_m, np.r_[0.0, f], np.r_[0.0, xf], np.vstack([y0, y])


def test_identification_runs_at_fixed_blas_threads_whatever_the_caller_set():
    """identify_with_pool (the ski job's call): the identification itself runs at
    IDENTIFICATION_BLAS_THREADS in this process too (the start and the held-out check run
    here), even when the caller allows two (#26)."""
    from skisnow.app.path_pool import IDENTIFICATION_BLAS_THREADS, identify_with_pool
    from skisnow.solvers.identify import identify_beam
    from threadpoolctl import threadpool_limits

    seen = set()

    def fake_identify(*args, path_map=None, **kwargs):
        seen.update(_threads(None))
        return identify_beam(*args, path_map=path_map, **kwargs)

    x, f, xf, y = _small_identification_data()
    with threadpool_limits(2):
        identify_with_pool(fake_identify, x, f, xf, y, workers=1, max_steps=2)
        assert _threads(None) == [2]  # restored afterwards
    assert seen == {IDENTIFICATION_BLAS_THREADS}


def test_same_beam_with_one_and_two_blas_threads():
    """The same data give bit for bit the same beam whether the caller runs one or two BLAS
    threads (the job's thread counts are fixed, #26)."""
    import numpy as np
    from skisnow.app.path_pool import identify_with_pool
    from skisnow.solvers.identify import identify_beam
    from threadpoolctl import threadpool_limits

    x, f, xf, y = _small_identification_data()
    out = []
    for threads in (1, 2):
        with threadpool_limits(threads):
            out.append(identify_with_pool(identify_beam, x, f, xf, y, workers=1, max_steps=4))
    a, b = out
    assert np.array_equal(a.beam.bending_stiffness_nm2, b.beam.bending_stiffness_nm2)
    assert np.array_equal(a.beam.unloaded_gap_m, b.beam.unloaded_gap_m)
    assert a.misfit_m == b.misfit_m
