"""Virtual ski-camber measuring device: an Euler–Bernoulli ski pressed onto a rigid flat.

Method.md §4 step 1: a device presses the ski with a point load F at x_F against a rigid flat and
records the gap H*(X) between the base and the flat along the ski. This module replaces the real
device for the demo skis and for tests: the ski is a free Euler–Bernoulli beam with bending
stiffness EI(X) and an unloaded camber c(X) (the gap above the flat when the ski rests on it with
no load; c ≥ 0, zero at the unloaded contact points).

Discretisation
--------------
Nodes on a uniform grid X_i (1 mm by default). The upward displacement u_i of the base is measured
from the unloaded shape, so the loaded gap is ``z_i = c_i + u_i``. The bending energy is
``½ Σ_i EI_i (u_{i-1} − 2u_i + u_{i+1})² / dx³`` over interior nodes (second-order finite
differences, free ends: zero moment and shear at the tip and the tail), i.e. ``K = D2ᵀ W D2``.
K has the two rigid-body modes (translation, rotation) in its null space, so force and moment
equilibrium of the nodal loads follow from ``K u = f + r`` to rounding.

Unilateral contact (exact for the discrete model): ``K u = f + r`` with the point load
``f = −F`` (split linearly between the two nodes around x_F), nodal reactions ``r ≥ 0``, gap
``z ≥ 0`` and ``r·z = 0``. Solved by a primal–dual active-set method (Hintermüller, Ito &
Kunisch, SIAM J. Optim. 13, 2002): on the active set the gap is fixed to zero, elsewhere the
reaction is zero; the set is updated from ``r − κ z`` until it repeats. Each step is one sparse
banded solve.

Units: SI throughout (m, N, N·m²).
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import numba
import numpy as np

from .errors import InputError

__all__ = [
    "G_STANDARD",
    "OTHER_DESIGNS",
    "BeamFlexibility",
    "BeamResult",
    "BeamSki",
    "ClassicSkiDesign",
    "camber_on_flat",
    "flat_supports",
    "measure_camber",
    "measure_unloaded",
    "solve_beam_contact",
]

#: Gravitational acceleration used by the papers to convert kg to N [m/s²]
G_STANDARD = 9.82


@dataclass(frozen=True)
class BeamSki:
    """A ski as a free Euler–Bernoulli beam on a uniform grid.

    Attributes
    ----------
    positions_m : ndarray, shape (N,)
        Node positions X from the balance point, positive towards the tip [m]; uniform spacing.
    bending_stiffness_nm2 : ndarray, shape (N,)
        Bending stiffness EI(X) [N·m²], > 0.
    unloaded_gap_m : ndarray, shape (N,)
        Camber c(X): gap between base and flat with no load [m], ≥ 0 with minimum 0.
    """

    positions_m: np.ndarray
    bending_stiffness_nm2: np.ndarray
    unloaded_gap_m: np.ndarray

    def __post_init__(self) -> None:
        x = np.asarray(self.positions_m, dtype=float)
        ei = np.asarray(self.bending_stiffness_nm2, dtype=float)
        c = np.asarray(self.unloaded_gap_m, dtype=float)
        if x.ndim != 1 or x.size < 5:
            raise InputError(f"positions_m must be 1-D with at least 5 nodes, got shape {x.shape}")
        for name, arr in (("bending_stiffness_nm2", ei), ("unloaded_gap_m", c)):
            if arr.shape != x.shape:
                raise InputError(f"{name} has shape {arr.shape}, expected {x.shape}")
            if not np.all(np.isfinite(arr)):
                raise InputError(f"{name} contains NaN or inf values")
        if not np.all(np.isfinite(x)):
            raise InputError("positions_m contains NaN or inf values")
        dx = np.diff(x)
        if np.any(dx <= 0) or np.ptp(dx) > 1e-9 * abs(dx.mean()) + 1e-12:
            raise InputError("positions_m must be increasing with a uniform spacing")
        if np.any(ei <= 0):
            raise InputError(f"bending_stiffness_nm2 must be > 0, got min {ei.min()!r}")
        if np.any(c < 0):
            raise InputError(f"unloaded_gap_m must be >= 0, got min {c.min()!r}")
        object.__setattr__(self, "positions_m", x)
        object.__setattr__(self, "bending_stiffness_nm2", ei)
        object.__setattr__(self, "unloaded_gap_m", c)

    @property
    def spacing_m(self) -> float:
        """Node spacing dx [m]."""
        return float(self.positions_m[1] - self.positions_m[0])


@dataclass
class BeamResult:
    """Loaded state of a beam ski on a rigid flat.

    Attributes
    ----------
    positions_m : ndarray (N,)
        Node positions X [m].
    gap_m : ndarray (N,)
        Loaded gap H*(X) ≥ 0 [m], exactly 0 on the contact set.
    reaction_n : ndarray (N,)
        Nodal contact reactions of the flat on the ski, ≥ 0 [N].
    displacement_m : ndarray (N,)
        Upward displacement u from the unloaded shape (elastic + rigid) [m].
    contact : ndarray of bool (N,)
        Nodes in contact with the flat.
    load_n, load_position_m : float
        F [N] and x_F [m].
    force_residual, moment_residual : float
        |Σr − F| / F and |Σ r (X − x_F)| / (F L) [-].
    converged, iterations, residual, message :
        Diagnostics; ``residual`` is the largest complementarity violation
        (max of −min gap / max camber, −min reaction / F, force and moment residuals) [-].
    solve_time_s : float
        Wall time [s].
    """

    positions_m: np.ndarray
    gap_m: np.ndarray
    reaction_n: np.ndarray
    displacement_m: np.ndarray
    contact: np.ndarray
    load_n: float
    load_position_m: float
    force_residual: float
    moment_residual: float
    converged: bool
    iterations: int
    residual: float
    message: str
    solve_time_s: float = 0.0


class BeamFlexibility:
    """Flexibility of a free beam ski under self-equilibrated nodal forces (reusable per ski).

    Column j of :attr:`matrix` is the upward deflection [m/N] due to a unit upward force at node j
    with the moment ``M(X) = Σ_{X_j < X} f_j (X − X_j)`` and ``w = w' = 0`` at the tail node; for a
    self-equilibrated force set this is the true deflection up to a rigid-body motion, which the
    contact solve carries separately. ``M/EI`` is linear between nodes and integrated exactly.

    Parameters
    ----------
    ski : BeamSki
        Beam model.
    """

    def __init__(self, ski: BeamSki) -> None:
        x = np.ascontiguousarray(ski.positions_m, dtype=float)
        ei = np.ascontiguousarray(ski.bending_stiffness_nm2, dtype=float)
        # compiled (the numpy form, _flexibility_reference, built five N × N temporaries:
        # 0.3-1 s at 2001 nodes, most of a forward fit's time); the same sums in the same
        # order, so bit-identical (tests/solvers/test_beam_compiled.py). Only the columns are
        # built (contiguous writes): also writing the matrix, one cache line per entry, took
        # 27 ms instead of 7 ms at 2001 nodes, and every forward-fit evaluation builds one
        self.ski = ski
        self._columns: np.ndarray = _flexibility_columns_compiled(x, ei, float(ski.spacing_m))

    @property
    def matrix(self) -> np.ndarray:
        """(N, N) flexibility [m/N]: a read-only transposed view of :attr:`columns` (the same
        values; not C-contiguous: a product with it may round differently from one with a
        C-contiguous copy, ``np.ascontiguousarray(flex.matrix)``)."""
        view = self._columns.T
        view.flags.writeable = False
        return view

    @property
    def columns(self) -> np.ndarray:
        """``matrix.T``, C-contiguous [m/N]: row j is column j of :attr:`matrix` in contiguous
        memory, so the contact solve reads the columns of its active nodes as streams instead
        of one cache line per node of the ski."""
        return self._columns

    def load_column(self, load_position_m: float) -> np.ndarray:
        """Deflection [m/N] under a unit upward force at x_F (split linearly between nodes;
        column j of :attr:`matrix` read as row j of :attr:`columns`, the same values)."""
        x = self.ski.positions_m
        s = (load_position_m - x[0]) / self.ski.spacing_m
        i = min(int(np.floor(s)), x.size - 2)
        t = s - i
        cols = self.columns
        return (1.0 - t) * cols[i] + t * cols[i + 1]


def _flexibility_reference(x: np.ndarray, ei: np.ndarray, dx: float) -> np.ndarray:
    """:class:`BeamFlexibility`'s matrix [m/N] in numpy (the reference of the compiled
    kernel): curvature κ_ij = max(X_i − X_j, 0) / EI_i of a unit force at node j, integrated
    twice along i (trapezoidal slope, exact deflection of a linear M/EI), zero at the tail."""
    kappa = np.maximum(x[:, None] - x[None, :], 0.0) / ei[:, None]
    slope_inc = 0.5 * dx * (kappa[:-1] + kappa[1:])
    slope = np.zeros_like(kappa)
    np.cumsum(slope_inc, axis=0, out=slope[1:])
    w_inc = dx * slope[:-1] + dx * dx * (2.0 * kappa[:-1] + kappa[1:]) / 6.0
    w = np.zeros_like(kappa)
    np.cumsum(w_inc, axis=0, out=w[1:])
    return w


@numba.njit(cache=True)
def _flexibility_columns_compiled(x, ei, dx):
    """:func:`_flexibility_reference`'s matrix transposed (C-contiguous) [m/N], column by
    column of the matrix (row by row of the result): κ, slope and deflection are zero at and
    behind node j (i ≤ j), so only i > j is summed, with the reference's operations in its
    order (bit-identical)."""
    n = x.size
    wt = np.zeros((n, n))
    half_dx = 0.5 * dx
    dx2 = dx * dx
    for j in range(n):
        slope = 0.0
        wij = 0.0
        k_prev = 0.0  # κ at node j itself
        for i in range(j + 1, n):
            k_i = max(x[i] - x[j], 0.0) / ei[i]
            w_inc = dx * slope + dx2 * (2.0 * k_prev + k_i) / 6.0
            slope = slope + half_dx * (k_prev + k_i)
            wij = wij + w_inc
            wt[j, i] = wij
            k_prev = k_i
    return wt


def solve_beam_contact(
    ski: BeamSki,
    load_n: float,
    load_position_m: float,
    *,
    flexibility: BeamFlexibility | None = None,
    max_iterations: int = 200,
    initial_contacts: np.ndarray | None = None,
    contact_compliance_m_per_n: float = 0.0,
) -> BeamResult:
    """Press a beam ski with a point load onto a rigid flat (unilateral contact, exact).

    Unknowns are the nodal reactions r ≥ 0 on the active (touching) set and the rigid motion
    ``a + b X``; force and moment equilibrium are imposed exactly as two equations, the gap is
    zero on the active set. Lawson–Hanson-type active set: add the deepest penetrating node of
    each penetrating run, step back when a reaction would become negative (finite, monotone).

    Parameters
    ----------
    ski : BeamSki
        Beam model: positions, EI(X) and unloaded camber c(X).
    load_n : float
        Point load F ≥ 0 [N], pointing down onto the flat.
    load_position_m : float
        x_F [m], strictly inside the ski.
    flexibility : BeamFlexibility, optional
        Precomputed flexibility of ``ski`` (saves ~0.1 s per call in loops).
    max_iterations : int
        Active-set updates before giving up (``converged=False``).
    initial_contacts : ndarray of int, optional
        Node indices to start the active set from (a warm start, e.g. the contacts of a nearby
        solve); used only when their reactions come out positive, else the default start. The
        contact problem has one solution, so the answer does not depend on the start.
    contact_compliance_m_per_n : float
        Compliance s ≥ 0 of each node's contact with the flat [m/N]: a touching node sinks by
        ``s·r`` (a stiff elastic foundation; 0 is the rigid flat of the device). The beam
        identification's continuation uses it to smooth the contact set's dependence on the
        camber (:mod:`solvers.beam_fit`); ``displacement_m`` then carries the sinking, and
        ``gap_m`` is 0 on the contact set.

    Returns
    -------
    BeamResult
    """
    return _solve_beam_contact(
        ski,
        load_n,
        load_position_m,
        flexibility,
        max_iterations,
        initial_contacts,
        contact_compliance_m_per_n,
        compiled=True,
    )


def _solve_beam_contact(
    ski: BeamSki,
    load_n: float,
    load_position_m: float,
    flexibility: BeamFlexibility | None,
    max_iterations: int,
    initial_contacts: np.ndarray | None,
    contact_compliance_m_per_n: float,
    *,
    compiled: bool,
) -> BeamResult:
    """:func:`solve_beam_contact`, with the compiled active-set loop or the reference one."""
    t0 = time.perf_counter()
    x, c = ski.positions_m, ski.unloaded_gap_m
    load_n = float(load_n)
    load_position_m = float(load_position_m)
    if not np.isfinite(load_n) or load_n < 0:
        raise InputError(f"load_n must be finite and >= 0, got {load_n!r}")
    if not np.isfinite(load_position_m) or not (x[0] < load_position_m < x[-1]):
        raise InputError(
            f"load_position_m must lie inside the ski ({x[0]:.4g} .. {x[-1]:.4g} m), "
            f"got {load_position_m!r}"
        )
    length = float(x[-1] - x[0])
    n = x.size
    c_min = float(c.min())
    if load_n == 0.0:
        contact = c <= c_min
        return BeamResult(
            positions_m=x,
            gap_m=c - c_min,
            reaction_n=np.zeros(n),
            displacement_m=np.zeros(n),
            contact=contact,
            load_n=0.0,
            load_position_m=load_position_m,
            force_residual=0.0,
            moment_residual=0.0,
            converged=True,
            iterations=0,
            residual=0.0,
            message="zero load: unloaded camber returned",
        )
    flex = flexibility if flexibility is not None else BeamFlexibility(ski)
    if flex.ski is not ski and flex.matrix.shape != (n, n):
        raise InputError("flexibility was built for a different ski")
    g_mat = flex.matrix
    g_load = -load_n * flex.load_column(load_position_m)
    rear = x <= load_position_m
    front = ~rear
    xs = x - load_position_m  # lever arms about the load
    scale_c = max(float(np.ptp(c)), 1e-9)
    tol_gap = 1e-10  # 0.1 nm: rounding of the dense solve, far below any measurable gap
    g_idx = np.arange(n)
    # start from the lowest node on each side of the load (lever rule gives positive reactions)
    idx0 = np.array([g_idx[rear][np.argmin(c[rear])], g_idx[front][np.argmin(c[front])]])
    warm = np.zeros(0, dtype=np.int64)
    if initial_contacts is not None:
        w = np.unique(np.asarray(initial_contacts, dtype=np.int64))
        w = w[(w >= 0) & (w < n)]
        if w.size >= 2 and rear[w].any() and front[w].any():
            warm = w
    args = (g_mat, c, xs, g_load, load_n, float(contact_compliance_m_per_n), idx0, warm)
    ok = False
    if compiled:
        idx, r_idx, a_rigid, b_rigid, z, it, converged, ok = _active_set_compiled(
            flex.columns, *args[1:], int(max_iterations), tol_gap
        )
    if not ok:  # reference loop: also when a KKT matrix is singular (least squares there)
        idx, r_idx, a_rigid, b_rigid, z, it, converged = _active_set_reference(
            *args, int(max_iterations), tol_gap
        )
    r = np.zeros(n)
    r[idx] = r_idx
    active = np.zeros(n, dtype=bool)
    active[idx] = True
    active |= np.abs(z) <= tol_gap
    # rigid + elastic displacement from the unloaded shape
    # columns of the active nodes: contiguous rows of flex.columns (cached by the compiled loop)
    elastic = r_idx @ flex.columns[idx] if compiled else g_mat[:, idx] @ r_idx
    u = a_rigid + b_rigid * xs + elastic + g_load
    gap = np.where(active, 0.0, np.maximum(z, 0.0))
    force_res = abs(float(r.sum()) - load_n) / load_n
    moment_res = abs(float(np.sum(r * xs))) / (load_n * length)
    residual = max(
        max(0.0, -float(z.min())) / scale_c,
        max(0.0, -float(r.min())) / load_n,
        force_res,
        moment_res,
    )
    if converged:
        message = f"converged in {it} active-set iterations"
    else:
        message = f"not converged: {it} iterations reached max_iterations"
    return BeamResult(
        positions_m=x,
        gap_m=gap,
        reaction_n=r,
        displacement_m=u,
        contact=active.copy(),
        load_n=load_n,
        load_position_m=load_position_m,
        force_residual=force_res,
        moment_residual=moment_res,
        converged=converged,
        iterations=it,
        residual=float(residual),
        message=message,
        solve_time_s=time.perf_counter() - t0,
    )


def _solve_beam_contact_reference(
    ski: BeamSki,
    load_n: float,
    load_position_m: float,
    *,
    flexibility: BeamFlexibility | None = None,
    max_iterations: int = 200,
    initial_contacts: np.ndarray | None = None,
    contact_compliance_m_per_n: float = 0.0,
) -> BeamResult:
    """:func:`solve_beam_contact` with the pure-numpy active-set loop (reference for tests)."""
    return _solve_beam_contact(
        ski,
        load_n,
        load_position_m,
        flexibility,
        max_iterations,
        initial_contacts,
        contact_compliance_m_per_n,
        compiled=False,
    )


def _kkt_system(g_mat, c, xs, g_load, load_n, compliance, idx):
    """The KKT matrix and right-hand side of the active set ``idx`` (reactions on it, rigid
    motion a, b; zero gap there, force and moment equilibrium), as the reference loop solves
    it; :func:`_kkt_solve` assembles the same system element by element."""
    m = idx.size
    kkt = np.zeros((m + 2, m + 2))
    kkt[:m, :m] = g_mat[np.ix_(idx, idx)]
    if compliance > 0.0:
        kkt[np.arange(m), np.arange(m)] += compliance
    kkt[:m, m] = 1.0
    kkt[:m, m + 1] = xs[idx]
    kkt[m, :m] = 1.0
    kkt[m + 1, :m] = xs[idx]
    rhs = np.concatenate([-c[idx] - g_load[idx], [load_n, 0.0]])
    return kkt, rhs


def _active_set_reference(
    g_mat: np.ndarray,
    c: np.ndarray,
    xs: np.ndarray,
    g_load: np.ndarray,
    load_n: float,
    compliance: float,
    idx0: np.ndarray,
    warm: np.ndarray,
    max_iterations: int,
    tol_gap: float,
) -> tuple[np.ndarray, np.ndarray, float, float, np.ndarray, int, bool]:
    """Lawson–Hanson-type active set on the reactions, pure numpy (the reference loop).

    Parameters are those of :func:`_active_set_compiled`. Returns the active nodes (sorted), their
    reactions [N], the rigid motion a [m] and b [-], the last gap z [m] (0 on the active set),
    the iteration count and whether no node penetrates."""
    n = c.size

    def solve_set(idx: np.ndarray) -> tuple[np.ndarray, float, float]:
        m = idx.size
        kkt, rhs = _kkt_system(g_mat, c, xs, g_load, load_n, compliance, idx)
        try:
            sol = np.linalg.solve(kkt, rhs)
        except np.linalg.LinAlgError:
            sol = np.linalg.lstsq(kkt, rhs, rcond=None)[0]
        return sol[:m], float(sol[m]), float(sol[m + 1])

    idx = idx0
    r_idx, a_rigid, b_rigid = solve_set(idx)
    if warm.size:
        r_w, a_w, b_w = solve_set(warm)
        if np.all(r_w > 0):
            idx, r_idx, a_rigid, b_rigid = warm, r_w, a_w, b_w
    converged = False
    it = 0
    z = c.copy()
    while it < max_iterations:
        it += 1
        z = c + a_rigid + b_rigid * xs + g_mat[:, idx] @ r_idx + g_load
        z[idx] = 0.0
        pen = z < -tol_gap
        if not pen.any():
            converged = True
            break
        # fast path: add the deepest node of each contiguous penetrating run at once
        edges = np.flatnonzero(np.diff(np.concatenate([[0], pen.astype(np.int8), [0]])))
        new = [
            s0 + int(np.argmin(z[s0:s1])) for s0, s1 in zip(edges[::2], edges[1::2], strict=True)
        ]
        cand = np.union1d(idx, new)
        r_c, a_c, b_c = solve_set(cand)
        if np.all(r_c > 0):
            idx, r_idx, a_rigid, b_rigid = cand, r_c, a_c, b_c
            continue
        # Lawson–Hanson step: add the single deepest node, step back while reactions go negative
        j = int(np.argmin(z))
        cand = np.union1d(idx, [j])
        r_old = np.zeros(n)
        r_old[idx] = r_idx
        stalled = False
        while True:
            r_c, a_c, b_c = solve_set(cand)
            if np.all(r_c > 0):
                break
            ro = r_old[cand]
            neg = r_c <= 0
            den = ro[neg] - r_c[neg]
            # a node entering with a zero reaction (0/0) cannot step: ratio 0
            ratios = np.divide(ro[neg], den, out=np.zeros_like(den), where=den > 0)
            block = cand[np.flatnonzero(neg)[np.argmin(ratios)]]
            if block == j and ratios.min() == 0.0:
                stalled = True
                break
            r_step = ro + ratios.min() * (r_c - ro)
            keep = (r_step > 0) & (cand != block)
            r_old = np.zeros(n)
            r_old[cand[keep]] = r_step[keep]
            cand = cand[keep]
        if stalled:
            break
        idx, r_idx, a_rigid, b_rigid = cand, r_c, a_c, b_c
    return idx, r_idx, a_rigid, b_rigid, z, it, converged


#: largest active set solved with numba's LAPACK (bit-identical to numpy's on the demo skis,
#: whose rigid-flat sets have ≤ 6 nodes); larger sets call numpy (object mode, ~60 µs a call)
_COMPILED_SOLVE_MAX_NODES = 8


def _numpy_kkt_solve(kkt, rhs):
    """``(solution, singular)`` of ``kkt @ x = rhs`` by numpy's LAPACK; ``(rhs, True)`` when the
    matrix is singular.

    Plain Python, called from the object-mode block of :func:`_kkt_solve`: a ``try`` written
    inside a ``numba.objmode`` block does not compile on Python 3.12 and 3.13 (numba 0.68:
    "POP_BLOCK peephole failed"), a call to a function that has one does.
    """
    try:
        return np.linalg.solve(kkt, rhs), False
    except np.linalg.LinAlgError:
        return rhs, True


@numba.njit(cache=True)
def _kkt_solve(g_mat, c, xs, g_load, load_n, compliance, idx):
    """Reactions [N] on the nodes ``idx`` and the rigid motion (a [m], b [-]) with zero gap there
    and force and moment equilibrium; ``ok`` False when the KKT matrix is singular."""
    m = idx.size
    kkt = np.zeros((m + 2, m + 2))
    rhs = np.zeros(m + 2)
    for p in range(m):
        ip = idx[p]
        for q in range(m):
            kkt[p, q] = g_mat[ip, idx[q]]
        if compliance > 0.0:
            kkt[p, p] += compliance
        kkt[p, m] = 1.0
        kkt[p, m + 1] = xs[ip]
        kkt[m, p] = 1.0
        kkt[m + 1, p] = xs[ip]
        rhs[p] = -c[ip] - g_load[ip]
    rhs[m] = load_n
    if m > _COMPILED_SOLVE_MAX_NODES:
        # numpy's LAPACK, as the reference loop: the LAPACK linked by numba rounds differently
        # on larger sets (1.9e-10 of the largest reaction at m = 150, cond(KKT) = 1.2e8)
        # no try/except in this block (Python 3.12+): the helper catches LinAlgError
        with numba.objmode(sol="float64[:]", singular="boolean"):
            sol, singular = _numpy_kkt_solve(kkt, rhs)
        if singular:
            return rhs[:m], 0.0, 0.0, False
    else:
        try:
            sol = np.linalg.solve(kkt, rhs)
        except Exception:
            return rhs[:m], 0.0, 0.0, False
    return sol[:m].copy(), sol[m], sol[m + 1], True


@numba.njit(cache=True)
def _insert_sorted(idx, new):
    """Sorted union of the sorted ``idx`` and the sorted ``new`` (disjoint from ``idx``)."""
    out = np.empty(idx.size + new.size, dtype=np.int64)
    a = b = 0
    for k in range(out.size):
        if b >= new.size or (a < idx.size and idx[a] < new[b]):
            out[k] = idx[a]
            a += 1
        else:
            out[k] = new[b]
            b += 1
    return out


@numba.njit(cache=True)
def _active_set_compiled(
    g_cols, c, xs, g_load, load_n, compliance, idx0, warm, max_iterations, tol_gap
):
    """The loop of :func:`_active_set_reference`, compiled: the same sets in the same order and
    the same KKT solves (LAPACK gesv), without numpy temporaries or Python overhead.

    Parameters
    ----------
    g_cols : ndarray (N, N)
        The flexibility's transpose, C-contiguous (:attr:`BeamFlexibility.columns`) [m/N]; the
        KKT systems read the flexibility as its transposed view (the same values;
        :class:`BeamFlexibility` keeps nothing else).
    c, xs, g_load : ndarray (N,)
        Unloaded gap [m], lever arms X − x_F [m], deflection under the load [m].
    load_n, compliance : float
        F [N] and the contact compliance [m/N].
    idx0, warm : ndarray of int64
        Sorted default start and sorted warm start (size 0: none).
    max_iterations : int
    tol_gap : float
        Penetration tolerance [m].

    Returns
    -------
    idx, r_idx, a, b, z, iterations, converged, ok
        As :func:`_active_set_reference`; ``ok`` False when a KKT matrix was singular (the caller
        then runs the reference loop, which falls back to least squares).
    """
    n = c.size
    g_mat = g_cols.T
    idx = idx0.copy()
    r_idx, a_rigid, b_rigid, ok = _kkt_solve(g_mat, c, xs, g_load, load_n, compliance, idx)
    if not ok:
        return idx, r_idx, a_rigid, b_rigid, c.copy(), 0, False, False
    if warm.size:
        r_w, a_w, b_w, ok = _kkt_solve(g_mat, c, xs, g_load, load_n, compliance, warm)
        if not ok:
            return idx, r_idx, a_rigid, b_rigid, c.copy(), 0, False, False
        if np.all(r_w > 0):
            idx, r_idx, a_rigid, b_rigid = warm.copy(), r_w, a_w, b_w
    converged = False
    it = 0
    z = c.copy()
    runs = np.empty(n, dtype=np.int64)
    gl = np.empty(n)
    while it < max_iterations:
        it += 1
        # z = c + a + b xs + G[:, idx] r + g_load, summed in numpy's order: each node's sum
        # over the active nodes k in their order, accumulated a column (a contiguous row of
        # g_cols) at a time (the same sums: reading a column per node was one cache line per
        # active node and node, most of a long contact's time)
        m = idx.size
        gl[:] = 0.0
        for k in range(m):
            row = g_cols[idx[k]]
            rk = r_idx[k]
            for i in range(n):
                gl[i] += row[i] * rk
        for i in range(n):
            z[i] = c[i] + a_rigid + b_rigid * xs[i] + gl[i] + g_load[i]
        for k in range(m):
            z[idx[k]] = 0.0
        any_pen = False
        jmin = 0
        nrun = 0
        i = 0
        while i < n:
            if z[i] < z[jmin]:
                jmin = i
            if z[i] < -tol_gap:
                any_pen = True
                best = i
                while i < n and z[i] < -tol_gap:
                    if z[i] < z[best]:
                        best = i
                    if z[i] < z[jmin]:
                        jmin = i
                    i += 1
                runs[nrun] = best
                nrun += 1
            else:
                i += 1
        if not any_pen:
            converged = True
            break
        # fast path: add the deepest node of each contiguous penetrating run at once
        cand = _insert_sorted(idx, runs[:nrun])
        r_c, a_c, b_c, ok = _kkt_solve(g_mat, c, xs, g_load, load_n, compliance, cand)
        if not ok:
            return idx, r_idx, a_rigid, b_rigid, z, it, False, False
        if np.all(r_c > 0):
            idx, r_idx, a_rigid, b_rigid = cand, r_c, a_c, b_c
            continue
        # Lawson–Hanson step: add the single deepest node, step back while reactions go negative
        j = jmin
        one = np.empty(1, dtype=np.int64)
        one[0] = j
        cand = _insert_sorted(idx, one)
        ro = np.zeros(cand.size)
        q = 0
        for k in range(cand.size):
            if q < idx.size and cand[k] == idx[q]:
                ro[k] = r_idx[q]
                q += 1
        stalled = False
        while True:
            r_c, a_c, b_c, ok = _kkt_solve(g_mat, c, xs, g_load, load_n, compliance, cand)
            if not ok:
                return idx, r_idx, a_rigid, b_rigid, z, it, False, False
            if np.all(r_c > 0):
                break
            # a node entering with a zero reaction (0/0) cannot step: ratio 0
            rmin = np.inf
            kblock = -1
            for k in range(cand.size):
                if r_c[k] <= 0:
                    den = ro[k] - r_c[k]
                    ratio = ro[k] / den if den > 0 else 0.0
                    if ratio < rmin:
                        rmin = ratio
                        kblock = k
            block = cand[kblock]
            if block == j and rmin == 0.0:
                stalled = True
                break
            nkeep = 0
            for k in range(cand.size):
                step = ro[k] + rmin * (r_c[k] - ro[k])
                if step > 0 and k != kblock:
                    cand[nkeep] = cand[k]
                    ro[nkeep] = step
                    nkeep += 1
            cand = cand[:nkeep].copy()
            ro = ro[:nkeep].copy()
        if stalled:
            break
        idx, r_idx, a_rigid, b_rigid = cand, r_c, a_c, b_c
    return idx, r_idx, a_rigid, b_rigid, z, it, converged, True


@dataclass(frozen=True)
class ClassicSkiDesign:
    """A few physically meaningful parameters that define a classic cross-country beam ski.

    The running surface between the tail and tip contact points has three parts: a straight rear
    glide zone, the camber pocket (kick zone, an arch of two half-cosines with zero slope at its
    ends and at its peak) and a straight front glide zone. Tail and tip shovels rise
    parabolically beyond the contact points. Positions are from the balance point, positive
    towards the tip [m].

    Attributes
    ----------
    tail_m, tip_m : float
        Ends of the ski [m] (length = tip_m − tail_m).
    tail_contact_m, tip_contact_m : float
        Where the tail and tip shovels leave the flat [m].
    pocket_m : tuple of float
        (start, end) of the camber pocket [m].
    camber_height_m : float
        Height of the pocket above the flat with no load [m].
    camber_peak_m : float
        Position of the pocket's highest point [m].
    tail_rise_m, tip_rise_m : float
        Rise of the tail and tip shovels at the ends [m].
    stiffness_nm2 : float
        Bending stiffness EI of the stiff kick zone (the pocket) [N·m²].
    end_stiffness_ratio : float
        EI at the ski ends over ``stiffness_nm2`` [-]; EI tapers (half-cosine) outside the pocket.
    """

    tail_m: float = -0.97
    tip_m: float = 1.03
    tail_contact_m: float = -0.90
    tip_contact_m: float = 0.80
    pocket_m: tuple[float, float] = (-0.35, 0.45)
    camber_height_m: float = 0.010
    camber_peak_m: float = 0.0
    pocket_height_m: float = 0.0
    tail_rise_m: float = 0.006
    tip_rise_m: float = 0.035
    stiffness_nm2: float = 1500.0
    end_stiffness_ratio: float = 0.15

    def __post_init__(self) -> None:
        p0, p1 = self.pocket_m
        order = (
            self.tail_m,
            self.tail_contact_m,
            p0,
            self.camber_peak_m,
            p1,
            self.tip_contact_m,
            self.tip_m,
        )
        if not all(a < b for a, b in itertools.pairwise(order)):
            raise InputError(
                "ClassicSkiDesign needs tail_m < tail_contact_m < pocket start < camber_peak_m < "
                f"pocket end < tip_contact_m < tip_m, got {order}"
            )
        for name in ("camber_height_m", "stiffness_nm2", "end_stiffness_ratio"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise InputError(f"{name} must be finite and > 0, got {v!r}")
        for name in ("tail_rise_m", "tip_rise_m"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise InputError(f"{name} must be finite and >= 0, got {v!r}")

    def build(self, spacing_m: float = 1e-3) -> BeamSki:
        """Sample the design on a uniform grid (tail to tip) of spacing ``spacing_m`` [m]."""
        if not np.isfinite(spacing_m) or spacing_m <= 0:
            raise InputError(f"spacing_m must be finite and > 0, got {spacing_m!r}")
        n = round((self.tip_m - self.tail_m) / spacing_m) + 1
        x = self.tail_m + spacing_m * np.arange(n)
        return BeamSki(x, self.stiffness(x), self.camber(x))

    def camber(self, x_m: np.ndarray) -> np.ndarray:
        """Unloaded gap c(X) [m]: first camber arch + kick-zone pocket + shovels."""
        x = np.asarray(x_m, dtype=float)
        c = np.zeros_like(x)
        xt, xp, xk = self.tail_contact_m, self.tip_contact_m, self.camber_peak_m
        h1 = self.camber_height_m
        rear = (x >= xt) & (x <= xk)
        front = (x > xk) & (x <= xp)
        c[rear] = h1 * (1 - ((xk - x[rear]) / (xk - xt)) ** 2)
        c[front] = h1 * (1 - ((x[front] - xk) / (xp - xk)) ** 2)
        p0, p1 = self.pocket_m
        pk = (x > p0) & (x < p1)
        c[pk] += self.pocket_height_m * np.sin(np.pi * (x[pk] - p0) / (p1 - p0)) ** 2
        tail = x < xt
        tip = x > xp
        c[tail] = self.tail_rise_m * ((xt - x[tail]) / (xt - self.tail_m)) ** 2
        c[tip] = self.tip_rise_m * ((x[tip] - xp) / (self.tip_m - xp)) ** 2
        return c

    def stiffness(self, x_m: np.ndarray) -> np.ndarray:
        """Bending stiffness EI(X) [N·m²]."""
        x = np.asarray(x_m, dtype=float)
        k0, k1 = self.pocket_m
        taper = np.ones_like(x)
        rear = x < k0
        front = x > k1
        s_r = np.clip((k0 - x[rear]) / (k0 - self.tail_m), 0, 1)
        s_f = np.clip((x[front] - k1) / (self.tip_m - k1), 0, 1)
        taper[rear] = 0.5 * (1 + np.cos(np.pi * s_r))
        taper[front] = 0.5 * (1 + np.cos(np.pi * s_f))
        ratio = self.end_stiffness_ratio
        return self.stiffness_nm2 * (ratio + (1 - ratio) * taper)


#: two designs unlike the demo skis (stable IDs for tests and studies): a short stiff pocket
#: ('stiff') and a long soft pocket with a forward camber peak ('soft')
OTHER_DESIGNS = {
    "stiff": ClassicSkiDesign(
        camber_height_m=0.0025,
        pocket_m=(-0.30, 0.35),
        pocket_height_m=6e-4,
        stiffness_nm2=2200.0,
        end_stiffness_ratio=0.2,
    ),
    "soft": ClassicSkiDesign(
        camber_height_m=0.0012,
        tail_contact_m=-0.85,
        tip_contact_m=0.75,
        pocket_m=(-0.45, 0.50),
        camber_peak_m=0.05,
        pocket_height_m=4e-4,
        stiffness_nm2=700.0,
        end_stiffness_ratio=0.35,
    ),
}


def flat_supports(x: np.ndarray, c: np.ndarray) -> tuple[int, int]:
    """The two nodes (i0 < i1) on which the unloaded camber ``c`` rests on the flat: the edge of
    its lower convex hull that spans the middle of the ski (:func:`camber_on_flat`).

    Compiled for float64 nodes (every evaluation of a forward fit calls it: 2-5 ms a call in
    Python at 2001 nodes); the same comparisons as :func:`_flat_supports_reference`."""
    x = np.asarray(x)
    c = np.asarray(c)
    if x.dtype == np.float64 and c.dtype == np.float64 and x.ndim == c.ndim == 1 and x.size >= 2:
        i0, i1 = _flat_supports_compiled(x, c)
        return int(i0), int(i1)
    return _flat_supports_reference(x, c)


@numba.njit(cache=True)
def _flat_supports_compiled(x, c):
    """:func:`_flat_supports_reference` compiled (the hull a stack of node indices)."""
    n = x.size
    hull = np.empty(n, dtype=np.int64)
    top = 0
    for i in range(n):
        while top >= 2:
            i0, i1 = hull[top - 2], hull[top - 1]
            cross = (x[i1] - x[i0]) * (c[i] - c[i0]) - (c[i1] - c[i0]) * (x[i] - x[i0])
            if cross <= 0:
                top -= 1
            else:
                break
        hull[top] = i
        top += 1
    mid = 0.5 * (x[0] + x[-1])
    i0, i1 = hull[0], hull[1]
    for k in range(top - 1):
        i0, i1 = hull[k], hull[k + 1]
        if x[i0] <= mid <= x[i1]:
            break
    return i0, i1


def _flat_supports_reference(x: np.ndarray, c: np.ndarray) -> tuple[int, int]:
    """:func:`flat_supports` in Python (the reference of the compiled form)."""
    hull: list[int] = []
    for i in range(x.size):
        while len(hull) >= 2:
            i0, i1 = hull[-2], hull[-1]
            cross = (x[i1] - x[i0]) * (c[i] - c[i0]) - (c[i1] - c[i0]) * (x[i] - x[i0])
            if cross <= 0:
                hull.pop()
            else:
                break
        hull.append(i)
    mid = 0.5 * (x[0] + x[-1])
    for i0, i1 in itertools.pairwise(hull):
        if x[i0] <= mid <= x[i1]:
            break
    return int(i0), int(i1)


def camber_on_flat(x: np.ndarray, c: np.ndarray) -> np.ndarray:
    """c minus the supporting line of its lower convex hull that spans the middle of the ski:
    ≥ 0, zero at two nodes (the unloaded ski resting on the flat). Only c's shape matters to the
    contact model; the line is a convention. It is also the device model of the unloaded case
    (F = 0): the ski rests on its two end contacts and nothing deflects."""
    i0, i1 = flat_supports(x, c)
    slope = (c[i1] - c[i0]) / (x[i1] - x[i0])
    return np.maximum(c - (c[i0] + slope * (x - x[i0])), 0.0)


def measure_camber(
    ski: BeamSki,
    loads_n: np.ndarray,
    load_positions_m: np.ndarray,
    *,
    noise_m: float = 3e-6,
    rng: np.random.Generator | int | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Virtual measuring device: loaded gaps over a grid of loads and load positions.

    Every (load, position) pair is one case; the gap is recorded at every beam node with
    independent Gaussian device noise (standard deviation ``noise_m``). Noise is not clipped, so a
    touching node may read a few µm below zero, as a real device does.

    Parameters
    ----------
    ski : BeamSki
        Beam model.
    loads_n : array_like (K1,)
        Loads F [N], > 0.
    load_positions_m : array_like (K2,)
        Load positions x_F [m].
    noise_m : float
        Device noise standard deviation [m], ≥ 0.
    rng : numpy.random.Generator or int
        Random generator or seed (required when ``noise_m > 0``).

    Returns
    -------
    cases_n, cases_m, gaps_m : ndarray
        Load of each case (K,) [N], load position (K,) [m], gaps (K, N) [m]; K = K1·K2,
        loads vary slowest.
    """
    loads = np.atleast_1d(np.asarray(loads_n, dtype=float))
    pos = np.atleast_1d(np.asarray(load_positions_m, dtype=float))
    if not np.isfinite(noise_m) or noise_m < 0:
        raise InputError(f"noise_m must be finite and >= 0, got {noise_m!r}")
    if noise_m > 0 and rng is None:
        raise InputError("rng (a numpy.random.Generator or a seed) is required when noise_m > 0")
    flex = BeamFlexibility(ski)
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    cases_n = np.repeat(loads, pos.size)
    cases_m = np.tile(pos, loads.size)
    gaps = np.empty((cases_n.size, ski.positions_m.size))
    for k, (f, xf) in enumerate(zip(cases_n, cases_m, strict=True)):
        res = solve_beam_contact(ski, f, xf, flexibility=flex)
        if not res.converged:
            raise InputError(f"beam solve failed for load {f} N at {xf} m: {res.message}")
        gaps[k] = res.gap_m
    if noise_m > 0:
        gaps = gaps + gen.normal(0.0, noise_m, size=gaps.shape)
    return cases_n, cases_m, gaps


