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
