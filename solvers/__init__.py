"""skisnow science kernels: pure functions on arrays and SI floats (no file or web access)."""

__version__ = "0.1.0"
