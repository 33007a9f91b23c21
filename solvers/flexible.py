"""Macro scale with a ski that bends on the snow (docs/physics.md §4b).

Problem
-------
The ski is a free Euler–Bernoulli beam (:class:`solvers.beam.BeamSki`: bending stiffness EI(X),
unloaded camber c(X)), rigid across its width, loaded by the point load F at x_F (down) and by
the snow pressure P(X, Y) ≥ 0 (up). With the rigid approach δ and the tilt θ (positive: tip
down) the clearance is

    H(X, Y) = c(X) + w(X; P, F) + u(X, Y; P) − δ − θ (X − x_F) ≥ 0,   P ≥ 0,   P · H = 0,

with w the beam's *upward* deflection (docs/physics.md writes −w with w downward), known up to a
rigid motion that δ and θ carry, u the half-space displacement of :mod:`solvers.macro`,
``Σ P dA = F`` and ``Σ P (X − x_F) dA = 0``. With rigid snow (E' = ∞, u = 0) this is the measuring
device of :func:`solvers.beam.solve_beam_contact`.

Discretisation
--------------
The footprint grid is :func:`solvers.macro.extrude_profile`'s (the rigid solve's pixels). The
beam lives on the pixel-row centres X_i, EI and c interpolated linearly from the ski's own grid;
its loads are the row forces ``r_i = Σ_j P_ij dx dy`` and F, split linearly between the two rows
around x_F (force and moment about x_F exact). Its flexibility is the device's
(:class:`solvers.beam.BeamFlexibility` on the rows: M/EI piecewise linear, integrated exactly),
projected on self-equilibrated loads: ``B = Π G Π``, ``Π = I − R (RᵀR)⁻¹ Rᵀ``, ``R = [1, X]``.
For equilibrated loads ``B f = G f`` up to a rigid motion, so with u = 0 the model is the
device's discrete beam exactly. B is symmetric positive semi-definite up to the O(dx²)
asymmetry of that quadrature (7e-6 of its largest entry at 4 mm on the demo skis).

The operator on the pressure is ``A P = u(P) + B r(P)`` (beam term broadcast across the
width) with ``h0 = c − F B e_F``: ``H = h0 + A P − δ − θ (X − x_F)``. Half-space: the exact
zero-padded Love convolution of :class:`solvers.macro._LineOperator` (its FFT convention: real
FFT of length 2n along X, ``norm="backward"``, no q = 0 special case). The per-ski part (B, the
banded beam stiffness, the footprint) is a :class:`FlexibleModel` built once by
:func:`prepare_flexible` and reused for every load and modulus.

Solver
------
The Polonsky–Keer CG of the rigid solve stalls here: pressing one zone lifts another through
the beam, so its penetration-driven contact updates swing over hundreds of pixels (measured:
~2000 iterations on demo ski B at 200 MPa, even from a converged coarse solution). Instead:

1. Warm start **(choice)**: the same problem restricted to one pressure level per footprint
   row (the Galerkin row operator ``Eᵀ A E``: the snow's row-to-row coupling for each row's
   pixels plus ``dx dy n_i n_j B_ij``; precomputed per model at unit modulus), solved by the
   primal–dual active set below with dense KKT solves, first on blocks of ``_ROW_BLOCK`` rows
   from the lowest block on each side of the load, then on the rows (on groups of rows where
   the contact set holds more than ``_MAX_DENSE`` of them: soft snow). It places the contact
   zones within a row or two of the pixel answer (measured on the demo skis, 2–2000 MPa,
   10–90 kg: 3–5 pixel sets instead of 4–13 from the rigid-shape start) for 0.6–2.6 ms
   (demo skis at 40 kg, 2–2000 MPa, medians on a loaded 2-core machine; the updates run
   compiled, one LU with partial pivoting each, while the sets stay below ``_MAX_DENSE``).
   If a row-level KKT system is singular, the rigid-shape solve
   (:func:`solvers.macro.solve_macro`) of the device's loaded profile is the start. Dense
   solves stay below ~100 unknowns (``_MAX_DENSE``): multi-threaded LAPACK on a busy machine
   was measured 10–1000 × slower above that.
2. Primal–dual active set (Hintermüller, Ito & Kunisch, SIAM J. Optim. 13, 2002): on the set C
   of pixels in contact the clearance is zero (``A_CC P_C − δ − θ (X − x_F) = −h0_C`` with force
   and moment balance), elsewhere P = 0; the next C is ``{P > 0} ∪ {H < 0}``; when C repeats
   it is solved once more to ``tol`` and checked again (then P > 0 on C and H ≥ 0 off C: the
   discrete problem is solved). The first sets are solved loosely (``_LOOSE_TOL``). The set
   solve stops on an RMS over C while the update tests each pixel, so two sets that differ by
   a zone edge's pixels can send the update to each other (the added pixels keep P ≈ ±1e-13 Pa
   or the dropped ones penetrate by ~1–3 tol; measured on the own-ski study's designs, issue
   #26): when exact solves cycle, the sets are solved again with the CG's stop divided by 10,
   at most twice (``_TIGHTEST_SOLVE``), before the fall-back of step 4; ``message`` says so.
3. Each set is solved by projected preconditioned CG (the projection removes a least-squares
   fit a + b (X − x_F) on C, so every iterate keeps force and moment). Two-level
   preconditioner ``M = E A_c⁻¹ Eᵀ + (I − E D⁻¹ Eᵀ)/ρ``: exact on row-uniform pressures
   (``A_c`` the Galerkin row operator of step 1 on C's own pixels per row, one dense Cholesky
   of size "contact rows" per set, rows grouped beyond ``_MAX_DENSE_PRECONDITIONER``), the
   within-row remainder scaled by ρ (the snow's compliance to a uniform pressure on C). It
   carries the snow's long-range coupling along the ski, which a scalar snow term does not:
   4–8 CG iterations per set at 1e-4 where a banded-beam preconditioner with scalar snow
   needed 12–15. The iterations touch only C's
   pixels (the convolution box is zero elsewhere; the beam acts on C's rows); A P on all
   pixels is formed once per set, for the set update.

   Compiled (numba, ``cache=True``): the vector work of a CG step (update, projections,
   the preconditioner's row sums and two triangular solves), A_CC's beam term, the set's row
   operators (pixel pairs counted per pattern pair and offset across the width, then one
   sum per pair of rows or, when fewer, per row offset and pattern pair), the clearance fit
   and the row-level active set; the FFTs stay pocketfft (:func:`solvers.macro.line_convolution`).
   Kept on the model: the kernel transforms of the convolution windows at unit modulus and
   B's columns (``FlexibleModel.window_couplings``, ``compliance_columns``).

   Cost, measured on the demo skis at the papers' case (default grid, medians of 15 solves
   each, the median of the per-pair flexible/rigid ratios, rigid and flexible solves
   alternated in one process, loaded 2-core machine, four runs; ``scripts/flexible_speed.py``):
   4 sets and 27–29 CG iterations, 0.99–1.15 × the rigid solve (1.7–2.5 × in the same runs
   before the compiled kernels and caches; previously 9–11 sets and 70–107 iterations from
   the rigid-shape start, 4.6–5.6 ×). Over 2–2000 MPa, 10–90 kg, −300…+100 mm: 3–6 sets,
   21–47 iterations, 0.6–1.15 × the rigid solve, except ski-a at 2 MPa (47 iterations, 6
   sets over ~330 contact rows): 1.85–2.3 × (was 3.5–3.7 ×). The floor is the
   convolutions: ~30 per solve (one per CG iteration plus one per set, on a window over the
   contact rows, and one over the footprint per set) against the rigid solve's ~25.
4. On stiff snow (E' ≳ 5 GPa, beyond real snow) the primal–dual sets can wander; after
   ``_MAX_PDAS_UPDATES`` (or a cycle the tightened solves do not break) the solve switches to
   a monotone Lawson–Hanson active set (the algorithm of
   :func:`solvers.beam.solve_beam_contact`: add the deepest penetration of each run, step back
   when a pressure would turn negative), started from the device's contacts. ``message`` says
   when that happened. It grows the set by a row or a pixel per step: on contact sets of
   ~1000 pixels it spends the iteration budget first (measured on the cycles of issue #26
   before the tightened solves: ~100 steps, 3000 CG iterations, residual 1e-3) and the answer
   says it did not converge.

Rigid snow (``effective_modulus_pa = inf``): one unknown per footprint row (the row force),
the Lawson–Hanson loop with dense KKT solves from the lowest row on each side of the load; each
row's force is spread uniformly over its footprint pixels (across the width the pressure is not
unique when u = 0).

Units: SI throughout (m, N, Pa, N·m²).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numba
import numpy as np
import scipy.linalg

from . import macro
from .beam import BeamFlexibility, BeamSki, solve_beam_contact
from .elastic import love_rectangle_influence
from .errors import InputError, NotConvergedError

__all__ = ["FlexibleModel", "prepare_flexible", "solve_flexible"]

#: relative CG tolerance of the primal-dual steps before the set settles: coarse for the first
#: _COARSE_UPDATES sets, then finer (choice, measured on the demo skis: coarse solves alone make
#: the set wander on stiff snow); the last set is always solved to ``tol``
_LOOSE_TOL = (1e-2, 1e-4)
_COARSE_UPDATES = 3
#: primal-dual active-set updates before the switch to Lawson-Hanson
_MAX_PDAS_UPDATES = 40
#: Lawson-Hanson steps (each adds or drops at least one unknown)
_MAX_LH_STEPS = 2000
#: CG iterations per active set
_MAX_CG = 400
#: a free pixel penetrates when H < −_PEN_TOL · tol · (largest displacement): below the
#: accuracy the CG solves are asked for, so rounding does not enter the contact set
_PEN_TOL = 0.5
#: the tightest CG stop (relative to ``tol``) the primal-dual sets are re-solved with when
#: exact solves cycle (choice): the stop is an RMS over the set, ``tol / 4``, so one pixel's
#: clearance may be off by up to ~√(set size) · tol / 4 (8 tol on 1000 pixels), more than the
#: set tests resolve (0.5 tol): two sets that differ by a pixel can each send the update to the
#: other (measured on the study designs with perturbed beams, issue #26). Each cycle divides the
#: stop by 10, down to this
_TIGHTEST_SOLVE = 1e-2
#: pixel rows per block of the coarse row problem that starts the row-level solve (choice)
_ROW_BLOCK = 8
#: largest dense factorisation (unknowns) of the row start and the row preconditioner; larger
#: problems are aggregated over consecutive rows (choice: LAPACK switches to threads above
#: ~100–200 unknowns, which on a busy machine cost 10–1000 × the single-threaded time)
_MAX_DENSE = 96
#: the same for the Cholesky of the row preconditioner
_MAX_DENSE_PRECONDITIONER = 96
#: primal-dual updates of each row-level problem
_MAX_ROW_UPDATES = 60
#: window lengths whose kernel transform a FlexibleModel keeps (~0.13 MB each at 256 × 8)
_WINDOW_CACHE = 32
_WINDOW_LOCK = threading.Lock()


def _equilibrated_flexibility(ski: BeamSki) -> tuple[BeamFlexibility, np.ndarray]:
    """Device flexibility G of ``ski`` and ``B = Π G Π`` on its nodes [m/N]."""
    flex = BeamFlexibility(ski)
    q = _rigid_basis(ski.positions_m)
    # a C-contiguous copy: the products below round as they did when the matrix was stored
    g = np.ascontiguousarray(flex.matrix)
    gp = g - (g @ q) @ q.T  # G Π
    return flex, gp - q @ (q.T @ gp)  # Π G Π


def _rigid_basis(x: np.ndarray) -> np.ndarray:
    """Orthonormal basis (n, 2) of the rigid motions span{1, X}."""
    xc = (x - x.mean()) / max(float(np.ptp(x)), 1e-300)
    q, _ = np.linalg.qr(np.stack([np.ones_like(xc), xc], axis=1))
    return q


@numba.njit(cache=True)
def _row_coupling(kernel: np.ndarray, rows: np.ndarray, patterns: np.ndarray) -> np.ndarray:
    """Galerkin snow coupling ``χ_iᵀ K(X_i − X_j) χ_j`` of rows with pixel patterns χ [m/Pa].

    ``kernel`` (nx, ny): displacement at row/column offsets under a unit pixel pressure;
    ``rows`` (m,) row indices; ``patterns`` (m, ny) bool, the row's pixels. The pixel pairs of
    each pair of distinct patterns (few: full rows, rows narrowed by the sidecut, partial rows
    at zone edges) are counted by their offset |j − j'| across the width
    (:func:`_pattern_pairs`), then each pair of rows sums the kernel at its row offset against
    those counts (``ny`` products per pair of rows). Compiled.
    """
    pid, pairs = _pattern_pairs(patterns)
    table = _pair_table(kernel, rows, pairs)
    m = rows.size
    out = np.empty((m, m))
    for i in range(m):
        for j in range(i, m):
            s = _pair_sum(kernel, table, abs(rows[i] - rows[j]), pairs, pid[i], pid[j])
            out[i, j] = s
            out[j, i] = s
    return out


@numba.njit(cache=True)
def _pair_table(kernel, rows, pairs):
    """``table[o, a, b] = Σ_l kernel[o, l] pairs[a, b, l]`` for the row offsets o the rows span,
    when that is fewer sums than one per pair of rows (few patterns, many rows: soft snow);
    else an empty table (sum per pair)."""
    m = rows.size
    npat, ny = pairs.shape[1], pairs.shape[2]
    span = 0
    for i in range(m):
        span = max(span, abs(rows[i] - rows[0]))
    for i in range(m):
        span = max(span, abs(rows[i] - rows[m - 1]))
    if (span + 1) * npat * npat >= m * (m + 1) // 2:
        return np.empty((0, npat, npat))
    table = np.empty((span + 1, npat, npat))
    for o in range(span + 1):
        for a in range(npat):
            for b in range(npat):
                s = 0.0
                for k in range(ny):
                    s += kernel[o, k] * pairs[a, b, k]
                table[o, a, b] = s
    return table


@numba.njit(cache=True, inline="always")
def _pair_sum(kernel, table, o, pairs, a, b):
    """``Σ_l kernel[o, l] pairs[a, b, l]``, from ``table`` when it holds it (same sum)."""
    if table.shape[0] > 0:
        return table[o, a, b]
    s = 0.0
    for k in range(kernel.shape[1]):
        s += kernel[o, k] * pairs[a, b, k]
    return s


@numba.njit(cache=True)
def _pattern_pairs(patterns):
    """Distinct rows of ``patterns`` (m, ny) bool: (pattern id of each row, pixel pairs
    ``pairs[a, b, l]`` of patterns a, b at offset l = |j − j'| across the width)."""
    m, ny = patterns.shape
    uniq = np.empty((m, ny), dtype=np.bool_)
    pid = np.empty(m, dtype=np.int64)
    npat = 0
    for i in range(m):
        found = -1
        for a in range(npat):
            same = True
            for j in range(ny):
                if uniq[a, j] != patterns[i, j]:
                    same = False
                    break
            if same:
                found = a
                break
        if found < 0:
            uniq[npat] = patterns[i]
            found = npat
            npat += 1
        pid[i] = found
    pairs = np.zeros((npat, npat, ny))
    for a in range(npat):
        for b in range(npat):
            for j in range(ny):
                if uniq[a, j]:
                    for jj in range(ny):
                        if uniq[b, jj]:
                            pairs[a, b, abs(j - jj)] += 1.0
    return pid, pairs


@numba.njit(cache=True)
def _set_operator(kernel, b, area, rows, patterns, counts, g):
    """The row operators of a contact set (see :class:`_Preconditioner`).

    Returns (beam (m, m) = ``area · B[rows][:, rows]`` [m/Pa]; the Galerkin row operator
    ``χ_iᵀ K χ_j + counts_i counts_j beam_ij`` summed over groups of g consecutive rows,
    symmetrised ((m/g), (m/g)) [m/Pa]; the sum of its snow part [m/Pa])."""
    snow = _row_coupling(kernel, rows, patterns)
    m = rows.size
    mg = (m + g - 1) // g
    beam = np.empty((m, m))
    for i in range(m):
        for j in range(m):
            beam[i, j] = area * b[rows[i], rows[j]]
    grp = np.arange(m) // g
    ac = np.zeros((mg, mg))
    snow_sum = 0.0
    for i in range(m):
        gi = grp[i]
        for j in range(i, m):
            s = snow[i, j]
            cc = counts[i] * counts[j]
            gj = grp[j]
            if i == j:
                snow_sum += s
                ac[gi, gi] += s + cc * beam[i, i]
            else:
                snow_sum += 2.0 * s
                v = 2.0 * s + cc * (beam[i, j] + beam[j, i])
                if gi == gj:
                    ac[gi, gi] += v
                else:  # symmetrised: half of each ordered pair on either side
                    ac[gi, gj] += 0.5 * v
                    ac[gj, gi] += 0.5 * v
    return beam, ac, snow_sum


@numba.njit(cache=True)
def _set_rows(cidx, ny):
    """Rows of a contact set: pixel indices ``cidx`` (sorted) on a grid ``ny`` wide →
    (rows with contact, row (0 … m−1) of each pixel, each row's pixel pattern (m, ny) bool,
    pixels per row)."""
    m = 0
    last = -1
    for i in range(cidx.size):
        r = cidx[i] // ny
        if r != last:
            m += 1
            last = r
    urows = np.empty(m, dtype=np.int64)
    local = np.empty(cidx.size, dtype=np.int64)
    pat = np.zeros((m, ny), dtype=np.bool_)
    counts = np.zeros(m)
    k = -1
    last = -1
    for i in range(cidx.size):
        r = cidx[i] // ny
        if r != last:
            k += 1
            urows[k] = r
            last = r
        local[i] = k
        pat[k, cidx[i] - r * ny] = True
        counts[k] += 1.0
    return urows, local, pat, counts


@dataclass(frozen=True, eq=False)
class FlexibleModel:
    """A beam ski on one footprint grid: what every flexible solve of this ski reuses.

    Build with :func:`prepare_flexible`; keep it (per ski and grid) and pass it to
    :func:`solve_flexible` for every load, load position and modulus. Compared and hashed by
    identity (a cache key that stays valid as long as the model is kept).

    Attributes
    ----------
    ski : BeamSki
        The beam model on its own grid.
    unloaded_map : GapMap
        Unloaded camber c(X) on the footprint [m] (NaN outside), on exactly the pixels of
        :func:`solvers.macro.extrude_profile` for the same width and pixel parameters.
    row_beam : BeamSki
        The beam on the pixel-row centres (EI and c interpolated linearly from ``ski``).
    row_flexibility : BeamFlexibility
        Device flexibility G of ``row_beam`` [m/N].
    compliance_m_per_n : ndarray (nx, nx)
        ``B = Π G Π``: upward deflection at row i per upward force at row j, exact up to a rigid
        motion for self-equilibrated row forces [m/N].
    snow_kernel_rows : ndarray (nx, ny)
        Love's influence at unit modulus, ``E' · u`` at row offset i and column offset j
        under a unit pressure on one pixel [m] (divide by E' [Pa] for [m/Pa]).
    footprint_rows : ndarray (nr,)
        Indices of the pixel rows with footprint pixels.
    row_pixels : ndarray (nr,)
        Footprint pixels per such row [-].
    row_snow_unit : ndarray (nr, nr)
        Galerkin row operator of the snow at unit modulus: ``Σ_{pixels of i, of j} E' u`` for
        a unit pressure on every footprint pixel of row j, summed over row i [m].
    row_beam_nn : ndarray (nr, nr)
        ``n_i n_j B_ij`` on the footprint rows [m/N] (times dx dy: the beam's Galerkin row
        operator on row-uniform pressures [m/Pa]).
    block_snow_unit, block_beam_nn : ndarray (nb, nb)
        The same two summed over blocks of ``row_block`` footprint rows (the coarse start).
    row_block : int
        Footprint rows per coarse block: ``_ROW_BLOCK``, or more so that nb ≤ ``_MAX_DENSE``.
    compliance_columns : ndarray (nx, nx)
        ``Bᵀ``, contiguous: row j is B's column j (the beam deflection under a force on row j)
        [m/N]; derived from ``compliance_m_per_n`` when not given.
    window_couplings : dict
        Kernel transforms of the convolution windows at unit modulus, per window length, filled
        by the solves (a cache: at most ``_WINDOW_CACHE`` entries, each independent of load,
        position and modulus).
    """

    ski: BeamSki = field(repr=False)
    unloaded_map: macro.GapMap = field(repr=False)
    row_beam: BeamSki = field(repr=False)
    row_flexibility: BeamFlexibility = field(repr=False)
    compliance_m_per_n: np.ndarray = field(repr=False)
    snow_kernel_rows: np.ndarray = field(repr=False)
    footprint_rows: np.ndarray = field(repr=False)
    row_pixels: np.ndarray = field(repr=False)
    row_snow_unit: np.ndarray = field(repr=False)
    row_beam_nn: np.ndarray = field(repr=False)
    block_snow_unit: np.ndarray = field(repr=False)
    block_beam_nn: np.ndarray = field(repr=False)
    row_block: int = 1
    compliance_columns: np.ndarray = field(repr=False, default=None)
    window_couplings: dict = field(repr=False, default_factory=dict)

    def __post_init__(self) -> None:
        if self.compliance_columns is None:
            object.__setattr__(
                self, "compliance_columns", np.ascontiguousarray(self.compliance_m_per_n.T)
            )

    @property
    def positions_m(self) -> np.ndarray:
        """Pixel-row centres X [m]."""
        return self.unloaded_map.positions_m


def prepare_flexible(
    ski: BeamSki,
    width_m: float | np.ndarray,
    *,
    pixel_along_m: float = macro.DEFAULT_PIXEL_ALONG_M,
    pixels_across: int = macro.DEFAULT_PIXEL_ACROSS,
    width_positions_m: np.ndarray | None = None,
    like: FlexibleModel | None = None,
) -> FlexibleModel:
    """Footprint grid and beam compliance of a ski for :func:`solve_flexible` (keep per ski).

    Parameters
    ----------
    ski : BeamSki
        Beam model: positions, EI(X) > 0 and unloaded camber c(X) ≥ 0.
    width_m : float or ndarray
        Ski width [m], constant, or sampled at ``width_positions_m``.
    pixel_along_m : float
        Pixel length dx along the ski [m].
    pixels_across : int
        Number of pixels across the maximum width [-].
    width_positions_m : ndarray, optional
        Positions [m] of a width profile given in ``width_m``.
    like : FlexibleModel, optional
        A model of another beam of the same ski outline (plausible beams drawn about an
        identified one): where its footprint is this one's, pixel for pixel, its snow parts,
        which depend on the footprint alone (``snow_kernel_rows``, ``row_snow_unit``,
        ``block_snow_unit`` and the ``window_couplings`` cache, shared), are taken instead of
        computed again (the same arrays: the results are bit for bit those without it); any
        other footprint is computed afresh.

    Returns
    -------
    FlexibleModel
        Build cost ~30 ms at 4 mm on a 2 m ski (a few (nx, nx) products and the row
        operators of the start and the preconditioner; measured on a loaded machine).
    """
    if not isinstance(ski, BeamSki):
        raise InputError(f"ski must be a solvers.beam.BeamSki, got {type(ski).__name__}")
    unloaded = macro.extrude_profile(
        ski.positions_m,
        ski.unloaded_gap_m,
        width_m,
        pixel_along_m=pixel_along_m,
        pixels_across=pixels_across,
        width_positions_m=width_positions_m,
    )
    rows = unloaded.positions_m
    if rows.size < 5:
        raise InputError(
            f"pixel_along_m {pixel_along_m} leaves {rows.size} pixel rows along the ski; the "
            "beam needs at least 5"
        )
    x = ski.positions_m
    row_beam = BeamSki(
        rows,
        np.interp(rows, x, ski.bending_stiffness_nm2),
        np.interp(rows, x, ski.unloaded_gap_m),
    )
    flex, b = _equilibrated_flexibility(row_beam)
    dx, dy = unloaded.pixel_size_m
    nx, ny = unloaded.gap_m.shape
    inside = np.isfinite(unloaded.gap_m)
    row_in = np.flatnonzero(inside.any(axis=1))
    pat = inside[row_in]
    n = pat.sum(axis=1).astype(float)
    row_nn = n[:, None] * n[None, :] * b[np.ix_(row_in, row_in)]
    kb = max(_ROW_BLOCK, -(-row_in.size // _MAX_DENSE))
    if _same_footprint(like, unloaded, inside):
        kern, row_snow, block_snow = like.snow_kernel_rows, like.row_snow_unit, like.block_snow_unit
        windows = like.window_couplings
    else:
        kern = (2.0 / np.pi) * love_rectangle_influence(
            np.arange(nx)[:, None] * dx, np.arange(ny)[None, :] * dy, dx / 2, dy / 2
        )
        row_snow = _row_coupling(kern, row_in, pat)
        block_snow, windows = _block_sum(row_snow, kb), {}
    return FlexibleModel(
        ski,
        unloaded,
        row_beam,
        flex,
        b,
        kern,
        row_in,
        n,
        row_snow,
        row_nn,
        block_snow,
        _block_sum(row_nn, kb),
        kb,
        window_couplings=windows,
    )


def _same_footprint(like: FlexibleModel | None, unloaded: macro.GapMap, inside) -> bool:
    """Whether ``like`` was prepared on this footprint: the same pixel rows and size and the
    same pixels inside (then its snow parts are this model's)."""
    if like is None:
        return False
    if not isinstance(like, FlexibleModel):
        raise InputError(f"like must be a FlexibleModel, got {type(like).__name__}")
    m = like.unloaded_map
    return bool(
        m.gap_m.shape == unloaded.gap_m.shape
        and m.pixel_size_m == unloaded.pixel_size_m
        and np.array_equal(m.positions_m, unloaded.positions_m)
        and np.array_equal(np.isfinite(m.gap_m), inside)
    )


def _load_split(rows_m: np.ndarray, load_position_m: float) -> tuple[int, float]:
    """Row i and weight t: F goes (1 − t) to row i and t to row i + 1 (force, moment exact)."""
    dx = float(rows_m[1] - rows_m[0])
    s = (load_position_m - rows_m[0]) / dx
    i = min(max(int(np.floor(s)), 0), rows_m.size - 2)
    return i, float(s - i)


class _WindowHalfSpace:
    """:class:`solvers.macro._LineOperator` on the first n rows, from a kernel table (internal).

    ``coupling`` (n + 1, ny, ny) [m/Pa]: the kernel transform of :func:`_window_coupling`
    (real FFT of length 2n along X, the kernel even in X, row n zero, dense coupling across
    the width per wavenumber).
    """

    def __init__(self, coupling: np.ndarray, n: int) -> None:
        self.n, self.ny, self.padded = n, coupling.shape[1], 2 * n
        self.coupling = coupling

    def displacement(self, pressure_pa: np.ndarray) -> np.ndarray:
        return macro.line_convolution(pressure_pa, self.coupling, self.n)


def _window_coupling(model: FlexibleModel, n: int) -> np.ndarray:
    """Kernel transform (n + 1, ny, ny) of an n-row window at unit modulus [m] (divide by E'),
    kept on the model (at most ``_WINDOW_CACHE`` window lengths; the oldest goes first)."""
    cache = model.window_couplings
    coupling = cache.get(n)
    if coupling is None:
        kernel = model.snow_kernel_rows
        ny = kernel.shape[1]
        kern = np.zeros((2 * n, ny))
        kern[:n] = kernel[:n]
        kern[n + 1 :] = kernel[n - 1 : 0 : -1]
        kh = scipy.fft.rfft(kern, axis=0).real
        j = np.arange(ny)
        coupling = np.ascontiguousarray(kh[:, np.abs(j[:, None] - j[None, :])])
        coupling.flags.writeable = False
        with _WINDOW_LOCK:  # solves of one model may run in several threads
            while len(cache) >= _WINDOW_CACHE:
                cache.pop(next(iter(cache)))
            cache[n] = coupling
    return coupling


class _Pixels:
    """The flexible problem on the footprint pixels, as compressed vectors (internal).

    ``apply(P)`` is ``A P`` [m] for pixel pressures P [Pa]; ``h0`` [m], ``xs = X − x_F`` [m]
    and ``rows`` (row of each pixel) are per pixel.
    """

    def __init__(
        self, model: FlexibleModel, inside: np.ndarray, f: float, xf: float, e_eff: float
    ) -> None:
        gmap = model.unloaded_map
        x = gmap.positions_m
        dx, dy = gmap.pixel_size_m
        nx, ny = inside.shape
        self.nx, self.ny, self.area = nx, ny, dx * dy
        self.n_box = macro._fast_rows(nx)
        self.hs = macro._halfspace((self.n_box, ny), dx, dy, e_eff)
        self.model = model
        self.b = model.compliance_m_per_n
        self.bt = model.compliance_columns
        i, t = _load_split(x, xf)
        #: beam deflection under the load alone, −F B e_F [m] (rows)
        self.load_deflection = -f * ((1.0 - t) * self.b[:, i] + t * self.b[:, i + 1])
        self.idx = np.flatnonzero(inside)
        self.rows = self.idx // ny
        self.xs = x[self.rows] - xf
        self.h0 = (model.row_beam.unloaded_gap_m + self.load_deflection)[self.rows]
        self.total = f / self.area  # Σ P over pixels [Pa]
        self.box = np.zeros((self.n_box, ny))
        self.flat = self.box.reshape(-1)
        self.u_load = self.load_deflection[self.rows]
        self.kernel_rows = model.snow_kernel_rows / e_eff
        self.windows: dict[int, _WindowHalfSpace] = {}
        self.fast_rows: dict[int, int] = {}
        self.e_eff = e_eff
        self.xr = x - xf
        self.h0_rows = model.row_beam.unloaded_gap_m + self.load_deflection

    def solve(self, contact, p_start, rel_tol, tol):
        """Zero clearance on C with balance (see :func:`_cg_on_set`)."""
        return _cg_on_set(self, contact, p_start, rel_tol, tol, _MAX_CG)

    def window(self, cidx: np.ndarray) -> tuple:
        """Half-space operator, zeroed box and box positions of pixels ``cidx`` on the rows
        they span (padded to a fast FFT length; exact there: zero-padded, linear convolution).
        Operators are kept per window length for this solve."""
        i0 = int(self.rows[cidx[0]])
        span = int(self.rows[cidx[-1]]) - i0 + 1
        n = self.fast_rows.get(span)
        if n is None:
            n = self.fast_rows[span] = macro._fast_rows(span)
        if n >= self.n_box:
            self.box[:] = 0.0
            return self.hs, self.box, self.idx[cidx]
        hs = self.windows.get(n)
        if hs is None:
            coupling = _window_coupling(self.model, n) / self.e_eff
            hs = self.windows[n] = _WindowHalfSpace(coupling, n)
        box = np.zeros((n, self.ny))
        return hs, box, self.idx[cidx] - i0 * self.ny

    def row_sum(self, v: np.ndarray) -> np.ndarray:
        return np.bincount(self.rows, weights=v, minlength=self.nx)

    def snow(self, v: np.ndarray) -> np.ndarray:
        """Half-space displacement [m] at the pixels under pixel pressures v [Pa]."""
        self.box[:] = 0.0
        self.flat[self.idx] = v
        return self.hs.displacement(self.box).reshape(-1)[self.idx]

    def beam(self, row_force_n: np.ndarray) -> np.ndarray:
        """Upward beam deflection at the rows [m] under upward row forces [N]."""
        return self.b @ row_force_n

    def apply(self, v: np.ndarray) -> np.ndarray:
        return self.snow(v) + self.beam(self.row_sum(v) * self.area)[self.rows]

    def apply_set(
        self, v: np.ndarray, vc: np.ndarray, local: np.ndarray, urows: np.ndarray
    ) -> np.ndarray:
        """``apply(v)`` for v zero off a set C: ``vc`` its values on C, ``local`` the row of C
        (0 … m−1) of each, ``urows`` (m,) those rows (the beam term uses B's m columns only)."""
        return self.snow(v) + _beam_columns(self.bt, urows, local, vc, self.area)[self.rows]


@numba.njit(cache=True)
def _beam_columns(bt, cols, local, v, area):
    """``B[:, cols] f`` from ``bt = Bᵀ`` (contiguous columns), with the row forces
    ``f_k = area · Σ_{local = k} v`` [m]."""
    f = np.zeros(cols.size)
    for i in range(v.size):
        f[local[i]] += v[i]
    out = np.zeros(bt.shape[1])
    for k in range(cols.size):
        fk = area * f[k]
        c = cols[k]
        for i in range(bt.shape[1]):
            out[i] += bt[c, i] * fk
    return out


class _Preconditioner:
    """Two-level ``M = E A_c⁻¹ Eᵀ + (I − E D⁻¹ Eᵀ)/ρ`` on a contact set C.

    E spreads a level per contact row over that row's pixels of C (D = EᵀE: pixels per row);
    ``A_c = Eᵀ A E`` is the exact Galerkin row operator: the snow's row-to-row coupling
    ``χ_iᵀ K(X_i − X_j) χ_j`` (χ_i the row's pixels in C by their grid column;
    :func:`_row_coupling`) plus the beam ``dx dy n_i n_j B_ij``, formed in one compiled pass
    (:func:`_set_operator`); one dense Cholesky per
    set (size: contact rows; beyond ``_MAX_DENSE_PRECONDITIONER`` rows, on soft snow, one
    level per group of consecutive contact rows). The within-row remainder is scaled by ρ, the
    snow's mean compliance on C. Vectors live on C only.
    """

    def __init__(self, pix: _Pixels, cidx: np.ndarray) -> None:
        urows, local, pat, counts = _set_rows(pix.idx[cidx], pix.ny)
        m = urows.size
        g = max(1, -(-m // _MAX_DENSE_PRECONDITIONER))
        # beam: deflection at row i per unit pressure on row j's pixels of C (dx dy B_ij)
        # [m/Pa]; ac: the Galerkin row operator, per group of g consecutive contact rows when
        # there are many (soft snow)
        self.beam, ac, snow_sum = _set_operator(
            pix.kernel_rows, pix.b, pix.area, urows, pat, counts, g
        )
        #: ρ: the snow's mean displacement under a unit pressure on C [m/Pa]
        self.rho = snow_sum / cidx.size
        #: row of C (0 … m−1) of each pixel, for the beam term of A_CC
        self.row_local = local
        #: the rows of C (grid row indices)
        self.rows = urows
        if g > 1:
            counts, local, m = _block_sum(counts, g), local // g, -(-m // g)
        self.factor, info = scipy.linalg.lapack.dpotrf(ac, lower=0)
        if info != 0:  # rounding on a near-singular beam: shift it slightly
            ac[np.diag_indices(m)] += 1e-12 * float(np.abs(ac.diagonal()).max())
            self.factor, info = scipy.linalg.lapack.dpotrf(ac, lower=0)
            if info != 0:
                raise NotConvergedError(
                    f"the row preconditioner is not positive definite (dpotrf info {info})"
                )
        self.local, self.m = local, m
        self.inv_counts = 1.0 / counts

    def __call__(self, v: np.ndarray) -> np.ndarray:
        out = np.empty_like(v)
        _precondition(v, self.local, self.factor, self.inv_counts, self.rho, out)
        return out


@numba.njit(cache=True)
def _precondition(v, local, factor, inv_counts, rho, out):
    """out = M v: row sums s of v, c = A_c⁻¹ s by the Cholesky factor U (upper, A_c = UᵀU,
    two triangular solves), then ``(v − s/n)/ρ + c`` per pixel of its row (group)."""
    m = factor.shape[0]
    s = np.zeros(m)
    for i in range(v.size):
        s[local[i]] += v[i]
    c = np.empty(m)
    for i in range(m):  # Uᵀ y = s
        acc = s[i]
        for k in range(i):
            acc -= factor[k, i] * c[k]
        c[i] = acc / factor[i, i]
    for i in range(m - 1, -1, -1):  # U c = y
        acc = c[i]
        for k in range(i + 1, m):
            acc -= factor[i, k] * c[k]
        c[i] = acc / factor[i, i]
    for i in range(v.size):
        g = local[i]
        out[i] = (v[i] - s[g] * inv_counts[g]) / rho + c[g]


@numba.njit(cache=True)
def _project(v, q0, q1):
    """v ← v − q (qᵀ v) in place, q = [q0, q1] orthonormal (removes the fit a + b xs)."""
    a = 0.0
    b = 0.0
    for i in range(v.size):
        a += q0[i] * v[i]
        b += q1[i] * v[i]
    for i in range(v.size):
        v[i] -= a * q0[i] + b * q1[i]


@numba.njit(cache=True)
def _snow_plus_beam(snow, pos, v, local, beam, out):
    """out = snow[pos] + (beam · row sums of v)[row]: A_CC v from the convolution's output."""
    m = beam.shape[0]
    s = np.zeros(m)
    for i in range(v.size):
        s[local[i]] += v[i]
    w = _matvec(beam, s)
    for i in range(v.size):
        out[i] = snow[pos[i]] + w[local[i]]


@numba.njit(cache=True)
def _matvec(a, x):
    """``a @ x`` with four running sums per row (one sum is bound by the latency of its
    additions: measured 4 × slower at 336 rows); single-threaded, unlike BLAS."""
    m, n = a.shape
    out = np.empty(m)
    n4 = n - n % 4
    for i in range(m):
        s0 = s1 = s2 = s3 = 0.0
        for k in range(0, n4, 4):
            s0 += a[i, k] * x[k]
            s1 += a[i, k + 1] * x[k + 1]
            s2 += a[i, k + 2] * x[k + 2]
            s3 += a[i, k + 3] * x[k + 3]
        for k in range(n4, n):
            s0 += a[i, k] * x[k]
        out[i] = (s0 + s1) + (s2 + s3)
    return out


@numba.njit(cache=True)
def _dot(a, b):
    s = 0.0
    for i in range(a.size):
        s += a[i] * b[i]
    return s


@numba.njit(cache=True)
def _cg_step(p, r, d, adc, z, q0, q1, local, factor, inv_counts, rho, rz):
    """One projected preconditioned CG step after ``adc = A_CC d``, in place on p, r, z, d.

    Returns (r·z new, |r| new); (nan, nan) when dᵀ A d ≤ 0 (nothing updated)."""
    den = _dot(d, adc)
    if not den > 0.0:
        return np.nan, np.nan
    alpha = rz / den
    for i in range(p.size):
        p[i] += alpha * d[i]
    _project(adc, q0, q1)
    for i in range(p.size):
        r[i] -= alpha * adc[i]
    _precondition(r, local, factor, inv_counts, rho, z)
    _project(z, q0, q1)
    rz_new = _dot(r, z)
    beta = rz_new / rz
    for i in range(p.size):
        d[i] = z[i] + beta * d[i]
    return rz_new, np.sqrt(_dot(r, r))


def _cg_on_set(
    pix: _Pixels,
    contact: np.ndarray,
    p_start: np.ndarray,
    rel_tol: float,
    tol: float,
    max_iterations: int,
) -> tuple[np.ndarray, np.ndarray, int] | None:
    """Zero clearance on C with force and moment balance: projected preconditioned CG.

    Returns (P, A P, iterations) on all pixels, or None if C lies on one row (no moment
    balance). The start is ``p_start`` on C plus the a + b xs that restores ``Σ P = total``,
    ``Σ P xs = 0``; the projection removes a least-squares fit a + b xs on C from residuals and
    preconditioned residuals, so every iterate keeps both. Stops when the projected residual
    (the clearance on C with δ, θ fitted) has dropped by ``rel_tol``, or when its RMS is below
    ``tol / 4`` of the largest elastic displacement on C (the final test of :func:`_residual`
    takes it over all pixels). Iterations touch only C's pixels (the vector work of a step
    compiled: :func:`_cg_step`); A P on all pixels is evaluated once at the end.
    """
    cidx = np.flatnonzero(contact)
    xc = pix.xs[cidx]
    if cidx.size < 2 or np.ptp(xc) <= 0:
        return None
    # orthonormal basis of span{1, xs} on C (Gram–Schmidt; xs is centred first)
    q0 = np.full(cidx.size, 1.0 / np.sqrt(cidx.size))
    q1 = xc - xc.mean()
    q1 /= np.sqrt(q1 @ q1)

    precond = _Preconditioner(pix, cidx)
    local, b_c = precond.row_local, precond.beam
    pl, factor, inv_counts, rho = precond.local, precond.factor, precond.inv_counts, precond.rho
    hs, box, pos = pix.window(cidx)  # the convolution over C's rows only
    flat = box.reshape(-1)

    def apply_c(v: np.ndarray, out: np.ndarray) -> np.ndarray:
        """A_CC v [m]: the box stays zero off C, so only C's pixels are written and read."""
        flat[pos] = v
        _snow_plus_beam(hs.displacement(box).reshape(-1), pos, v, local, b_c, out)
        return out

    p = np.array(p_start[cidx], dtype=float) if p_start is not None else np.zeros(cidx.size)
    # a + b xs that restores Σ P = total and Σ P xs = 0 (2 × 2 normal equations)
    s0, s1, s2 = float(cidx.size), float(xc.sum()), float(xc @ xc)
    r0_, r1_ = pix.total - p.sum(), -float(p @ xc)
    det = s0 * s2 - s1 * s1
    p += (s2 * r0_ - s1 * r1_) / det + (s0 * r1_ - s1 * r0_) / det * xc
    uc = apply_c(p, np.empty(cidx.size))
    # the scale over C only: at most the largest displacement of _residual, so never looser
    abs_tol = 0.25 * tol * float(np.max(np.abs(uc + pix.u_load[cidx]))) * np.sqrt(cidx.size)
    r = -(pix.h0[cidx] + uc)
    _project(r, q0, q1)
    r0 = float(np.sqrt(r @ r))
    z = precond(r)
    _project(z, q0, q1)
    d = z.copy()
    rz = float(r @ z)
    adc = np.empty(cidx.size)
    its = 0
    rn = r0
    while its < max_iterations:
        if rn <= rel_tol * r0 or rn <= abs_tol or not rz > 0:
            break
        its += 1
        apply_c(d, adc)
        rz, rn = _cg_step(p, r, d, adc, z, q0, q1, pl, factor, inv_counts, rho, rz)
        if np.isnan(rn):
            break
    full = np.zeros(pix.xs.size)
    full[cidx] = p
    u = pix.apply_set(full, p, local, precond.rows)  # all pixels, for the set update
    return full, u, its


@dataclass
class _ActiveSetSolve:
    pressure: np.ndarray  # unknowns (pixel pressures [Pa] or row forces [N])
    clearance: np.ndarray  # H [m] per unknown, 0 on contact
    delta: float
    theta: float
    iterations: int  # CG iterations (operator applications)
    set_updates: int
    residual: float
    converged: bool
    note: str


def _residual(h: np.ndarray, contact: np.ndarray, u_ref: float) -> float:
    """macro's residual: (RMS H on contact + RMS penetration off contact) / u_ref."""
    nc = max(int(contact.sum()), 1)
    hc, pen = h[contact], np.minimum(h[~contact], 0.0)
    return float((np.sqrt(hc @ hc / nc) + np.sqrt(pen @ pen / nc)) / max(u_ref, 1e-30))


class _Rows:
    """Rigid snow: one unknown per footprint row, the row force [N]; dense KKT per set."""

    def __init__(self, model: FlexibleModel, row_in: np.ndarray, f: float, xf: float) -> None:
        x = model.positions_m
        b = model.compliance_m_per_n
        i, t = _load_split(x, xf)
        self.load_deflection = -f * ((1.0 - t) * b[:, i] + t * b[:, i + 1])
        self.idx = np.flatnonzero(row_in)
        self.rows = np.arange(self.idx.size)  # each unknown is its own "row"
        self.b = b[np.ix_(self.idx, self.idx)]
        self.xs = x[self.idx] - xf
        self.h0 = (model.row_beam.unloaded_gap_m + self.load_deflection)[self.idx]
        self.total = f
        self.u_load = self.load_deflection[self.idx]

    def apply(self, r: np.ndarray) -> np.ndarray:
        return self.b @ r

    def solve(self, contact, p_start, rel_tol, tol):
        idx = np.flatnonzero(contact)
        m = idx.size
        if m < 2 or np.ptp(self.xs[idx]) <= 0:
            return None
        kkt = np.zeros((m + 2, m + 2))
        kkt[:m, :m] = self.b[np.ix_(idx, idx)]
        kkt[:m, m] = -1.0
        kkt[:m, m + 1] = -self.xs[idx]
        kkt[m, :m] = 1.0
        kkt[m + 1, :m] = self.xs[idx]
        rhs = np.concatenate([-self.h0[idx], [self.total, 0.0]])
        try:
            sol = np.linalg.solve(kkt, rhs)
        except np.linalg.LinAlgError:
            sol = np.linalg.lstsq(kkt, rhs, rcond=None)[0]
        r = np.zeros(self.xs.size)
        r[idx] = sol[:m]
        return r, self.b[:, idx] @ sol[:m], 0


def _clearance(prob, contact: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, float, float]:
    """H for every unknown with δ, θ fitted (least squares) on C; returns (H, δ, θ)."""
    h = np.empty(u.size)
    delta, theta = _fit_clearance(prob.h0, u, prob.xs, contact, h)
    return h, delta, theta


@numba.njit(cache=True)
def _fit_clearance(h0, u, xs, contact, h):
    """h = h0 + u − δ − θ xs with (δ, θ) the least-squares fit of h0 + u on the contact set
    (about the set's mean xs, so no cancellation); returns (δ, θ)."""
    n = 0
    sx = 0.0
    sg = 0.0
    for i in range(u.size):
        if contact[i]:
            n += 1
            sx += xs[i]
            sg += h0[i] + u[i]
    xm = sx / n
    gm = sg / n
    sxx = 0.0
    sxg = 0.0
    for i in range(u.size):
        if contact[i]:
            d = xs[i] - xm
            sxx += d * d
            sxg += d * (h0[i] + u[i] - gm)
    theta = sxg / sxx if sxx > 0.0 else 0.0
    delta = gm - theta * xm
    for i in range(u.size):
        h[i] = h0[i] + u[i] - delta - theta * xs[i]
    return delta, theta


def _u_ref(prob, u: np.ndarray) -> float:
    """Largest elastic displacement (snow plus beam under P and F) [m]."""
    return float(np.max(np.abs(u + prob.u_load)))


def _runs_deepest(prob, pen: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Penetrating unknowns of the deepest row in each run of rows that penetrate."""
    rows_pen = np.zeros(int(prob.rows.max()) + 1, dtype=bool)
    rows_pen[prob.rows[pen]] = True
    deepest = np.full(rows_pen.size, np.inf)
    np.minimum.at(deepest, prob.rows[pen], h[pen])
    edges = np.flatnonzero(np.diff(np.concatenate([[0], rows_pen.astype(np.int8), [0]])))
    chosen = np.zeros(rows_pen.size, dtype=bool)
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        chosen[a + int(np.argmin(deepest[a:b]))] = True
    return pen & chosen[prob.rows]


def _primal_dual(prob, p, contact, tol, budget):
    """Primal–dual active set: C ← {P > 0} ∪ {H < 0}; loose solves until the set settles.

    Returns (solve or None, p, contact, its, updates, note); None when it cycles or runs out
    of updates (the caller continues with :func:`_lawson_hanson`).
    """
    seen = {np.packbits(contact).tobytes()}
    its = 0
    loose = True
    solve_tol = tol  # the CG's stop (tightened when exact solves cycle)
    for update in range(1, _MAX_PDAS_UPDATES + 1):
        rel = _LOOSE_TOL[update > _COARSE_UPDATES] if loose else 0.0
        sol = prob.solve(contact, p, rel, solve_tol)
        if sol is None:
            return None, p, contact, its, update, "set cannot balance the moment"
        p, u, k = sol
        its += k
        h, delta, theta = _clearance(prob, contact, u)
        u_ref = _u_ref(prob, u)
        new = np.where(contact, p > 0, h < -_PEN_TOL * tol * u_ref)
        if np.array_equal(new, contact):
            if not loose:
                res = _residual(h, contact, u_ref)
                h = np.where(contact, 0.0, np.maximum(h, 0.0))
                note = "" if solve_tol == tol else f"set solves tightened to {solve_tol:.2g}"
                out = _ActiveSetSolve(p, h, delta, theta, its, update, res, res < tol, note)
                return out, p, contact, its, update, ""
            loose = False  # the set has settled: solve it to tol and check it again
            continue
        key = np.packbits(new).tobytes()
        if key in seen:
            if not loose:
                if solve_tol <= _TIGHTEST_SOLVE * tol:
                    return None, p, contact, its, update, "primal-dual active set cycled"
                # the sets differ by less than the solves resolve pixel by pixel: solve this
                # set again, tighter
                solve_tol *= 0.1
                seen = {np.packbits(contact).tobytes()}
                continue
            loose = False  # a cycle of loose solves: decide with exact ones from now on
            seen = set()
        seen.add(key)
        contact = new
        if its >= budget:
            break
    return None, p, contact, its, update, "primal-dual active set did not settle"


def _block_sum(v: np.ndarray, k: int, square: bool = True) -> np.ndarray:
    """Sums over consecutive blocks of k entries along the first axis, and along the second
    too if ``square`` (the last block padded with zeros)."""
    if v.ndim == 1:
        return v.copy() if k == 1 else np.add.reduceat(v, np.arange(0, v.size, k))
    nb = -(-v.shape[0] // k)
    pad = nb * k - v.shape[0]
    if not square:
        return np.pad(v, ((0, pad), (0, 0))).reshape(nb, k, -1).sum(axis=1)
    return np.pad(v, ((0, pad), (0, pad))).reshape(nb, k, nb, k).sum(axis=(1, 3))


def _kkt_solve(a, n, mx, hsum, total):
    """[s, δ, θ] of ``a s − n δ − mx θ = −hsum``, ``nᵀ s = total``, ``mxᵀ s = 0``.

    Up to ``_MAX_DENSE`` unknowns: one LU of the KKT system. Beyond (soft snow), where a
    threaded LU is slow: a is symmetric positive semi-definite (nearly singular when the beam
    dominates: its rigid motions), so it is augmented by ``Cᵀ Γ C`` (C = [n, mx]ᵀ, Γ
    diagonal, scaled to a's diagonal), which leaves s unchanged and shifts the multipliers by
    Γ C s = Γ [total, 0]; then one Cholesky and the 2 × 2 Schur complement of the balance; the
    LU if that Cholesky fails. None if singular.
    """
    k = n.size
    c = np.stack([n, mx])  # (2, k)

    def lu() -> np.ndarray | None:
        kkt = np.zeros((k + 2, k + 2))
        kkt[:k, :k] = a
        kkt[:k, k:] = -c.T
        kkt[k:, :k] = c
        rhs = np.empty(k + 2)
        rhs[:k] = -hsum
        rhs[k:] = total, 0.0
        # LAPACK's dgesv directly (numpy.linalg.solve's checks cost more than these solves)
        x, info = scipy.linalg.lapack.dgesv(kkt, rhs)[2:]
        return x if info == 0 and np.all(np.isfinite(x)) else None

    if k + 2 <= _MAX_DENSE:  # small: one LU of the KKT system is cheapest
        return lu()
    scale = float(np.mean(a.diagonal()))
    gamma = scale / np.maximum(np.mean(c * c, axis=1), 1e-300)
    factor, info = scipy.linalg.lapack.dpotrf(a + (c.T * gamma) @ c, lower=0)
    if info != 0:  # not numerically definite
        return lu()
    y = scipy.linalg.lapack.dpotrs(factor, np.stack([n, mx, hsum], axis=1), lower=0)[0]
    try:
        lam = np.linalg.solve(c @ y[:, :2], [total + n @ y[:, 2], mx @ y[:, 2]])
    except np.linalg.LinAlgError:
        return None
    out = np.empty(k + 2)
    out[:k] = y[:, :2] @ lam - y[:, 2]
    out[k:] = lam - gamma * np.array([total, 0.0])
    return out


def _row_pdas(op, n, mx, hsum, total, act):
    """Primal–dual active set on row levels s [Pa] (a uniform pressure on each row's pixels).

    ``op = (snow, beam, e_eff, area, g)``: the Galerkin operator Eᵀ A E [m/Pa] is
    ``snow / e_eff + area · beam`` summed over groups of g consecutive rows (only its block on
    the current set and the response to the current levels are ever formed:
    :func:`_group_block`, :func:`_group_response`); n the pixels per row (group), mx =
    Σ (X − x_F) and hsum = Σ h0 over each row's pixels [m], ``total`` = Σ P [Pa]; dense KKT
    solves (force and moment balance; a set that loses one side of the load gets back its most
    penetrating row there). Returns (s, contact rows, updates), or None if a KKT system is
    singular.

    The updates run compiled (:func:`_row_pdas_dense`, one LU of the KKT system each) while the
    sets have at most ``_MAX_DENSE`` − 2 rows; a larger set continues here with
    :func:`_kkt_solve`'s Cholesky route (soft snow).
    """
    snow, beam, e_eff, area, g = op
    status, s_rows, act, first, hist = _row_pdas_dense(
        snow, beam, e_eff, area, g, n, mx, hsum, total, act, _MAX_ROW_UPDATES, _MAX_DENSE
    )
    if status == 0:
        return s_rows, act, first
    if status == 1:
        return None
    seen = {h.tobytes() for h in hist}
    sides = [np.flatnonzero(mx < 0), np.flatnonzero(mx > 0)]
    for update in range(first, _MAX_ROW_UPDATES + 1):
        idx = np.flatnonzero(act)
        k = idx.size
        sol = _kkt_solve(
            _group_block(snow, beam, e_eff, area, g, idx), n[idx], mx[idx], hsum[idx], total
        )
        if sol is None:
            return None
        s_rows = np.zeros(n.size)
        s_rows[idx] = sol[:k]
        gap = _group_response(snow, beam, e_eff, area, g, n.size, idx, sol[:k])
        gap += hsum - n * sol[k] - mx * sol[k + 1]
        new = np.where(act, s_rows > 0, gap < 0)
        for cand in sides:  # keep a row on each side of the load (moment balance)
            if cand.size and not new[cand].any():
                new[cand[np.argmin(gap[cand])]] = True
        key = new.tobytes()
        if np.array_equal(new, act) or key in seen:
            return s_rows, act, update
        seen.add(key)
        act = new
    return s_rows, act, _MAX_ROW_UPDATES


@numba.njit(cache=True)
def _row_pdas_dense(snow, beam, e_eff, area, g, n, mx, hsum, total, act, max_updates, max_dense):
    """The updates of :func:`_row_pdas` while its KKT systems have at most ``max_dense``
    unknowns (one LU with partial pivoting each: :func:`_lu_solve`).

    Returns (status, s, act, update, sets seen): status 0 done, 1 singular KKT system, 2 the
    set of ``update`` is too large (continue from ``act``).
    """
    nn = n.size
    hist = np.zeros((max_updates, nn), dtype=np.bool_)
    nh = 0
    s_rows = np.zeros(nn)
    act = act.copy()
    for update in range(1, max_updates + 1):
        idx = np.flatnonzero(act)
        k = idx.size
        if k + 2 > max_dense:
            return 2, s_rows, act, update, hist[:nh]
        kkt = np.zeros((k + 2, k + 2))
        kkt[:k, :k] = _group_block(snow, beam, e_eff, area, g, idx)
        rhs = np.empty(k + 2)
        for a in range(k):
            i = idx[a]
            kkt[a, k] = -n[i]
            kkt[a, k + 1] = -mx[i]
            kkt[k, a] = n[i]
            kkt[k + 1, a] = mx[i]
            rhs[a] = -hsum[i]
        rhs[k] = total
        rhs[k + 1] = 0.0
        if not _lu_solve(kkt, rhs):
            return 1, s_rows, act, update, hist[:nh]
        s_rows = np.zeros(nn)
        for a in range(k):
            s_rows[idx[a]] = rhs[a]
        gap = _group_response(snow, beam, e_eff, area, g, nn, idx, rhs[:k])
        new = np.empty(nn, dtype=np.bool_)
        for i in range(nn):
            gap[i] += hsum[i] - n[i] * rhs[k] - mx[i] * rhs[k + 1]
            new[i] = s_rows[i] > 0.0 if act[i] else gap[i] < 0.0
        for side in (-1.0, 1.0):  # keep a row on each side of the load (moment balance)
            best = -1
            for i in range(nn):
                if mx[i] * side > 0.0:
                    if new[i]:
                        best = -2
                        break
                    if best == -1 or gap[i] < gap[best]:
                        best = i
            if best >= 0:
                new[best] = True
        if np.array_equal(new, act):
            return 0, s_rows, act, update, hist[:nh]
        for h in range(nh):
            if np.array_equal(hist[h], new):
                return 0, s_rows, act, update, hist[:nh]
        hist[nh] = new
        nh += 1
        act = new
    return 0, s_rows, act, max_updates, hist[:nh]


@numba.njit(cache=True)
def _lu_solve(a, b):
    """Solve a x = b in place (x in b, a overwritten): LU with partial pivoting, as LAPACK's
    dgesv. False when a pivot is exactly zero or the solution is not finite (singular)."""
    k = b.size
    for c in range(k):
        p = c
        for i in range(c + 1, k):
            if abs(a[i, c]) > abs(a[p, c]):
                p = i
        if a[p, c] == 0.0:
            return False
        if p != c:
            for j in range(k):
                a[c, j], a[p, j] = a[p, j], a[c, j]
            b[c], b[p] = b[p], b[c]
        inv = 1.0 / a[c, c]
        for i in range(c + 1, k):
            f = a[i, c] * inv
            if f != 0.0:
                for j in range(c + 1, k):
                    a[i, j] -= f * a[c, j]
                b[i] -= f * b[c]
    for c in range(k - 1, -1, -1):
        s = b[c]
        for j in range(c + 1, k):
            s -= a[c, j] * b[j]
        b[c] = s / a[c, c]
    for c in range(k):
        if not np.isfinite(b[c]):
            return False
    return True


@numba.njit(cache=True)
def _group_block(snow, beam, e_eff, area, g, idx):
    """``A[idx][:, idx]`` of ``A = snow / e_eff + area · beam`` summed over groups of g rows."""
    nr = snow.shape[0]
    k = idx.size
    out = np.empty((k, k))
    for a in range(k):
        i0 = idx[a] * g
        for b in range(k):
            j0 = idx[b] * g
            ss = 0.0
            sb = 0.0
            for i in range(i0, min(i0 + g, nr)):
                for j in range(j0, min(j0 + g, nr)):
                    ss += snow[i, j]
                    sb += beam[i, j]
            out[a, b] = ss / e_eff + area * sb
    return out


@numba.njit(cache=True)
def _group_response(snow, beam, e_eff, area, g, ng, idx, s):
    """``A[:, idx] @ s`` (ng,) of the grouped operator of :func:`_group_block`."""
    nr = snow.shape[0]
    cols = np.empty(idx.size * g, dtype=np.int64)  # the rows of the groups idx, and their level
    lev = np.empty(idx.size * g)
    nc = 0
    for b in range(idx.size):
        for j in range(idx[b] * g, min(idx[b] * g + g, nr)):
            cols[nc] = j
            lev[nc] = s[b]
            nc += 1
    out = np.zeros(ng)
    for i in range(nr):
        ss = 0.0
        sb = 0.0
        for c in range(nc):
            ss += snow[i, cols[c]] * lev[c]
            sb += beam[i, cols[c]] * lev[c]
        out[i // g] += ss / e_eff + area * sb
    return out


def _row_start(pix: _Pixels, model: FlexibleModel) -> np.ndarray | None:
    """Warm start [Pa] per pixel: the problem with one pressure level per footprint row.

    The Galerkin restriction of the pixel problem to row-uniform pressures (snow:
    ``FlexibleModel.row_snow_unit / E'``, beam: ``dx dy · row_beam_nn``) is solved by the
    primal–dual active set with dense KKT solves, first on blocks of ``_ROW_BLOCK`` rows (from
    the lowest block on each side of the load), then on the rows from the blocks' contact set.
    None when either level cannot balance the moment.
    """
    row_in = model.footprint_rows
    n = model.row_pixels
    xr = pix.xr[row_in]
    h0 = pix.h0_rows[row_in]
    k = model.row_block
    n_b, mx_b, h_b = (_block_sum(v, k) for v in (n, n * xr, n * h0))
    x_b = mx_b / np.maximum(n_b, 1.0)
    h_mean = h_b / np.maximum(n_b, 1.0)
    act = np.zeros(n_b.size, dtype=bool)
    for side in (x_b <= 0, x_b > 0):
        act[np.flatnonzero(side)[np.argmin(h_mean[side])]] = True
    block_op = (model.block_snow_unit, model.block_beam_nn, pix.e_eff, pix.area, 1)
    coarse = _row_pdas(block_op, n_b, mx_b, h_b, pix.total, act)
    if coarse is None:
        return None
    act_rows = np.repeat(coarse[1], k)[: row_in.size]
    s_rows = np.repeat(coarse[0], k)[: row_in.size]
    # then on groups of g rows, g as small as keeps the dense solves below _MAX_DENSE
    g = max(1, -(-int(act_rows.sum()) // _MAX_DENSE))
    if g < k:
        nr = row_in.size
        n_g, mx_g, h_g = (_block_sum(v, g) for v in (n, n * xr, n * h0))
        act_g = _block_sum(act_rows.astype(float), g) > 0
        row_op = (model.row_snow_unit, model.row_beam_nn, pix.e_eff, pix.area, g)
        fine = _row_pdas(row_op, n_g, mx_g, h_g, pix.total, act_g)
        if fine is None:
            return None
        s_rows = np.repeat(fine[0], g)[:nr]
    level = np.zeros(pix.nx)
    level[row_in] = np.maximum(s_rows, 0.0)
    return level[pix.rows]


def _lawson_hanson(prob, p, contact, tol, budget):
    """Monotone active set from a feasible balanced P (Lawson–Hanson, as solve_beam_contact).

    Try adding the deepest penetrating row of each penetrating run at once; if that leaves a
    negative pressure, add the single deepest unknown instead and, whenever a pressure would
    turn negative, step back along the segment to the first zero and drop it. Every set is
    solved to ``tol``.
    """
    its = 0
    steps = 0
    note = ""
    sol = prob.solve(contact, p, 0.0, tol)
    while sol is not None and its <= budget and steps < _MAX_LH_STEPS:
        steps += 1
        p_n, u_n, k = sol
        its += k
        neg = contact & (p_n <= 0)
        if neg.any():  # step back to the first zero, drop it
            ratios = p[neg] / (p[neg] - p_n[neg])
            alpha = float(ratios.min())
            if not alpha > 0:
                note = "stalled: the deepest penetrating unknown comes out without pressure"
                break
            p = np.where(contact, p + alpha * (p_n - p), 0.0)
            contact = contact & (p > 0)
            contact[np.flatnonzero(neg)[np.argmin(ratios)]] = False
            p = np.where(contact, p, 0.0)
            sol = prob.solve(contact, p, 0.0, tol)
            continue
        p = p_n
        h, delta, theta = _clearance(prob, contact, u_n)
        u_ref = _u_ref(prob, u_n)
        pen = ~contact & (h < -_PEN_TOL * tol * u_ref)
        if not pen.any():
            res = _residual(h, contact, u_ref)
            h = np.where(contact, 0.0, np.maximum(h, 0.0))
            return _ActiveSetSolve(p, h, delta, theta, its, steps, res, res < tol, "")
        block = contact | _runs_deepest(prob, pen, h)
        sol = prob.solve(block, p, 0.0, tol)
        if sol is not None and np.all(sol[0][block] > 0):
            contact = block
            continue
        if sol is not None:
            its += sol[2]
        single = contact.copy()
        single[np.flatnonzero(pen)[np.argmin(h[pen])]] = True
        contact = single
        sol = prob.solve(contact, p, 0.0, tol)
    if sol is None:
        note = note or "set cannot balance the moment"
    elif not note:
        note = "iteration budget spent"
    p = np.where(contact, np.maximum(p, 0.0), 0.0)
    u = prob.apply(p)
    h, delta, theta = _clearance(prob, contact, u)
    u_ref = _u_ref(prob, u)
    res = _residual(h, contact, u_ref)
    h = np.where(contact, 0.0, np.maximum(h, 0.0))
    return _ActiveSetSolve(p, h, delta, theta, its, steps, res, False, note)


def _lowest_rows_start(prob) -> np.ndarray:
    """Balanced P ≥ 0 on the lowest row (least h0) on each side of the load (lever rule)."""
    rear, front = np.flatnonzero(prob.xs <= 0), np.flatnonzero(prob.xs > 0)
    r_row = prob.rows[rear[np.argmin(prob.h0[rear])]]
    f_row = prob.rows[front[np.argmin(prob.h0[front])]]
    p = np.zeros(prob.xs.size)
    x_r = float(prob.xs[prob.rows == r_row][0])
    x_f = float(prob.xs[prob.rows == f_row][0])
    for row, share in ((r_row, x_f / (x_f - x_r)), (f_row, -x_r / (x_f - x_r))):
        sel = prob.rows == row
        p[sel] = share * prob.total / np.count_nonzero(sel)
    return p


def _active_set(prob, p0: np.ndarray, tol: float, max_iterations: int, pdas: bool, lh_start=None):
    """Primal–dual active set (fast), then Lawson–Hanson (monotone) if it does not settle.

    ``lh_start()``, if given, returns the feasible balanced start of the monotone phase (else
    the lowest row on each side of the load).
    """
    contact = p0 > 0
    if not (np.any(prob.xs[contact] < 0) and np.any(prob.xs[contact] > 0)):
        contact = np.ones(prob.xs.size, dtype=bool)
        p0 = np.ones(prob.xs.size)
    p, its, updates, note = p0, 0, 0, ""
    if pdas:
        out, p, contact, its, updates, note = _primal_dual(prob, p0, contact, tol, max_iterations)
        if out is not None:
            return out
        # the monotone phase starts from a small set (stiff snow: the device's contacts) and
        # grows it; the primal-dual sets were too wide, and dropping one unknown per step is slow
        p = lh_start() if lh_start is not None else None
        if p is None:
            p = _lowest_rows_start(prob)
        contact = p > 0
    out = _lawson_hanson(prob, p, contact, tol, max_iterations - its)
    out.iterations += its
    out.set_updates += updates
    if note:
        out.note = f"{note}; {out.note}" if out.note else f"{note}, then Lawson-Hanson"
    return out


def solve_flexible(
    model: FlexibleModel,
    load_n: float,
    load_position_m: float,
    effective_modulus_pa: float,
    *,
    tol: float = 1e-8,
    max_iterations: int = 3000,
    initial_pressure_pa: np.ndarray | None = None,
) -> macro.MacroResult:
    """Press a bending beam ski into the snow half-space (docs/physics.md §4b).

    Parameters
    ----------
    model : FlexibleModel
        Ski and footprint grid from :func:`prepare_flexible`.
    load_n : float
        Point load F ≥ 0 [N], down.
    load_position_m : float
        x_F [m], inside the footprint, with footprint rows on both sides.
    effective_modulus_pa : float
        E' of docs/physics.md eq. (1) [Pa], > 0; ``numpy.inf`` for rigid snow (the measuring
        device).
    tol : float
        Relative residual: RMS clearance on the contact set plus RMS penetration outside it,
        over the largest elastic displacement (snow plus beam) [-].
    max_iterations : int
        Operator applications (CG iterations) in all; exhausting them returns
        ``converged=False``.
    initial_pressure_pa : ndarray (nx, ny), optional
        Warm start [Pa] on the model's grid (e.g. a previous result's ``pressure_pa``); default
        the rigid-shape solve of the device's loaded profile.

    Returns
    -------
    MacroResult
        Same fields and meaning as :func:`solvers.macro.solve_macro` (zones, sub-pixel apparent
        area, line pressure); the window is the whole footprint (``window_gap_m = inf``);
        ``iterations`` counts CG iterations. In ``extra``:

        - ``beam_gap_m`` (nx,): the ski's loaded profile ``c + w − δ − θ (X − x_F)`` [m], the
          base's height above the undeformed snow surface (negative where it has sunk in; the
          clearance is this plus the snow displacement);
        - ``beam_deflection_m`` (nx,): elastic deflection w, upward, with the rigid motion that
          makes it orthogonal to 1 and X over the rows removed [m];
        - ``beam_reaction_row_n`` (nx,): snow force on each pixel row [N];
        - ``set_updates``: active-set updates; ``warm_start``: where the start came from.
    """
    t0 = time.perf_counter()
    if not isinstance(model, FlexibleModel):
        raise InputError(
            f"model must be a FlexibleModel from prepare_flexible, got {type(model).__name__}"
        )
    gmap = model.unloaded_map
    c_map = gmap.gap_m
    rows = gmap.positions_m
    dx, dy = gmap.pixel_size_m
    inside = np.isfinite(c_map)
    f = _finite_float(load_n, "load_n")
    xf = _finite_float(load_position_m, "load_position_m")
    e_eff = _float(effective_modulus_pa, "effective_modulus_pa")
    if f < 0:
        raise InputError(f"load_n must be >= 0, got {load_n!r}")
    if np.isnan(e_eff) or e_eff <= 0:
        raise InputError(
            f"effective_modulus_pa must be > 0 (inf for rigid snow), got {effective_modulus_pa!r}"
        )
    if not (np.isfinite(tol) and tol > 0):
        raise InputError(f"tol must be finite and > 0, got {tol!r}")
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise InputError(f"max_iterations must be an integer >= 1, got {max_iterations!r}")
    foot = rows[inside.any(axis=1)]
    if not (foot.min() < xf < foot.max()):
        raise InputError(
            f"load_position_m {xf} m must lie between the first and last footprint rows "
            f"({foot.min():.4g} .. {foot.max():.4g} m): no moment balance otherwise"
        )
    p_warm = None
    if initial_pressure_pa is not None:
        p_warm = np.asarray(initial_pressure_pa, dtype=float)
        if p_warm.shape != c_map.shape:
            raise InputError(
                f"initial_pressure_pa has shape {p_warm.shape}, expected the grid's {c_map.shape}"
            )
        p_warm = np.where(inside & np.isfinite(p_warm), np.maximum(p_warm, 0.0), 0.0)
        if not p_warm.sum() > 0:
            p_warm = None
    window = (float(rows[0] - dx / 2), float(rows[-1] + dx / 2))
    n_inside = int(np.count_nonzero(inside))
    b = model.compliance_m_per_n
    c_rows = model.row_beam.unloaded_gap_m
    if f == 0.0:
        return macro._finish(
            gmap,
            np.where(inside, 0.0, np.nan),
            np.where(inside, c_map - np.nanmin(c_map), np.nan),
            f,
            xf,
            e_eff,
            0.0,
            0.0,
            window,
            np.inf,
            n_inside,
            True,
            0,
            0.0,
            "zero load: no contact",
            t0,
            window_length=window[1] - window[0],
        )
    extra: dict = {}
    if np.isinf(e_eff):
        prob = _Rows(model, inside.any(axis=1), f, xf)
        p0 = _lowest_rows_start(prob)
        sol = _active_set(prob, p0, tol, max_iterations, pdas=False)
        row_force = np.zeros(rows.size)
        row_force[prob.idx] = sol.pressure
        counts = inside.sum(axis=1)
        p = np.where(inside, (row_force / np.maximum(counts, 1) / (dx * dy))[:, None], 0.0)
        u_snow = np.zeros(c_map.shape)
        extra["warm_start"] = "lowest row on each side of the load (Lawson-Hanson start)"
    else:
        pix = _Pixels(model, inside, f, xf, e_eff)
        if p_warm is not None:
            extra["warm_start"] = "initial_pressure_pa"
            p0 = np.ascontiguousarray(p_warm.reshape(-1)[pix.idx])
        else:
            p0 = _row_start(pix, model)
            extra["warm_start"] = "row-level problem"
        if p0 is None:
            dev = solve_beam_contact(model.row_beam, f, xf, flexibility=model.row_flexibility)
            p_warm = _rigid_start(model, dev.gap_m, inside, f, xf, e_eff)
            extra["warm_start"] = "rigid-shape solve of the device profile"
            p0 = np.ascontiguousarray(p_warm.reshape(-1)[pix.idx])
        if not macro._restore_balance(p0, pix.xs, pix.total, True):
            p0 = np.zeros(pix.xs.size)

        def device_start() -> np.ndarray | None:
            """The device's row reactions spread over their rows' pixels (stiff-snow limit)."""
            counts = np.bincount(pix.rows, minlength=pix.nx)
            dev = solve_beam_contact(model.row_beam, f, xf, flexibility=model.row_flexibility)
            if not dev.converged or np.any((dev.reaction_n > 0) & (counts == 0)):
                return None
            per_pixel = dev.reaction_n / np.maximum(counts, 1) / pix.area
            return np.ascontiguousarray(per_pixel[pix.rows])

        sol = _active_set(pix, p0, tol, max_iterations, pdas=True, lh_start=device_start)
        p = np.zeros(c_map.size)
        p[pix.idx] = sol.pressure
        p = p.reshape(c_map.shape)
        row_force = p.sum(axis=1) * dx * dy
        u_snow = np.zeros(c_map.size)
        u_snow[pix.idx] = pix.snow(sol.pressure)
        u_snow = u_snow.reshape(c_map.shape)
    delta, theta, its, res = sol.delta, sol.theta, sol.iterations, sol.residual
    updates, conv, note = sol.set_updates, sol.converged, sol.note
    i, t = _load_split(rows, xf)
    w = b @ row_force - f * ((1.0 - t) * b[:, i] + t * b[:, i + 1])
    xs = rows - xf
    beam_gap = c_rows + w - delta - theta * xs
    clear = np.where(inside, beam_gap[:, None] + u_snow, np.nan)
    clear[p > 0] = 0.0
    clear = np.where(inside, np.maximum(clear, 0.0), np.nan)
    detail = f"{updates} active-set updates" + (f", {note}" if note else "")
    msg = (
        f"converged: {its} CG iterations, {detail} (residual {res:.3g} < tol {tol:.3g})"
        if conv
        else f"not converged: {its} CG iterations, {detail}, residual {res:.3g} (tol {tol:.3g})"
    )
    result = macro._finish(
        gmap,
        np.where(inside, p, np.nan),
        clear,
        f,
        xf,
        e_eff,
        delta,
        theta,
        window,
        np.inf,
        n_inside,
        conv,
        its,
        res,
        msg,
        t0,
        window_length=window[1] - window[0],
    )
    extra.update(
        beam_gap_m=beam_gap,
        beam_deflection_m=w,
        beam_reaction_row_n=row_force,
        set_updates=updates,
    )
    result.extra.update(extra)
    return result


def _rigid_start(
    model: FlexibleModel,
    device_gap_m: np.ndarray,
    inside: np.ndarray,
    f: float,
    xf: float,
    e_eff: float,
) -> np.ndarray:
    """Pressure [Pa] of the rigid-shape model: the device's profile pressed by solve_macro."""
    gmap = model.unloaded_map
    h = np.where(inside, device_gap_m[:, None], np.nan)
    rigid = macro.solve_macro(macro.GapMap(h, gmap.positions_m, gmap.pixel_size_m), f, xf, e_eff)
    return np.where(inside, rigid.pressure_pa, 0.0)


def _float(value, name: str) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None


def _finite_float(value, name: str) -> float:
    v = _float(value, name)
    if not np.isfinite(v):
        raise InputError(f"{name} must be a finite number, got {value!r}")
    return v