def measure_unloaded(
    ski: BeamSki,
    *,
    noise_m: float = 3e-6,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Virtual measuring device, the unloaded case (F = 0) real devices record first.

    With no load the ski rests on the flat on its two unloaded contacts, so the gap is the camber
    on the flat (:func:`camber_on_flat` of ``ski.unloaded_gap_m``: ≥ 0, zero at
    the two supports of its lower hull; c itself when c is zero at two nodes, as on fine grids —
    a coarse sampling of a design may leave c a few µm above zero at its contacts), plus
    independent Gaussian device noise of standard deviation ``noise_m`` at every node (not
    clipped), drawn from ``rng`` as :func:`measure_camber` does. The same model as
    :func:`solvers.identify.predict_gaps` for a 0 N case.

    Returns
    -------
    gaps_m : ndarray (N,)
        Unloaded gap at every beam node [m].
    """
    if not np.isfinite(noise_m) or noise_m < 0:
        raise InputError(f"noise_m must be finite and >= 0, got {noise_m!r}")
    if noise_m > 0 and rng is None:
        raise InputError("rng (a numpy.random.Generator or a seed) is required when noise_m > 0")
    gaps = camber_on_flat(ski.positions_m, ski.unloaded_gap_m)
    if noise_m > 0:
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        gaps = gaps + gen.normal(0.0, noise_m, size=gaps.shape)
    return gaps
