"""skisnow science kernels: pure functions on arrays and SI floats (no file or web access).

The kernels never read or write the environment. Thread settings are the caller's: the
application sets ``GOMP_SPINCOUNT`` before any OpenMP runtime starts (:mod:`skisnow.app`); a
program that uses these kernels alone should do the same (``GOMP_SPINCOUNT=1000``: see there
why).
"""

__version__ = "0.1.0"
