"""skisnow edges: command line, service, jobs, storage; everything that is not a pure kernel.

Rooms (each package's docstring says what it may import): ``commands`` → ``api`` / ``web`` /
``jobs`` → ``service`` → ``storage`` → :mod:`skisnow.solvers`; top-level modules (settings,
units, presets, errors, bounds) are shared by all rooms and import none of them.

Importing this package configures the OpenMP runtimes of the process (the one place skisnow
writes the environment). Two runtimes share the cores during a micro solve: numba's (the
element-wise kernels) and the one bundled with pyFFTW (threaded FFTs). With libgomp's default
spin-wait the idle threads of one runtime busy-wait after each parallel region and starve the
other: on 2 cores a 256² solve took 2.6 s instead of 0.07 s (measured). A short spin keeps both
responsive. It must be set before either runtime starts, i.e. before the first solver import
(every entry point, uvicorn worker and Dask task imports this package first); a value already
in the environment wins.
"""

import os as _os

_os.environ.setdefault("GOMP_SPINCOUNT", "1000")
