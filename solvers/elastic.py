"""Elastic half-space kernels: periodic (micro scale) and non-periodic (macro scale).

Elasticity convention (docs/physics.md §3)
------------------------------------
One effective modulus ``E'`` with ``2/E' = (1-ν²)/E_snow + (1-ν²)/E_base``. The surface
displacement under a pressure ``p`` is ``u(x, y) = 2/(π E') ∬ p(x', y') / r dx' dy'``, i.e.
``û(q) = 4 p̂(q) / (E' |q|)``. ``E' = 2 E*`` where ``E*`` is Johnson's composite modulus.
Displacement ``u`` is positive *into* the half-space (it opens the gap).

FFT convention (periodic kernel)
--------------------------------
- Real-to-complex transforms ``rfft2`` / ``irfft2`` over both axes with ``norm="backward"``:
  the forward transform is unnormalised and the inverse carries ``1/(nx ny)``. Because the
  kernel multiplies the transform pointwise, the convention cancels: ``u = irfft2(G · rfft2(p))``.
- Layout: axis 0 has ``nx`` points (``fftfreq``), axis 1 is the half spectrum of ``ny`` points
  (``rfftfreq``); odd and even sizes are both exact.
- Wavevector ``q = 2π (fx, fy)`` in rad/m for a pixel size ``dx, dy`` [m]; ``G(q) = 4/(E'|q|)``.
- The ``q = 0`` mode (the mean pressure) is mapped to zero displacement: on a periodic cell a
  uniform pressure only moves the half-space rigidly, which the solvers carry separately as the
  rigid approach. The displacement returned therefore has zero mean.

Non-periodic kernel (macro scale)
---------------------------------
The half-space is infinite: pressure is piecewise constant on rectangular pixels and the
influence coefficients are Love's (1929) closed-form displacement at pixel centres due to a
uniformly loaded rectangle, ``u = (2/(π E')) F(x, y; a, b)``. The discrete convolution is done
with zero padding to ``(2nx, 2ny)`` so that it is linear, not circular. Same FFT normalisation.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
import scipy.fft
from numba import njit, prange

from .errors import InputError

__all__ = [
    "FFTBackend",
    "NonPeriodicHalfSpace",
    "PeriodicHalfSpace",
    "effective_modulus",
    "love_rectangle_influence",
]


def effective_modulus(
    snow_modulus_pa: float, base_modulus_pa: float = 0.7e9, poisson_ratio: float = 0.3
) -> float:
    """Effective modulus E' of docs/physics.md eq. (1).

    Parameters
    ----------
    snow_modulus_pa : float
        Young's modulus of the (virtual) snow [Pa].
    base_modulus_pa : float
        Young's modulus of the ski base [Pa]; default 0.7 GPa (sintered UHMWPE, our choice).
    poisson_ratio : float
        Poisson's ratio of both bodies [-]; default 0.3 (our choice).

    Returns
    -------
    float
        E' [Pa] with ``2/E' = (1-ν²)/E_snow + (1-ν²)/E_base``.
    """
    for name, value in (("snow_modulus_pa", snow_modulus_pa), ("base_modulus_pa", base_modulus_pa)):
        if not np.isfinite(value) or value <= 0:
            raise InputError(f"{name} must be a finite number > 0, got {value!r}")
    if not np.isfinite(poisson_ratio) or not (0.0 <= poisson_ratio < 0.5):
        raise InputError(f"poisson_ratio must be in [0, 0.5), got {poisson_ratio!r}")
    c = 1.0 - poisson_ratio**2
    return 2.0 / (c / snow_modulus_pa + c / base_modulus_pa)


def _default_workers() -> int:
    return max(1, os.cpu_count() or 1)


def pyfftw_available() -> bool:
    """True when pyFFTW can be imported (the ``fftw`` extra)."""
    try:
        import pyfftw  # noqa: F401
    except ImportError:
        return False
    return True


def resolve_backend(backend: str) -> str:
    """``"auto"`` → ``"pyfftw"`` when installed (faster here, docs/benchmarks.md), else scipy."""
    if backend == "auto":
        return "pyfftw" if pyfftw_available() else "scipy"
    if backend not in ("scipy", "pyfftw"):
        raise InputError(f"backend must be 'auto', 'scipy' or 'pyfftw', got {backend!r}")
    return backend


@njit(parallel=True, cache=True)
def _multiply_spectrum(spec, kernel, scale):  # pragma: no cover - compiled
    """spec ← spec · kernel · scale, in place (one pass, all threads)."""
    nx, ny = spec.shape
    for i in prange(nx):
        for j in range(ny):
            spec[i, j] *= kernel[i, j] * scale


@dataclass
class FFTBackend:
    """Real 2-D FFT pair for one array shape: ``scipy.fft`` or pyFFTW.

    Parameters
    ----------
    shape : tuple of int
        Real-space shape ``(nx, ny)``.
    backend : {"auto", "scipy", "pyfftw"}
        ``"pyfftw"`` needs the ``fftw`` extra (``pip install 'skisnow[fftw]'``); ``"auto"``
        uses it when installed.
    workers : int, optional
        Threads; default: all cores.

    Notes
    -----
    pyFFTW plans are made with ``FFTW_ESTIMATE``: planning is instant and deterministic (the
    same plan, hence bit-identical results, in every process), where ``FFTW_MEASURE`` times
    candidate plans and may pick a different one in each run. :meth:`convolve` executes plans
    bound to the caller's arrays (no copies) and folds the ``1/N`` of the inverse transform
    into the spectral multiplication.
    """

    shape: tuple[int, int]
    backend: str = "auto"
    workers: int | None = None
    _fwd: object = field(init=False, repr=False, default=None)
    _inv: object = field(init=False, repr=False, default=None)
    _plans: dict = field(init=False, repr=False, default_factory=dict)
    _work: dict = field(init=False, repr=False, default_factory=dict)
    _owned: set = field(init=False, repr=False, default_factory=set)
    _spectra: dict = field(init=False, repr=False, default_factory=dict)

    def __post_init__(self) -> None:
        self.shape = (int(self.shape[0]), int(self.shape[1]))
        self._inverse_scale = 1.0 / (self.shape[0] * self.shape[1])
        if self.workers is None:
            self.workers = _default_workers()
        self.backend = resolve_backend(self.backend)
        if self.backend == "pyfftw":
            try:
                import pyfftw
            except ImportError as exc:  # pragma: no cover - depends on the environment
                raise ImportError(
                    "backend='pyfftw' needs pyFFTW: pip install 'skisnow[fftw]'"
                ) from exc
            self._pyfftw = pyfftw
            # private buffers for arrays that are not workspace arrays (copied in and out)
            buffers = (self.empty(), self.empty())
            self._owned.update(b.ctypes.data for b in buffers)
            self._fwd, self._inv, _ = self.bound_plans(*buffers)

    @property
    def spectrum_shape(self) -> tuple[int, int]:
        """Shape of the rfft2 half spectrum."""
        return (self.shape[0], self.shape[1] // 2 + 1)

    def empty(self, dtype: type = np.float64) -> np.ndarray:
        """An uninitialised real array of ``shape``, SIMD-aligned for pyFFTW."""
        if self.backend == "pyfftw":
            return self._pyfftw.empty_aligned(self.shape, dtype=dtype)
        return np.empty(self.shape, dtype=dtype)

    def _plan(self, a: np.ndarray, b: np.ndarray, direction: str):
        flags = ("FFTW_ESTIMATE",)
        if direction == "FFTW_BACKWARD":
            flags = ("FFTW_ESTIMATE", "FFTW_DESTROY_INPUT")
        return self._pyfftw.FFTW(
            a, b, axes=(0, 1), direction=direction, threads=self.workers, flags=flags
        )

    def workspace(self, count: int, dtype: type = np.float64) -> list[np.ndarray]:
        """``count`` real work arrays of ``shape`` and ``dtype`` owned by this backend,
        allocated once.

        Transforms between workspace arrays run on the arrays themselves with plans made
        once (pyFFTW); the arrays are shared by every caller of this backend, so a solver
        uses them for the duration of one call only. float32 arrays give single-precision
        transforms (relative error ~1e-7 of the result's scale: for preconditioners and
        small corrections, never for a field that must be exact).
        """
        work = self._work.setdefault(np.dtype(dtype), [])
        while len(work) < count:
            arr = self.empty(dtype)
            work.append(arr)
            self._owned.add(arr.ctypes.data)
        return work[:count]

    def bound_plans(self, src: np.ndarray, out: np.ndarray) -> tuple:
        """pyFFTW ``(forward, inverse, spectrum)`` bound to two distinct workspace arrays of
        one dtype, made once: ``forward.execute()`` transforms ``src`` into ``spectrum``,
        ``inverse.execute()`` the spectrum into ``out`` (unnormalised, destroying it)."""
        key = (src.ctypes.data, out.ctypes.data)
        plans = self._plans.get(key)
        if plans is None:
            if out is src or key[0] not in self._owned or key[1] not in self._owned:
                raise InputError("bound_plans needs two distinct workspace arrays")
            if src.dtype != out.dtype:
                raise InputError("bound_plans needs two workspace arrays of one dtype")
            complex_dtype = np.result_type(src.dtype, np.complex64)
            spectrum = self._spectra.get(complex_dtype)
            if spectrum is None:
                spectrum = self._pyfftw.empty_aligned(self.spectrum_shape, dtype=complex_dtype)
                self._spectra[complex_dtype] = spectrum
            plans = (
                self._plan(src, spectrum, "FFTW_FORWARD"),
                self._plan(spectrum, out, "FFTW_BACKWARD"),
                spectrum,
            )
            self._plans[key] = plans
        return plans

    def convolve(
        self, kernel: np.ndarray, src: np.ndarray, out: np.ndarray | None = None
    ) -> np.ndarray:
        """``out = irfft2(kernel · rfft2(src))`` with ``kernel`` on the rfft2 layout.

        With pyFFTW, when ``src`` and ``out`` are distinct :meth:`workspace` arrays of one
        dtype the transforms run on them directly, in that precision; other arrays are
        copied through internal float64 buffers.
        """
        if self.backend == "scipy":
            res = scipy.fft.irfft2(
                kernel * scipy.fft.rfft2(src, workers=self.workers),
                s=self.shape,
                workers=self.workers,
            )
            if out is None:
                return res
            out[...] = res
            return out
        if (
            out is not None
            and out is not src
            and src.dtype == out.dtype
            and src.ctypes.data in self._owned
            and out.ctypes.data in self._owned
        ):
            fwd, inv, spectrum = self.bound_plans(src, out)
            target = out
        else:
            fwd, inv = self._fwd, self._inv
            spectrum = fwd.output_array
            fwd.input_array[...] = src
            target = inv.output_array
        fwd.execute()
        _multiply_spectrum(spectrum, kernel, self._inverse_scale)
        inv.execute()
        if out is None:
            return target.copy()
        if target is not out:
            out[...] = target
        return out


class PeriodicHalfSpace:
    """Periodic elastic half-space on an ``(nx, ny)`` grid (micro scale).

    Parameters
    ----------
    shape : tuple of int
        Grid ``(nx, ny)`` [-].
    pixel_size_m : float or tuple of float
        Pixel size ``dx`` (and ``dy``) [m].
    effective_modulus_pa : float
        E' of docs/physics.md eq. (1) [Pa].
    backend, workers :
        Passed to :class:`FFTBackend`.
    """

    def __init__(
        self,
        shape: tuple[int, int],
        pixel_size_m: float | tuple[float, float],
        effective_modulus_pa: float,
        *,
        backend: str = "auto",
        workers: int | None = None,
    ) -> None:
        nx, ny = int(shape[0]), int(shape[1])
        if nx < 1 or ny < 1:
            raise InputError(f"shape must be positive, got {shape!r}")
        dx, dy = np.broadcast_to(np.asarray(pixel_size_m, dtype=float), (2,))
        if not (np.isfinite(dx) and np.isfinite(dy) and dx > 0 and dy > 0):
            raise InputError(f"pixel_size_m must be finite and > 0, got {pixel_size_m!r}")
        if not np.isfinite(effective_modulus_pa) or effective_modulus_pa <= 0:
            raise InputError(
                f"effective_modulus_pa must be finite and > 0, got {effective_modulus_pa!r}"
            )
        self.shape = (nx, ny)
        self.pixel_size_m = (float(dx), float(dy))
        self.effective_modulus_pa = float(effective_modulus_pa)
        self.fft = FFTBackend(self.shape, backend=backend, workers=workers)
        self._self_compliance: float | None = None
        self._coarse: PeriodicHalfSpace | None = None
        #: number of FFT pairs (forward + inverse) applied so far (for benchmarks)
        self.fft_pairs = 0
        #: number of single-precision FFT pairs applied so far (for benchmarks)
        self.fft_pairs32 = 0
        qx = 2 * np.pi * scipy.fft.fftfreq(nx, d=dx)[:, None]
        qy = 2 * np.pi * scipy.fft.rfftfreq(ny, d=dy)[None, :]
        q = np.sqrt(qx**2 + qy**2)
        #: |q| on the rfft2 layout [rad/m]
        self.wavevector = q
        with np.errstate(divide="ignore"):
            g = np.where(q > 0, 4.0 / (self.effective_modulus_pa * q), 0.0)
        #: compliance G(q) = 4/(E'|q|) [m/Pa · m], zero at q = 0
        self.compliance = g
        with np.errstate(divide="ignore"):
            #: stiffness 1/G(q) = E'|q|/4, zero at q = 0
            self.stiffness = np.where(q > 0, self.effective_modulus_pa * q / 4.0, 0.0)

    @property
    def self_compliance(self) -> float:
        """Displacement of a pixel under a unit pressure on itself (diagonal) [m/Pa]."""
        if self._self_compliance is None:
            delta = np.zeros(self.shape)
            delta[0, 0] = 1.0
            self._self_compliance = float(self.displacement(delta)[0, 0])
        return self._self_compliance

    def coarsened(self) -> PeriodicHalfSpace:
        """The half-space on the 2×-coarsened grid (pixels twice as large; same modulus,
        backend and threads), built on first use and kept."""
        if self._coarse is None:
            nx, ny = self.shape
            if nx % 2 or ny % 2:
                raise InputError(f"grid {self.shape} cannot be coarsened by 2")
            dx, dy = self.pixel_size_m
            self._coarse = PeriodicHalfSpace(
                (nx // 2, ny // 2),
                (2 * dx, 2 * dy),
                self.effective_modulus_pa,
                backend=self.fft.backend,
                workers=self.fft.workers,
            )
        return self._coarse

    def workspace(self, count: int, dtype: type = np.float64) -> list[np.ndarray]:
        """Work fields of the grid's shape for FFTs without copies (see FFTBackend)."""
        return self.fft.workspace(count, dtype)

    def _count(self, out: np.ndarray | None) -> None:
        if out is not None and out.dtype == np.float32:
            self.fft_pairs32 += 1
        else:
            self.fft_pairs += 1

    def displacement(self, pressure_pa: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Zero-mean surface displacement [m] under a periodic pressure field [Pa].

        ``out`` (optional, not ``pressure_pa``): write the result there; two
        :meth:`workspace` arrays avoid copies with pyFFTW, and two float32 ones give a
        single-precision pair (counted in ``fft_pairs32``).
        """
        self._count(out)
        return self.fft.convolve(self.compliance, pressure_pa, out)

    def pressure(self, displacement_m: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Zero-mean pressure [Pa] that produces a (zero-mean part of a) displacement [m]
        (``out`` as in :meth:`displacement`)."""
        self._count(out)
        return self.fft.convolve(self.stiffness, displacement_m, out)


def love_rectangle_influence(
    x_m: np.ndarray, y_m: np.ndarray, half_width_x_m: float, half_width_y_m: float
) -> np.ndarray:
    """Love's (1929) function F so that ``u = 2/(π E') · p · F`` at (x, y) [m].

    Displacement of an elastic half-space at ``(x, y)`` under a uniform pressure ``p`` on the
    rectangle ``|x| ≤ a, |y| ≤ b`` (Johnson, Contact Mechanics, 1985, §3.3, with E' = 2E*).
    """
    a, b = half_width_x_m, half_width_y_m
    x = np.asarray(x_m, dtype=float)
    y = np.asarray(y_m, dtype=float)

    def term(s: np.ndarray, t: np.ndarray) -> np.ndarray:
        # s * asinh(t/|s|)-type primitive, written stably: s*ln(t + sqrt(s²+t²))
        r = np.sqrt(s * s + t * t)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = np.where(s != 0, s * np.log(np.where(r + t > 0, t + r, 1.0)), 0.0)
        return out

    def prim(xx: np.ndarray, yy: np.ndarray) -> np.ndarray:
        # ∬ dx dy / r primitive: x ln(y + r) + y ln(x + r)
        return term(xx, yy) + term(yy, xx)

    xp, xm = x + a, x - a
    yp, ym = y + b, y - b
    return prim(xp, yp) - prim(xp, ym) - prim(xm, yp) + prim(xm, ym)


class NonPeriodicHalfSpace:
    """Infinite elastic half-space sampled on an ``(nx, ny)`` grid (macro scale).

    Pressure is constant over each pixel; displacement is evaluated at pixel centres by a
    zero-padded (linear) FFT convolution with Love's influence coefficients.

    Parameters
    ----------
    shape : tuple of int
        Grid ``(nx, ny)`` [-].
    pixel_size_m : float or tuple of float
        Pixel size ``(dx, dy)`` [m].
    effective_modulus_pa : float
        E' [Pa].
    """

    def __init__(
        self,
        shape: tuple[int, int],
        pixel_size_m: float | tuple[float, float],
        effective_modulus_pa: float,
        *,
        workers: int | None = None,
    ) -> None:
        nx, ny = int(shape[0]), int(shape[1])
        if nx < 1 or ny < 1:
            raise InputError(f"shape must be positive, got {shape!r}")
        dx, dy = np.broadcast_to(np.asarray(pixel_size_m, dtype=float), (2,))
        if not (np.isfinite(dx) and np.isfinite(dy) and dx > 0 and dy > 0):
            raise InputError(f"pixel_size_m must be finite and > 0, got {pixel_size_m!r}")
        if not np.isfinite(effective_modulus_pa) or effective_modulus_pa <= 0:
            raise InputError(
                f"effective_modulus_pa must be finite and > 0, got {effective_modulus_pa!r}"
            )
        self.shape = (nx, ny)
        self.pixel_size_m = (float(dx), float(dy))
        self.effective_modulus_pa = float(effective_modulus_pa)
        self.workers = workers if workers is not None else _default_workers()
        px, py = 2 * nx, 2 * ny
        ix = np.arange(px)
        iy = np.arange(py)
        ix = np.where(ix < nx, ix, ix - px)  # signed offsets, wrap-around layout
        iy = np.where(iy < ny, iy, iy - py)
        xx = ix[:, None] * dx
        yy = iy[None, :] * dy
        kern = (
            2.0
            / (np.pi * self.effective_modulus_pa)
            * love_rectangle_influence(xx, yy, dx / 2, dy / 2)
        )
        kern[nx, :] = 0.0  # offsets that can never be reached by an nx-long grid
        kern[:, ny] = 0.0
        self._padded_shape = (px, py)
        self._kernel_hat = scipy.fft.rfft2(kern, workers=self.workers)
        #: influence of a unit pressure on its own pixel [m/Pa]
        self.self_compliance = float(kern[0, 0])

    def displacement(self, pressure_pa: np.ndarray) -> np.ndarray:
        """Surface displacement [m] at pixel centres under ``pressure_pa`` [Pa]."""
        nx, ny = self.shape
        p_hat = scipy.fft.rfft2(pressure_pa, s=self._padded_shape, workers=self.workers)
        u = scipy.fft.irfft2(p_hat * self._kernel_hat, s=self._padded_shape, workers=self.workers)
        return u[:nx, :ny]
