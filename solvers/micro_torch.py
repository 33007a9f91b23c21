"""The micro solver on PyTorch: the same algorithm as :func:`solvers.micro.solve_micro` on a
GPU (``device="cuda"``) or on the CPU (``device="cpu"``, the CI check against the numpy solver).

Same iteration, step by step, as :func:`solvers.micro._pk_cg` (preconditioned
load-controlled Polonsky–Keer CG with Polak–Ribière+ directions, a descent restart and the
Jacobi fallback, the preconditioner ``E'|q|/4``, ``u(t)`` and the clipping correction in
single precision, ``u(p)`` in double precision, recomputed exactly every 50 iterations and
before convergence is accepted), the same nested-grid start (2×2 block means, solved to
:data:`solvers.micro.COARSE_TOL`, prolonged by repetition), the same full-contact shortcut and
the same :class:`solvers.micro.MicroResult`. The fused numba passes of
:mod:`solvers._pk_kernels` are eager tensor expressions here (``torch.compile`` of them was
2–15× slower on an H200 in issue #29's prototype).

torch is imported only when a solve asks for it (:func:`_torch`): importing this module, the
micro solver or the service imports no torch (tests/test_layers.py checks), and without torch
nothing else changes. Install it with the ``train`` extra (``pip install 'skisnow[train]'``).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from .errors import InputError
from .micro import (
    COARSE_TOL,
    DEFAULT_GAP_FLOOR_M,
    MicroResult,
    _gap_statistics,
    check_micro_inputs,
)

__all__ = ["DEVICES", "TorchHalfSpace", "solve_micro_torch"]

#: devices of :func:`solve_micro_torch`
DEVICES = ("cpu", "cuda")


def _torch():
    """torch, imported on first use (an optional dependency: the ``train`` extra)."""
    try:
        import torch
    except ImportError as exc:  # pragma: no cover - torch is a test dependency
        raise InputError(
            "the torch micro backend needs PyTorch: pip install 'skisnow[train]' "
            "(or a CUDA build of torch for device='cuda')"
        ) from exc
    return torch


def check_device(device: str):
    """The ``torch.device`` of ``device`` ("cpu" or "cuda"); InputError when it is neither or
    no GPU is visible."""
    if device not in DEVICES:
        raise InputError(f"device must be one of {DEVICES}, got {device!r}")
    torch = _torch()
    if device == "cuda" and not torch.cuda.is_available():
        raise InputError(
            "device 'cuda' asked for, but torch sees no CUDA GPU (torch "
            f"{torch.__version__}; a CPU build, or no driver): use device 'cpu'"
        )
    return torch.device(device)


class TorchHalfSpace:
    """:class:`solvers.elastic.PeriodicHalfSpace` on a torch device: the same compliance
    ``4/(E'|q|)`` and stiffness ``E'|q|/4`` on the rfft2 layout (computed in float64 on the
    device from numpy's 1-D wavenumbers), the transforms ``torch.fft.rfft2``/``irfft2``. A
    float32 field gets a single-precision pair (the kernels cast once), a float64 field a
    double one."""

    def __init__(self, shape, pixel_size_m, effective_modulus_pa: float, device: str = "cpu"):
        import scipy.fft

        torch = _torch()
        self.device = check_device(device)
        nx, ny = int(shape[0]), int(shape[1])
        dx, dy = np.broadcast_to(np.asarray(pixel_size_m, dtype=float), (2,))
        if not (np.isfinite(dx) and np.isfinite(dy) and dx > 0 and dy > 0):
            raise InputError(f"pixel_size_m must be finite and > 0, got {pixel_size_m!r}")
        e_eff = float(effective_modulus_pa)
        if not np.isfinite(e_eff) or e_eff <= 0:
            raise InputError(f"effective_modulus_pa must be finite and > 0, got {e_eff!r}")
        self.shape = (nx, ny)
        self.pixel_size_m = (float(dx), float(dy))
        self.effective_modulus_pa = e_eff
        # the 1-D wavenumbers as numpy computes them (n values), the 2-D kernels on the device:
        # the same correctly rounded operations, no (n, n/2) arrays built on the host and copied
        f64 = torch.float64
        dev = self.device
        qx = torch.as_tensor(2 * np.pi * scipy.fft.fftfreq(nx, d=dx), dtype=f64, device=dev)
        qy = torch.as_tensor(2 * np.pi * scipy.fft.rfftfreq(ny, d=dy), dtype=f64, device=dev)
        q = torch.sqrt(qx[:, None] ** 2 + qy[None, :] ** 2)
        positive = q > 0
        g = torch.where(positive, 4.0 / (e_eff * torch.where(positive, q, 1.0)), 0.0)
        k = torch.where(positive, e_eff * q / 4.0, 0.0)
        del q, positive
        self._kernels = {}
        for name, t64 in (("compliance", g), ("stiffness", k)):
            self._kernels[name, torch.float64] = t64
            self._kernels[name, torch.float32] = t64.to(torch.float32)
        self._coarse: TorchHalfSpace | None = None
        self._self_compliance: float | None = None
        #: FFT pairs applied (double, single precision), for benchmarks
        self.fft_pairs = 0
        self.fft_pairs32 = 0

    def _convolve(self, name: str, field):
        torch = _torch()
        if field.dtype == torch.float32:
            self.fft_pairs32 += 1
        else:
            self.fft_pairs += 1
        spec = torch.fft.rfft2(field) * self._kernels[name, field.dtype]
        return torch.fft.irfft2(spec, s=self.shape)

    def displacement(self, pressure_pa):
        """Zero-mean displacement [m] under a periodic pressure [Pa] (a tensor on the device)."""
        return self._convolve("compliance", pressure_pa)

    def pressure(self, displacement_m):
        """Zero-mean pressure [Pa] of a displacement [m]."""
        return self._convolve("stiffness", displacement_m)

    @property
    def self_compliance(self) -> float:
        """Displacement of a pixel under a unit pressure on itself [m/Pa]."""
        if self._self_compliance is None:
            torch = _torch()
            delta = torch.zeros(self.shape, dtype=torch.float64, device=self.device)
            delta[0, 0] = 1.0
            self._self_compliance = float(self.displacement(delta)[0, 0])
        return self._self_compliance

    def coarsened(self) -> TorchHalfSpace:
        """The half-space on the 2×-coarsened grid, built on first use and kept."""
        if self._coarse is None:
            nx, ny = self.shape
            if nx % 2 or ny % 2:
                raise InputError(f"grid {self.shape} cannot be coarsened by 2")
            dx, dy = self.pixel_size_m
            self._coarse = TorchHalfSpace(
                (nx // 2, ny // 2), (2 * dx, 2 * dy), self.effective_modulus_pa, self.device.type
            )
        return self._coarse


def _gap_statistics_torch(gap, contact, floor_m: float) -> tuple[float, float]:
    """:func:`solvers.micro._gap_statistics` on the device: (floored, raw) mean reciprocal gap
    over the gap set [1/m] (zero gaps of the gap set counted at the floor in the raw one)."""
    torch = _torch()
    free = ~contact
    n_free = int(free.sum())
    if n_free == 0:
        return 1.0 / floor_m, 1.0 / floor_m
    floored = float(torch.where(free, 1.0 / torch.clamp(gap, min=floor_m), 0.0).sum()) / n_free
    pos = free & (gap > 0)
    n_pos = int(pos.sum())
    raw = (
        float(torch.where(pos, 1.0 / torch.where(pos, gap, 1.0), 0.0).sum()) / n_free
        if n_pos
        else 1.0 / floor_m
    )
    if n_pos < n_free:  # as the numpy version: zero gaps of the gap set at the floor
        raw += (n_free - n_pos) / n_free / floor_m
    return floored, raw


def _full_contact_pressure(h, hs: TorchHalfSpace):
    """:func:`solvers.micro.full_contact_pressure` on the device: (P_fc [Pa], p̃ [Pa])."""
    fluct = hs.pressure(h - h.mean())
    return max(-float(fluct.min()), 0.0), fluct


def _pk_cg(
    hs: TorchHalfSpace,
    h0,
    mean_pressure: float,
    p_init,
    tol: float,
    max_iterations: int,
    callback: Callable[[int, float], None] | None,
    precondition: bool = True,
    refresh_every: int = 50,
):
    """:func:`solvers.micro._pk_cg` on tensors; returns (p, g, δ, iterations, residual,
    converged), p and g tensors on the device. Each numbered step below is the fused pass of
    :mod:`solvers._pk_kernels` of the same name; the contact set is ``p > 0`` as it is at the
    start of the pass."""
    torch = _torch()
    f64, f32 = torch.float64, torch.float32
    n = h0.numel()
    total = mean_pressure * n
    scale_h = float(torch.sqrt(torch.mean((h0 - h0.mean()) ** 2))) or 1.0
    if p_init is None:
        p = torch.full_like(h0, mean_pressure)
    else:
        p = torch.clamp(p_init.to(f64), min=0.0)
        s = float(p.sum())
        p = p * (total / s) if s > 0 else torch.full_like(h0, mean_pressure)
    u = hs.displacement(p)

    def contact_mean_gap(p, u):
        c = p > 0
        return int(c.sum()), float(torch.where(c, h0 + u, 0.0).sum())

    nc, sum_c = contact_mean_gap(p, u)
    t = torch.zeros_like(h0)
    gc_prev = torch.zeros_like(h0)
    rz_old = 1.0
    first = True
    residual = float("inf")
    delta = 0.0
    it = 0
    converged = False
    since_refresh = 0
    while True:
        delta = sum_c / nc if nc else float(torch.min(h0 + u))
        # gap_and_norms
        c = p > 0
        g = h0 + u - delta
        gc = torch.where(c, g, 0.0)
        pen = torch.where(~c & (g < 0), g, 0.0)
        g_norm, pen_norm = float((gc * gc).sum()), float((pen * pen).sum())
        residual = (np.sqrt(g_norm / max(nc, 1)) + np.sqrt(pen_norm / max(nc, 1))) / scale_h
        if callback is not None:
            callback(it, residual)
        if residual < tol:
            if since_refresh:  # confirm on a freshly computed displacement
                u = hs.displacement(p)
                nc, sum_c = contact_mean_gap(p, u)
                since_refresh = 0
                continue
            converged = True
            break
        if it >= max_iterations:
            break
        it += 1
        gc32 = gc.to(f32)
        z32 = hs.pressure(gc32) if precondition and nc else gc32
        # mask_and_dots (float64 sums of the float32 preconditioned residual)
        z = torch.where(c, z32.to(f64), 0.0)
        z_sum = float(z.sum())
        rz = float((g * z).sum())
        z_gp = float((gc_prev * z).sum())
        gp_sum = float(torch.where(c, gc_prev, 0.0).sum())
        gc_prev = gc
        z_mean = z_sum / nc if nc else 0.0
        cross = z_gp - z_mean * gp_sum
        beta = 0.0 if first or rz_old <= 0 else max(0.0, (rz - cross) / rz_old)
        first = False

        t_new = _direction(c, z, z_mean, beta, t)
        w, tau = _step(hs, c, g, nc, t_new)
        if not tau > 0 and beta != 0.0:
            # not a descent direction: restart from the preconditioned residual
            t_new = _direction(c, z, z_mean, 0.0, t)
            w, tau = _step(hs, c, g, nc, t_new)
        t = t_new
        rz_old = rz
        if not tau > 0:
            tau = 1.0 / hs.self_compliance
        # update_pressure
        v = p - tau * t
        clipped_mask = c & (v < 0)
        added_mask = (~c & (g < 0)) if pen_norm > 0 else torch.zeros_like(c)
        p_new = torch.where(c, torch.clamp(v, min=0.0), torch.where(added_mask, -tau * g, p))
        corr = torch.where(clipped_mask, -v, torch.where(added_mask, -tau * g - v, 0.0))
        s = float(torch.where(c | added_mask, p_new, 0.0).sum())
        changed = bool(clipped_mask.any()) or bool(added_mask.any())
        p = p_new
        refresh = False
        if s <= 0:
            p = torch.full_like(h0, mean_pressure)
            refresh = first = True
            s = total
        factor = total / s
        since_refresh += 1
        refresh = refresh or since_refresh >= refresh_every
        # scale_and_update
        p = p * factor
        if refresh:
            u = hs.displacement(p)
            since_refresh = 0
        else:
            v = u - tau * w
            if changed:
                v = v + hs.displacement(corr.to(f32)).to(f64)
            u = factor * v
        nc, sum_c = contact_mean_gap(p, u)
    gap = torch.where(p > 0, 0.0, torch.clamp(g, min=0.0))
    return p, gap, delta, it, float(residual), converged


def _direction(c, z, z_mean: float, beta: float, t):
    """update_direction: t ← (z − z̄) + β t on the contact set c, 0 elsewhere."""
    return _torch().where(c, z - z_mean + beta * t, 0.0)


def _step(hs: TorchHalfSpace, c, g, nc: int, t):
    """u(t) in single precision (as float64), and the step τ of step_sums (0 when not a
    descent direction)."""
    torch = _torch()
    w = hs.displacement(t.to(torch.float32)).to(torch.float64)
    sw = float(torch.where(c, w, 0.0).sum())
    swt, st, sgt = float((w * t).sum()), float(t.sum()), float((g * t).sum())
    w_mean = sw / nc if nc else 0.0
    denom = swt - w_mean * st
    return w, (sgt / denom if denom > 0 else 0.0)


def _nested_start(h, hs, p_nom, tol, max_iterations, levels, min_size: int = 64):
    """:func:`solvers.micro._nested_start` on the device (None if the grid cannot coarsen)."""
    nx, ny = h.shape
    if nx % 2 or ny % 2 or min(nx, ny) < 2 * min_size:
        return None
    hc = h.reshape(nx // 2, 2, ny // 2, 2).mean(dim=(1, 3))
    hsc = hs.coarsened()
    p_fc, _ = _full_contact_pressure(hc, hsc)
    if p_nom >= p_fc:
        return None
    p_coarse_start = _nested_start(hc, hsc, p_nom, tol, max_iterations, levels, min_size)
    p, _, _, its, _, _ = _pk_cg(
        hsc, hc.max() - hc, p_nom, p_coarse_start, max(tol, COARSE_TOL), max_iterations, None
    )
    levels.append(its)
    return p.repeat_interleave(2, dim=0).repeat_interleave(2, dim=1)


def solve_micro_torch(
    heights_m: np.ndarray,
    pixel_size_m: float | tuple[float, float],
    nominal_pressure_pa: float,
    effective_modulus_pa: float,
    *,
    device: str = "cpu",
    tol: float = 1e-6,
    max_iterations: int = 2000,
    initial_pressure_pa: np.ndarray | None = None,
    nested: bool = True,
    gap_floor_m: float = DEFAULT_GAP_FLOOR_M,
    halfspace: TorchHalfSpace | None = None,
    callback: Callable[[int, float], None] | None = None,
) -> MicroResult:
    """:func:`solvers.micro.solve_micro` on a torch ``device`` ("cpu" or "cuda"): same
    parameters (without the FFT ``backend``/``workers``), same checks, same result (numpy
    arrays, SI units). ``halfspace``: a :class:`TorchHalfSpace` to reuse (same shape, pixel
    size, modulus and device), as a table chunk does across its rising pressures."""
    t0 = time.perf_counter()
    torch = _torch()
    h_np, p_nom, e_eff, initial_pressure_pa = check_micro_inputs(
        heights_m,
        nominal_pressure_pa,
        effective_modulus_pa,
        tol=tol,
        gap_floor_m=gap_floor_m,
        initial_pressure_pa=initial_pressure_pa,
    )
    hs = halfspace or TorchHalfSpace(h_np.shape, pixel_size_m, e_eff, device)
    if hs.shape != h_np.shape:
        raise InputError(f"halfspace has shape {hs.shape}, heights {h_np.shape}")
    dev = hs.device
    h = torch.as_tensor(h_np, dtype=torch.float64, device=dev)
    h0 = h.max() - h

    def finish(p, gap, delta, full, conv, its, res, msg, levels):
        if hasattr(p, "cpu"):  # statistics on the device, then the two fields to the host
            contact_count, mean_gap = int((p > 0).sum()), float(gap.mean())
            rec, rec_raw = _gap_statistics_torch(gap, p > 0, gap_floor_m)
            p, gap = p.cpu().numpy(), gap.cpu().numpy()
        else:
            contact = p > 0
            contact_count, mean_gap = int(np.count_nonzero(contact)), float(gap.mean())
            rec, rec_raw = _gap_statistics(gap, contact, gap_floor_m)
        return MicroResult(
            pressure_pa=p,
            gap_m=gap,
            nominal_pressure_pa=p_nom,
            effective_modulus_pa=e_eff,
            pixel_size_m=hs.pixel_size_m,
            real_contact_area_fraction=float(contact_count / p.size),
            mean_gap_m=mean_gap,
            mean_reciprocal_gap_per_m=rec,
            mean_reciprocal_gap_raw_per_m=rec_raw,
            gap_floor_m=float(gap_floor_m),
            rigid_approach_m=float(delta),
            full_contact=full,
            converged=conv,
            iterations=its,
            residual=float(res),
            message=msg,
            solve_time_s=time.perf_counter() - t0,
            level_iterations=levels,
        )

    if p_nom == 0.0:
        h0_np = h_np.max() - h_np
        return finish(
            np.zeros_like(h_np),
            h0_np,
            0.0,
            False,
            True,
            0,
            0.0,
            "zero load: unloaded texture, no contact",
            [],
        )
    p_fc, fluct = _full_contact_pressure(h, hs)
    if p_nom >= p_fc:
        p = torch.clamp(p_nom + fluct, min=0.0)
        return finish(
            p,
            torch.zeros_like(h),
            float(h0.mean()),
            True,
            True,
            0,
            0.0,
            f"full contact: nominal pressure {p_nom:.6g} Pa >= full-contact pressure {p_fc:.6g} Pa",
            [],
        )
    levels: list[int] = []
    p_start = (
        None
        if initial_pressure_pa is None
        else torch.as_tensor(initial_pressure_pa, dtype=torch.float64, device=dev)
    )
    if p_start is None and nested:
        p_start = _nested_start(h, hs, p_nom, tol, max_iterations, levels)
    p, gap, delta, its, res, conv = _pk_cg(hs, h0, p_nom, p_start, tol, max_iterations, callback)
    levels.append(its)
    msg = (
        f"converged in {its} iterations (residual {res:.3g} < tol {tol:.3g})"
        if conv
        else f"not converged: {its} iterations reached max_iterations, residual {res:.3g}"
    )
    return finish(p, gap, delta, False, conv, its, res, msg, levels)
