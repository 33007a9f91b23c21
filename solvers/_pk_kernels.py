"""Fused element-wise passes of the Polonsky-Keer iteration (numba, parallel over pixels).

Each function makes one pass over flat (raveled) arrays and returns the reductions the
iteration needs, so that one CG iteration makes six passes over the fields instead of the
~40 passes of the equivalent NumPy expressions. The contact set is ``p > 0`` evaluated on the
pressure as it is at the start of the pass.
"""

from __future__ import annotations

from numba import njit, prange


@njit(parallel=True, cache=True)
def contact_mean_gap(p, h0, u):
    """Return (nc, Σ_{p>0} (h0 + u))."""
    nc = 0
    s = 0.0
    for i in prange(p.size):
        if p[i] > 0.0:
            nc += 1
            s += h0[i] + u[i]
    return nc, s


@njit(parallel=True, cache=True)
def gap_and_norms(p, h0, u, delta, g, gc32):
    """g = h0 + u − δ; gc32 = g on contact, 0 elsewhere, in single precision.

    Return (Σ_c g², Σ penetration²).
    """
    gn = 0.0
    pn = 0.0
    for i in prange(p.size):
        gi = h0[i] + u[i] - delta
        g[i] = gi
        if p[i] > 0.0:
            gc32[i] = gi
            gn += gi * gi
        else:
            gc32[i] = 0.0
            if gi < 0.0:
                pn += gi * gi
    return gn, pn


@njit(parallel=True, cache=True)
def mask_and_dots(p, z, g, gc_prev):
    """z ← z on contact (0 elsewhere); gc_prev ← g on contact (0 elsewhere) after reading it.

    Return (Σ_c z, Σ_c g·z, Σ_c gc_prev·z, Σ_c gc_prev) with the old gc_prev.
    """
    s = 0.0
    d = 0.0
    dp = 0.0
    sp = 0.0
    for i in prange(p.size):
        if p[i] > 0.0:
            zi = z[i]
            s += zi
            d += g[i] * zi
            dp += gc_prev[i] * zi
            sp += gc_prev[i]
            gc_prev[i] = g[i]
        else:
            z[i] = 0.0
            gc_prev[i] = 0.0
    return s, d, dp, sp


@njit(parallel=True, cache=True)
def update_direction(p, z, z_mean, beta, t, t32):
    """t ← (z − z̄) + β t on contact, 0 elsewhere; t32 ← t in single precision."""
    for i in prange(p.size):
        if p[i] > 0.0:
            t[i] = z[i] - z_mean + beta * t[i]
        else:
            t[i] = 0.0
        t32[i] = t[i]


@njit(parallel=True, cache=True)
def step_sums(p, w, t, g):
    """Return (Σ_{p>0} w, Σ w·t, Σ t, Σ g·t); t is zero off the contact set."""
    sw = 0.0
    swt = 0.0
    st = 0.0
    sgt = 0.0
    for i in prange(p.size):
        ti = t[i]
        swt += w[i] * ti
        st += ti
        sgt += g[i] * ti
        if p[i] > 0.0:
            sw += w[i]
    return sw, swt, st, sgt


@njit(parallel=True, cache=True)
def update_pressure(p, t, g, tau, use_overlap, corr):
    """p ← max(p − τ t, 0) on contact; p ← −τ g on penetrating free points (if use_overlap).

    ``corr`` receives the departure from the linear update, ``p_new − (p − τ t)``: non-zero
    only where a pressure was clipped or a point added. Return (Σ p, clipped, added).
    """
    s = 0.0
    clipped = 0
    added = 0
    for i in prange(p.size):
        c = 0.0
        if p[i] > 0.0:
            v = p[i] - tau * t[i]
            if v < 0.0:
                c = -v
                v = 0.0
                clipped += 1
            p[i] = v
            s += v
        elif use_overlap and g[i] < 0.0:
            v = -tau * g[i]
            c = v - (p[i] - tau * t[i])
            p[i] = v
            s += v
            added += 1
        corr[i] = c
    return s, clipped, added


@njit(parallel=True, cache=True)
def scale_and_update(p, factor, u, w, tau, update_u, du, use_du, h0):
    """p ← factor·p; if update_u: u ← factor·(u − τ w [+ du if use_du]).

    Return (nc, Σ_{p>0} (h0 + u)) of the updated fields (meaningful when update_u).
    """
    nc = 0
    s = 0.0
    for i in prange(p.size):
        p[i] *= factor
        if update_u:
            v = u[i] - tau * w[i]
            if use_du:
                v += du[i]
            u[i] = factor * v
            if p[i] > 0.0:
                nc += 1
                s += h0[i] + u[i]
    return nc, s
