"""skisnow science kernels: pure functions on arrays and SI floats (no file or web access)."""

__version__ = "0.1.0"

import os as _os

# Two OpenMP runtimes share the cores during a micro solve: numba's (the element-wise
# kernels) and the one bundled with pyFFTW (threaded FFTs). With libgomp's default spin-wait,
# the idle threads of one runtime busy-wait after each parallel region and starve the other:
# on 2 cores a 256² solve took 2.6 s instead of 0.07 s (measured). A short spin keeps both
# responsive. It must be set before either runtime starts, so it is set on import; a value
# already in the environment wins.
_os.environ.setdefault("GOMP_SPINCOUNT", "1000")
