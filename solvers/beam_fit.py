"""Forward-model fit of a ski's beam to its camber cases (docs/physics.md §4c, the Gauss–Newton
polish).

The start (:mod:`solvers.identify`, variable projection with free reactions at contact points
read from the data) fits the measured cases at the device noise but leaves two freedoms that
spoil predictions of cases it has not seen (docs/camber-identification.md): per-case redundant
reactions at candidate contacts, and a camber c(X) fitted node by node, whose per-node noise
(σ/√K) pins the beam's slope wrongly wherever a short contact holds it. This module removes
both:

- **The exact device model.** Every case is predicted by the unilateral contact solve of
  :func:`solvers.beam.solve_beam_contact`: its contacts and reactions follow from EI and c, so
  no case has freedom of its own. For a fixed contact set the solve is linear (a KKT system in
  the reactions and the rigid motion), and its derivatives follow by implicit differentiation:
  ``∂H/∂θ = (I − B K⁻¹ S) ∂d/∂θ`` with ``d`` the gap before the contact correction, ``B`` the
  columns [G_{:,A}, 1, X − x_F], ``K`` the KKT matrix and ``S`` the selection of the contact
  rows. The contact sets are re-solved at every trial point (Levenberg–Marquardt).
- **A smooth camber with the kinks the data show.** c(X) is a cubic B-spline with knots
  ``camber_spacing_m`` apart, plus a triple knot (a slope kink) wherever the mean measured
  profile has a significant slope jump (:func:`detect_camber_kinks`). The loaded gap is
  ``c + u + line`` with u twice continuously differentiable, so a kink of the mean profile is
  a kink of c; a shovel that starts with a kink (the demo skis) keeps it, a smooth base stays
  smooth.
- **Continuation in the contact.** On the rigid flat of a 1 mm device model, a short contact of
  two nodes pins the beam's slope, and which node pair touches flips with tiny changes of c:
  the misfit is continuous but made of very small smooth pieces, and Gauss–Newton stalls on
  them (ski-a: 1.015 × the noise, held-out profiles 0.42 µm RMS from the truth). The fit
  therefore starts with the flat as a Winkler foundation of length (4 EI/k)^¼ = 10 mm on a
  subset of the cases, shortens it 3× per stage, and ends on the rigid flat with every case
  (ski-a: 1.000 × the noise, 0.07 µm).
- 1/EI = Σ exp(γ_m) φ_m(X) on hat functions (positive by construction), with the same smoothness
  prior on the second differences of γ as the start.

The result carries the Gauss–Newton covariance of all parameters, from which the bands on EI(X)
and c(X) and the draws of plausible beams follow.

Units: SI throughout (m, N, N·m²).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numba
import numpy as np
import scipy.linalg
import scipy.sparse
from scipy.interpolate import BSpline

from .beam import BeamFlexibility, BeamSki, camber_on_flat, flat_supports, solve_beam_contact
from .errors import InputError

__all__ = [
    "DEFAULT_CAMBER_SPACING_M",
    "ForwardFit",
    "camber_basis",
    "detect_camber_kinks",
    "fit_forward",
    "flat_supports",
    "model_grid",
]

#: knot spacing of the camber's cubic B-spline [m]: on the demo skis' true cambers (with their
#: kinks as knots) 10 mm leaves ≤ 0.05 µm in c and ≤ 0.07 µm RMS in predicted profiles near
#: contact; 20 mm leaves 0.3 µm (docs/camber-identification.md)
DEFAULT_CAMBER_SPACING_M = 0.010
#: the continuation's first stage: beam-on-foundation length of the softened flat [m]; each
#: further stage divides it by FOUNDATION_STEP, down to two nodes, then the flat is rigid
DEFAULT_FOUNDATION_LENGTH_M = 0.010
FOUNDATION_STEP = 3.0
#: the first stage only brings the fit near: it stops at this relative decrease [-] or after
#: STAGE_STEPS steps (its softened contact cannot fit rigid-flat data to the noise)
STAGE_RTOL = 1e-3
STAGE_STEPS = 12
#: continuation in the grid: the softened stages and a first rigid stage see the nodes at about
#: this spacing [m] (every 2nd node of a 1 mm device); their contact pieces are twice as long,
#: so Gauss–Newton crosses them, and each solve is cheaper. Measured on dense 'stiff' / 'soft'
#: test designs (docs/camber-identification.md)
DEFAULT_COARSE_SPACING_M = 0.002
#: the coarse rigid stage stops at this relative decrease [-] or after COARSE_STEPS steps
COARSE_RTOL = 1e-4
COARSE_STEPS = 30
#: cases the first stage uses at most (spread over all; the rigid stage uses every case)
STAGE_CASES = 120
#: fit_forward's ``model_spacing_m``: measured nodes more than this many times the model
#: spacing apart get the finer model grid (1.25 mm data stay on their nodes at 1 mm)
MODEL_REFINE_RATIO = 1.5
#: accepted steps the finer grid's stage may take at least (it starts from the measured
#: nodes' fit, near its minimum)
FINE_STEPS = 20
#: half-width of the window in which a slope kink of the mean profile is tested [m]
KINK_WINDOW_M = 0.015
#: a slope jump is a kink when it exceeds this many standard errors (2000 nodes tested: a
#: Gaussian false alarm at 6 σ has probability ~4e-6 per ski)
KINK_THRESHOLD = 6.0
#: how far from the score's peak the kink's least-squares position is searched [nodes]
KINK_SEARCH_NODES = 6


def detect_camber_kinks(
    positions_m: np.ndarray,
    profiles_m: np.ndarray,
    noise_m: float,
    *,
    window_m: float = KINK_WINDOW_M,
    threshold: float = KINK_THRESHOLD,
) -> np.ndarray:
    """Positions [m] where the camber has a slope kink, read from the measured profiles.

    Every measured gap is ``c + u_k + a_k + b_k X`` with u_k twice continuously differentiable
    (M/EI is continuous), so the mean profile ȳ over all cases is c plus a smooth function and
    its kinks are c's. At every node X_j a local model ``α + β s + γ s² + ε s₊² + δ s₊``
    (s = X − X_j, over ±``window_m``) is fitted to ȳ; δ is the slope jump and ε absorbs a jump
    in curvature (which a cubic spline follows without a kink). A node is a kink where
    |δ| > ``threshold`` × its standard error (noise σ/√K) and |δ| is largest within the window.

    Parameters
    ----------
    positions_m : ndarray (N,)
        Uniform measurement nodes X [m].
    profiles_m : ndarray (K, N)
        Measured gaps [m].
    noise_m : float
        Device noise σ [m].
    window_m : float
        Half-width of the local fit [m].
    threshold : float
        Significance of a kink in standard errors [-].

    Returns
    -------
    ndarray
        Kink positions [m], increasing (possibly empty).
    """
    x = np.asarray(positions_m, dtype=float)
    y = np.asarray(profiles_m, dtype=float)
    dx = float(x[1] - x[0])
    half = max(3, round(window_m / dx))
    if x.size < 2 * half + 1:
        return np.zeros(0)
    s = np.arange(-half, half + 1) * dx
    sp = np.maximum(s, 0.0)
    design = np.stack([np.ones_like(s), s, s * s, sp * sp, sp], axis=1)
    pinv = np.linalg.pinv(design)
    filt = pinv[4]  # δ̂ = filt · ȳ[window]
    mean = y.mean(axis=0)
    windows = np.lib.stride_tricks.sliding_window_view(mean, 2 * half + 1)
    delta = windows @ filt
    se = noise_m / np.sqrt(y.shape[0]) * float(np.linalg.norm(filt))
    score = np.abs(delta) / max(se, 1e-300)
    centre = np.arange(half, x.size - half)
    out: list[float] = []
    for i in np.argsort(-score):
        if score[i] < threshold:
            break
        lo, hi = max(i - half, 0), min(i + half + 1, score.size)
        if score[i] < score[lo:hi].max():
            continue
        xi = float(x[centre[i]]) + _kink_offset(windows[i], s)
        if all(abs(xi - k) > window_m for k in out):
            out.append(xi)
    return np.sort(np.asarray(out, dtype=float))


def _kink_offset(window: np.ndarray, s: np.ndarray) -> float:
    """Where, within ±KINK_SEARCH_NODES of the window's centre, a kink explains the window best
    [m]: the least-squares position τ of the local model
    ``α + β s + γ s² + ε (s−τ)₊² + δ (s−τ)₊`` (tenths of a node). The score of
    :func:`detect_camber_kinks` can peak a few nodes off the kink (measured: 3 nodes on the
    'stiff' test design's tail, where a ±2-node search stopped at its edge, 1 node off, and
    the forward fit stalled at 1.004 × the noise); the residual is exact at the kink."""
    dx = float(s[1] - s[0])
    reach = min(KINK_SEARCH_NODES, max(2, (s.size - 1) // 2 - 2)) * dx
    best, best_rss = 0.0, np.inf
    for tau in np.linspace(-reach, reach, 20 * round(reach / dx) + 1):
        sp = np.maximum(s - tau, 0.0)
        design = np.stack([np.ones_like(s), s, s * s, sp * sp, sp], axis=1)
        coef = np.linalg.lstsq(design, window, rcond=None)[0]
        rss = float(np.sum((design @ coef - window) ** 2))
        if rss < best_rss:
            best, best_rss = float(tau), rss
    return best


def camber_basis(
    positions_m: np.ndarray, spacing_m: float, kinks_m: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Cubic B-spline basis of the camber on the nodes: (N, n) design matrix and knot vector.

    Knots are uniform ``spacing_m`` apart; each kink gets a triple knot (the spline stays
    continuous and its slope may jump there), and uniform knots closer than 0.3 × spacing to a
    kink are dropped.
    """
    x = np.asarray(positions_m, dtype=float)
    if not (np.isfinite(spacing_m) and spacing_m > 0):
        raise InputError(f"camber_spacing_m must be finite and > 0, got {spacing_m!r}")
    n = max(round((x[-1] - x[0]) / spacing_m), 1)
    inner = list(np.linspace(x[0], x[-1], n + 1)[1:-1])
    kinks = [] if kinks_m is None else [float(k) for k in kinks_m if x[0] < k < x[-1]]
    for k in kinks:
        inner = [t for t in inner if abs(t - k) > 0.3 * spacing_m]
    knots = np.r_[[x[0]] * 4, sorted(inner + 3 * kinks), [x[-1]] * 4]
    mat = BSpline.design_matrix(x, knots, 3).toarray()
    return mat, knots


def hats(x: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """(N, m) piecewise-linear hat functions on ``knots`` evaluated at ``x`` (constant beyond)."""
    eye = np.eye(knots.size)
    return np.stack([np.interp(x, knots, eye[m]) for m in range(knots.size)], axis=1)


def double_integral(kappa: np.ndarray, dx: float) -> np.ndarray:
    """∫∫ κ from the first node along the last axis (zero value and slope there); κ piecewise
    linear between nodes, integrated exactly (the rule of :class:`solvers.beam.BeamFlexibility`).
    ``dx`` node spacing [m] (a float, or the (N−1,) spacings).

    One or two dimensions of float64 (every call of the identification: per case and
    evaluation of a forward fit, and the variable-projection start's columns, whose ``dx`` are
    the (N−1,) spacings) run compiled, bit-identical to :func:`_double_integral_reference` (the
    same sums in the same order); the rest runs it."""
    kappa = np.asarray(kappa)
    if kappa.dtype == np.float64 and kappa.ndim in (1, 2) and kappa.shape[-1] >= 2:
        if np.ndim(dx) == 0:
            # one spacing: every interval's (the same products, so the same bits)
            spacings = np.full(kappa.shape[-1] - 1, float(dx))
        else:
            spacings = np.ascontiguousarray(dx, dtype=np.float64)
        if spacings.shape == (kappa.shape[-1] - 1,):
            rows = np.ascontiguousarray(kappa.reshape(-1, kappa.shape[-1]))
            w = _double_integral_rows(rows, spacings).reshape(kappa.shape)
            if w.strides != np.empty_like(kappa).strides:
                # the reference's memory layout (its zeros_like: a transposed κ gives a
                # transposed w), so that the products made with it round as they did
                out = np.empty_like(kappa)
                out[...] = w
                return out
            return w
    return _double_integral_reference(kappa, dx)


def _double_integral_reference(kappa: np.ndarray, dx) -> np.ndarray:
    """:func:`double_integral` in numpy (any shape, ``dx`` a float or the spacings)."""
    k0, k1 = kappa[..., :-1], kappa[..., 1:]
    slope = np.zeros_like(kappa)
    np.cumsum(0.5 * dx * (k0 + k1), axis=-1, out=slope[..., 1:])
    w = np.zeros_like(kappa)
    np.cumsum(dx * slope[..., :-1] + dx * dx * (2.0 * k0 + k1) / 6.0, axis=-1, out=w[..., 1:])
    return w


@numba.njit(cache=True)
def _double_integral_rows(kappa, dx):
    """:func:`_double_integral_reference` of each row of the (m, N) ``kappa`` with the (N−1,)
    spacings ``dx`` [m], its operations in its order (bit-identical), without its four
    temporaries."""
    m, n = kappa.shape
    w = np.zeros((m, n))
    for r in range(m):
        slope = 0.0
        acc = 0.0
        for i in range(n - 1):
            k0 = kappa[r, i]
            k1 = kappa[r, i + 1]
            h = dx[i]
            w_inc = h * slope + h * h * (2.0 * k0 + k1) / 6.0
            slope = slope + 0.5 * h * (k0 + k1)
            acc = acc + w_inc
            w[r, i + 1] = acc
    return w


def _continuation(
    start: BeamSki, foundation_length_m: float, spacing_m: float | None = None
) -> list[float]:
    """Contact compliances [m/N] of the continuation's stages: Winkler foundations of modulus
    k = 4 EI / ℓ⁴ [N/m²] (EI the start's median), lumped per node (k·dx, dx = ``spacing_m``,
    default the start's), for ℓ = ``foundation_length_m`` and then ÷ FOUNDATION_STEP until ℓ
    reaches 2 nodes, then 0 (the rigid flat)."""
    if not foundation_length_m > 0:
        return [0.0]
    dx = start.spacing_m if spacing_m is None else float(spacing_m)
    ei = float(np.median(start.bending_stiffness_nm2))
    out = []
    ell = foundation_length_m
    while ell >= 2.0 * dx:
        out.append(1.0 / (4.0 * ei / ell**4 * dx))
        ell /= FOUNDATION_STEP
    return [*out, 0.0]


@dataclass
class ForwardFit:
    """Result of :func:`fit_forward`.

    Attributes
    ----------
    beam : BeamSki
        Fitted beam (camber shifted to rest on the flat).
    camber_coefficients : ndarray (n_c,)
        B-spline coefficients of c [m] (before the shift to the flat).
    camber_knots_m : ndarray
        Knot vector of c's cubic B-spline [m].
    kinks_m : ndarray
        Slope kinks of c (triple knots) [m].
    stiffness_knots_m : ndarray (m,)
        Hat-function knots of 1/EI [m].
    log_compliance : ndarray (m,)
        γ: log of 1/EI at the knots [log(1/(N·m²))].
    covariance : ndarray (n_c + m, n_c + m)
        Gauss–Newton covariance of (camber coefficients, γ), σ̂² H⁻¹, the camber's line gauge
        removed [m², -].
    misfit_m : float
        RMS residual over all cases and nodes [m].
    case_misfit_m : ndarray (K,)
        RMS residual per case [m].
    converged : bool
        The objective stopped decreasing by more than ``rtol`` (relative), every contact solve
        converged, within ``max_steps``.
    iterations : int
        Accepted Gauss–Newton steps.
    message : str
        What stopped the iteration.
    solve_time_s : float
        Wall time [s].
    history_m : list of float
        Misfit after each accepted step [m].
    objective : float
        The fitted objective at the end, χ²/σ² plus the prior on γ [-]: fits of one data set
        with the same bases compare by it (the lower is the better local minimum).
    stiffness_resolution : ndarray (m,)
        Diagonal of the model resolution matrix H⁻¹ (JᵀJ/σ²) at the γ knots [-]: the share of
        each knot's estimate the data set (1: the cases alone, 0: the smoothing prior alone,
        where no case bends the ski).
    """

    beam: BeamSki
    camber_coefficients: np.ndarray
    camber_knots_m: np.ndarray
    kinks_m: np.ndarray
    stiffness_knots_m: np.ndarray
    log_compliance: np.ndarray
    covariance: np.ndarray
    misfit_m: float
    case_misfit_m: np.ndarray
    converged: bool
    iterations: int
    message: str
    solve_time_s: float = 0.0
    history_m: list = field(default_factory=list)
    objective: float = float("nan")
    stiffness_resolution: np.ndarray | None = None


class _Model:
    """Data, bases and the evaluation of residuals and Gauss–Newton normal equations."""

    def __init__(self, x, loads, xfs, y, noise, camber_mat, stiff_knots, smoothing, obs=None):
        self.x, self.loads, self.xfs, self.y = x, loads, xfs, y
        self.noise = noise
        self.dx = float(x[1] - x[0])
        self.bc = camber_mat
        #: the nodes the cases were measured at (indices into x; every node when None): the
        #: model's nodes may be finer than the measurement's (fit_forward's model_spacing_m)
        self.obs = slice(None) if obs is None else np.asarray(obs, dtype=int)
        bc_obs = camber_mat[self.obs]
        self.bc_sparse = scipy.sparse.csr_matrix(bc_obs)
        self.bc_sparse_t = scipy.sparse.csr_matrix(self.bc_sparse.T)
        self.bc_gram = (self.bc_sparse_t @ self.bc_sparse).toarray()
        self.phi = hats(x, stiff_knots)
        self.phi_t = np.ascontiguousarray(self.phi.T)
        m = stiff_knots.size
        d2 = np.zeros((max(m - 2, 0), m))
        for i in range(m - 2):
            d2[i, i : i + 3] = (1.0, -2.0, 1.0)
        self.reg = smoothing * d2
        self.nc = camber_mat.shape[1]
        #: contact compliance of the flat [m/N] (0: rigid; > 0 in the continuation's first stage)
        self.compliance = 0.0
        #: each case's contact nodes at the last evaluation (warm starts of the contact solves)
        self.contacts: list[np.ndarray | None] = [None] * loads.size
        self.nq = m
        # the camber's rigid-line directions in coefficient space: gaps do not see them
        line = np.linalg.lstsq(camber_mat, np.stack([np.ones_like(x), x - x.mean()], 1), rcond=None)
        self.line_c, _ = np.linalg.qr(line[0])

    def beam(self, theta: np.ndarray) -> BeamSki:
        cc, gamma = theta[: self.nc], theta[self.nc :]
        q = self.phi @ np.exp(gamma)
        return BeamSki(self.x, 1.0 / q, camber_on_flat(self.x, self.bc @ cc))

    def objective(self, ssr: float, theta: np.ndarray) -> float:
        rg = self.reg @ theta[self.nc :]
        return ssr / self.noise**2 + float(rg @ rg)

    def evaluate(self, theta: np.ndarray, jacobian: bool):
        """Residual sum of squares, per-case sums, and (optionally) JᵀJ and Jᵀρ [m², m²/θ]."""
        x, n = self.x, self.x.size
        beam = self.beam(theta)
        flex = BeamFlexibility(beam)
        beta = np.exp(theta[self.nc :])
        p = self.nc + self.nq
        jtj = np.zeros((p, p))
        jtr = np.zeros(p)
        per = np.zeros(self.loads.size)
        all_converged = True
        sl_c, sl_q = slice(0, self.nc), slice(self.nc, p)
        if jacobian:
            jtj[sl_c, sl_c] = self.loads.size * self.bc_gram
        for k, (load, xf) in enumerate(zip(self.loads, self.xfs, strict=True)):
            if load == 0.0:
                # the unloaded case: c resting on its two end contacts (no deflection). For a
                # fixed pair of supports the gap is linear in c's coefficients:
                # J = Bc − v R, with v the two supports' interpolation weights, R their rows
                c_now = self.bc @ theta[: self.nc]
                i0, i1 = flat_supports(x, c_now)
                gap = camber_on_flat(x, c_now)
                rho = gap[self.obs] - self.y[k]
                per[k] = float(rho @ rho)
                if not jacobian:
                    continue
                s1 = (x[self.obs] - x[i0]) / (x[i1] - x[i0])
                v = np.stack([1.0 - s1, s1], axis=1)  # (N_obs, 2)
                rows = self.bc[[i0, i1]]  # (2, nc)
                btv = self.bc_sparse_t @ v  # (nc, 2)
                cross = btv @ rows
                jtj[sl_c, sl_c] += rows.T @ (v.T @ v) @ rows - cross - cross.T
                jtr[sl_c] += self.bc_sparse_t @ rho - rows.T @ (v.T @ rho)
                continue
            res = solve_beam_contact(
                beam,
                load,
                xf,
                flexibility=flex,
                initial_contacts=self.contacts[k],
                contact_compliance_m_per_n=self.compliance,
            )
            self.contacts[k] = np.flatnonzero(res.reaction_n > 0)
            all_converged &= bool(res.converged)
            gap = res.gap_m if self.compliance == 0.0 else beam.unloaded_gap_m + res.displacement_m
            rho = gap[self.obs] - self.y[k]
            per[k] = float(rho @ rho)
            if not jacobian:
                continue
            act = np.flatnonzero(res.reaction_n > 0)
            r = res.reaction_n[act]
            xs = x - xf
            s = (xf - x[0]) / self.dx
            i0 = min(int(np.floor(s)), n - 2)
            t = s - i0
            mom = np.maximum(x[None, :] - x[act][:, None], 0.0).T @ r - load * (
                (1.0 - t) * np.maximum(x - x[i0], 0.0) + t * np.maximum(x - x[i0 + 1], 0.0)
            )
            # ∂d/∂γ_m: deflection of this case's moment with 1/EI = β_m φ_m
            ut = double_integral(mom[None, :] * self.phi_t, self.dx) * beta[:, None]  # (nq, N)
            m_act = act.size
            bm = np.empty((n, m_act + 2))
            bm[:, :m_act] = flex.matrix[:, act]
            bm[:, m_act] = 1.0
            bm[:, m_act + 1] = xs
            kkt = np.zeros((m_act + 2, m_act + 2))
            kkt[:m_act, :m_act] = flex.matrix[np.ix_(act, act)]
            kkt[np.arange(m_act), np.arange(m_act)] += self.compliance
            kkt[:m_act, m_act] = 1.0
            kkt[:m_act, m_act + 1] = xs[act]
            kkt[m_act, :m_act] = 1.0
            kkt[m_act + 1, :m_act] = xs[act]
            sd = np.zeros((m_act + 2, p))
            sd[:m_act, sl_c] = self.bc[act]
            sd[:m_act, sl_q] = ut[:, act].T
            w = np.linalg.lstsq(kkt, sd, rcond=None)[0] if m_act else np.zeros((2, p))
            # J = D − Bm W with D = [Bc, U], on the measured nodes' rows (the contact rows
            # above are the model's)
            ut, bm = ut[:, self.obs], bm[self.obs]
            jtj[sl_c, sl_q] += self.bc_sparse_t @ ut.T  # Bcᵀ U (nc, nq)
            jtj[sl_q, sl_q] += ut @ ut.T
            dtb = np.empty((p, m_act + 2))
            dtb[sl_c] = self.bc_sparse_t @ bm
            dtb[sl_q] = ut @ bm
            cross = dtb @ w
            jtj -= cross + cross.T
            jtj += w.T @ ((bm.T @ bm) @ w)
            jtr[sl_c] += self.bc_sparse_t @ rho
            jtr[sl_q] += ut @ rho
            jtr -= w.T @ (bm.T @ rho)
        if jacobian:
            jtj[sl_q, sl_c] = jtj[sl_c, sl_q].T
        return float(per.sum()), per, jtj, jtr, all_converged


def model_grid(
    positions_m: np.ndarray, model_spacing_m: float
) -> tuple[np.ndarray, np.ndarray] | None:
    """The finer model grid of :func:`fit_forward`'s ``model_spacing_m``: (its nodes [m], the
    indices of the measured nodes among them), or None when the measured nodes serve (no
    spacing given, or they are at most MODEL_REFINE_RATIO × ``model_spacing_m`` apart).

    Each measured interval is divided into round(dx / ``model_spacing_m``) equal parts, and
    the measured positions are kept bit for bit."""
    x = np.asarray(positions_m, dtype=float)
    if not (model_spacing_m > 0) or x.size < 2:
        return None
    dx = float(x[1] - x[0])
    if dx <= MODEL_REFINE_RATIO * model_spacing_m:
        return None
    parts = max(2, round(dx / model_spacing_m))
    frac = np.arange(parts) / parts
    x_f = np.empty((x.size - 1) * parts + 1)
    x_f[:-1] = (x[:-1, None] + np.diff(x)[:, None] * frac[None, :]).ravel()
    x_f[-1] = x[-1]
    obs = np.arange(0, x_f.size, parts)
    x_f[obs] = x
    return x_f, obs


def _scaled_inverse(h: np.ndarray) -> np.ndarray:
    """Pseudo-inverse of the symmetric normal matrix ``h`` after Jacobi scaling.

    The camber coefficients [m] and γ [-] differ by ~10¹⁵ in their data information: a plain
    ``pinv`` cut at 1e-15 of the largest singular value dropped every direction only the
    prior on γ holds (the ski's ends beyond the device's contact points), and gave them zero
    variance instead of the prior's. Scaled to a unit diagonal the cut-off only drops true
    null directions."""
    d = np.sqrt(np.clip(np.diag(h), 0.0, None))
    d[d == 0] = 1.0
    return np.linalg.pinv(h / np.outer(d, d), hermitian=True) / np.outer(d, d)


def fit_forward(
    positions_m: np.ndarray,
    loads_n: np.ndarray,
    load_positions_m: np.ndarray,
    profiles_m: np.ndarray,
    start: BeamSki,
    *,
    noise_m: float,
    stiffness_knots_m: np.ndarray,
    smoothing: float,
    camber_spacing_m: float = DEFAULT_CAMBER_SPACING_M,
    kinks_m: np.ndarray | None = None,
    max_steps: int = 80,
    rtol: float = 1e-5,
    foundation_length_m: float = DEFAULT_FOUNDATION_LENGTH_M,
    coarse_spacing_m: float = DEFAULT_COARSE_SPACING_M,
    model_spacing_m: float = 0.0,
    callback=None,
) -> ForwardFit:
    """Levenberg–Marquardt fit of (c, EI) through the exact device model, from ``start``.

    Parameters
    ----------
    positions_m : ndarray (N,)
        Uniform measurement nodes X [m].
    loads_n, load_positions_m : ndarray (K,)
        F_k [N] (≥ 0) and x_k [m] of each case. A case of 0 N is the unloaded profile: its
        device model is c resting on the flat (:func:`camber_on_flat`), x_k is ignored.
    profiles_m : ndarray (K, N)
        Measured gaps [m].
    start : BeamSki
        Starting beam on the same nodes (the variable-projection start).
    noise_m : float
        Device noise σ [m] (the scale of the prior on γ).
    stiffness_knots_m : ndarray (m,)
        Hat-function knots of 1/EI [m].
    smoothing : float
        Weight of the second differences of γ in units of the noise [-].
    camber_spacing_m : float
        Knot spacing of c's cubic B-spline [m].
    kinks_m : ndarray, optional
        Slope kinks of c [m]; default: :func:`detect_camber_kinks` on the data.
    max_steps : int
        Accepted steps at most.
    rtol : float
        Stop when the objective falls by less than this (relative) in a step.
    foundation_length_m : float
        Continuation: the first stage fits with the flat as an elastic foundation whose
        beam-on-foundation length (4 EI / k)^¼ is this [m] (median EI of the start), on at most
        STAGE_CASES cases; each next stage is FOUNDATION_STEP times shorter, down to two nodes;
        the last stage fits every case on the rigid flat. 0 skips the softened stages.
    coarse_spacing_m : float
        Continuation in the grid: when the nodes are finer than this [m], the softened stages
        and a first rigid stage fit every k-th node only (spacing ≈ this), and the last stage
        polishes on every node. 0 fits every node throughout.
    model_spacing_m : float
        Node spacing of the device model [m]. When the measured nodes are more than
        MODEL_REFINE_RATIO times coarser, the fit ends with a stage on a model grid that
        divides each measured interval into round(spacing / model_spacing_m) (the measured
        nodes among its nodes; residuals only there), and the beam is returned on that grid:
        the rigid flat touches the ski between measured nodes too, and a model on nodes
        5 mm apart misses the device's contact (docs/camber-identification.md, "Sample
        spacing"). 0: the measured nodes.
    callback : callable, optional
        ``callback(step, misfit_m)`` after each accepted step (progress; silent by default).

    Returns
    -------
    ForwardFit
        Its beam on the model grid (the measured nodes, or the finer grid of
        ``model_spacing_m``); ``case_misfit_m`` and ``misfit_m`` over the measured nodes.
    """
    t0 = time.perf_counter()
    x = np.asarray(positions_m, dtype=float)
    loads = np.asarray(loads_n, dtype=float)
    xfs = np.asarray(load_positions_m, dtype=float)
    y = np.asarray(profiles_m, dtype=float)
    if start.positions_m.shape != x.shape:
        raise InputError("start beam must be on the measurement nodes")
    if not np.all(loads >= 0):
        raise InputError(
            f"loads_n must be > 0 (0 N: the unloaded profile), got min {loads.min():g} N"
        )
    kinks = detect_camber_kinks(x, y, noise_m) if kinks_m is None else np.asarray(kinks_m, float)
    bc, knots_c = camber_basis(x, camber_spacing_m, kinks)
    knots_q = np.asarray(stiffness_knots_m, dtype=float)
    model = _Model(x, loads, xfs, y, noise_m, bc, knots_q, smoothing)
    cc0 = np.linalg.lstsq(bc, start.unloaded_gap_m, rcond=None)[0]
    g0 = np.log(1.0 / np.interp(knots_q, x, start.bending_stiffness_nm2))
    theta = np.concatenate([cc0, g0])
    nc = model.nc
    s2 = noise_m**2
    gauge = model.line_c @ model.line_c.T / s2

    def normal(jtj, jtr, theta):
        h = jtj / s2
        g = jtr / s2
        h[nc:, nc:] += model.reg.T @ model.reg
        g[nc:] += model.reg.T @ (model.reg @ theta[nc:])
        h[:nc, :nc] += gauge
        return h, g

    history: list[float] = []
    total = [0]

    def levenberg_marquardt(model: _Model, theta: np.ndarray, steps_left: int, rtol: float):
        """Damped Gauss–Newton steps from ``theta`` until the objective stalls."""
        ssr, _, jtj, jtr, _ = model.evaluate(theta, jacobian=True)
        cur = model.objective(ssr, theta)
        h, g = normal(jtj, jtr, theta)
        lam = 1e-3
        steps = 0
        message = f"max_steps {max_steps} reached"
        converged = False
        while steps < steps_left:
            # Jacobi scaling: c's coefficients [m] and γ [-] differ by ~1e6 in the normal matrix
            # (floored relative to the largest diagonal: a parameter the data barely see, such
            # as a camber spline piece between the coarse stage's nodes, would get a scale of
            # ~1e150 and overflow the scaled matrix; measured on ski-b)
            d = np.diag(h)
            scale = 1.0 / np.sqrt(np.maximum(d, 1e-12 * max(float(d.max()), 1e-300)))
            hs = h * scale[:, None] * scale[None, :]
            gs = g * scale
            while True:
                damped = hs + lam * np.eye(hs.shape[0])
                try:
                    step = -scale * scipy.linalg.solve(
                        damped, gs, assume_a="pos", check_finite=False
                    )
                except (np.linalg.LinAlgError, ValueError):
                    try:
                        step = -scale * np.linalg.lstsq(damped, gs, rcond=None)[0]
                    except np.linalg.LinAlgError:
                        step = np.full(theta.size, np.nan)
                if not np.all(np.isfinite(step)):
                    new = np.inf  # a singular or overflowing system: damp more
                    if lam > 1e8:
                        break
                    lam *= 10.0
                    continue
                step[nc:] = np.clip(step[nc:], -1.0, 1.0)
                trial = theta + step
                ssr_t, *_ = model.evaluate(trial, jacobian=False)
                new = model.objective(ssr_t, trial)
                if new <= cur or lam > 1e8:
                    break
                lam *= 10.0
            if not np.isfinite(new):
                message = "no finite step: the normal equations are singular or overflow"
                break
            if new > cur:
                message = "no step lowers the misfit (converged to a local minimum)"
                converged = True
                break
            improvement = (cur - new) / max(cur, 1e-300)
            theta, cur, ssr = trial, new, ssr_t
            steps += 1
            total[0] += 1
            lam = max(lam / 10.0, 1e-9)
            history.append(float(np.sqrt(ssr / model.y.size)))
            if callback is not None:
                callback(total[0], history[-1])
            if improvement < rtol:
                message = f"converged: objective fell by {improvement:.1e} (< rtol {rtol:g})"
                converged = True
                break
            ssr, _, jtj, jtr, _ = model.evaluate(theta, jacobian=True)
            h, g = normal(jtj, jtr, theta)
        return theta, converged, message

    # continuation in the grid, then in the contact: the first stages see every
    # ``stride``-th node only (coarser contact pieces, cheaper solves; c's B-spline and 1/EI's
    # hats are the same functions on any nodes, so θ carries over), with the flat first as a
    # stiff elastic foundation (contacts spread over a few nodes, so the gaps depend smoothly
    # on c's local slope), then rigid; the last stage is the rigid flat on every node
    messages = []
    stride = 1
    if coarse_spacing_m > 0:
        stride = max(1, round(coarse_spacing_m / model.dx))
    plan: list[tuple[int, float]] = []
    if stride > 1:
        plan += [(stride, c) for c in _continuation(start, foundation_length_m, stride * model.dx)]
        plan.append((1, 0.0))
    else:
        plan += [(1, c) for c in _continuation(start, foundation_length_m)]
    fine = model_grid(x, model_spacing_m)
    for i, (level, compliance) in enumerate(plan):
        last = i == len(plan) - 1 and fine is None
        rigid = compliance == 0.0
        rows = slice(None, None, level)
        cases = np.arange(loads.size)
        if not rigid and loads.size > STAGE_CASES:
            cases = np.unique(
                np.concatenate(
                    [
                        np.linspace(0, loads.size - 1, STAGE_CASES).round().astype(int),
                        np.flatnonzero(loads == 0.0),  # the unloaded profile is always fitted
                    ]
                )
            )
        if last or (level == 1 and compliance == 0.0):
            stage_model = model
        else:
            stage_model = _Model(
                x[rows],
                loads[cases],
                xfs[cases],
                y[cases][:, rows],
                noise_m,
                bc[rows],
                knots_q,
                smoothing,
            )
        stage_model.compliance = compliance
        if last:
            budget, stage_rtol = max_steps - total[0], rtol
        elif rigid:
            budget, stage_rtol = COARSE_STEPS, COARSE_RTOL
        else:
            budget, stage_rtol = STAGE_STEPS, STAGE_RTOL
        theta, converged, message = levenberg_marquardt(
            stage_model, theta, max(budget, 1), stage_rtol
        )
        messages.append(message)
    if fine is not None:
        # the last stage on the finer model grid (θ carries over: c's B-spline and 1/EI's
        # hats are functions of X), residuals at the measured nodes only
        x_f, obs = fine
        bc_f = BSpline.design_matrix(x_f, knots_c, 3).toarray()
        model = _Model(x_f, loads, xfs, y, noise_m, bc_f, knots_q, smoothing, obs=obs)
        gauge = model.line_c @ model.line_c.T / s2
        theta, converged, message = levenberg_marquardt(
            model, theta, max(max_steps - total[0], FINE_STEPS), rtol
        )
        messages.append(message)
    message = messages[-1]
    steps = total[0]
    # covariance at the final point (scaled by the misfit over the noise)
    ssr, per, jtj, jtr, ok = model.evaluate(theta, jacobian=True)
    h, _ = normal(jtj, jtr, theta)
    misfit = float(np.sqrt(ssr / y.size))
    sigma_ratio = misfit / noise_m
    h_inv = _scaled_inverse(h)
    cov = h_inv * sigma_ratio**2
    # the share of each γ knot's estimate set by the data, not by the prior (model resolution)
    resolution = np.einsum("ij,ji->i", h_inv[nc:], jtj[:, nc:] / s2)
    # remove the line gauge from c's block (a line does not change any gap)
    proj = np.eye(theta.size)
    proj[:nc, :nc] -= model.line_c @ model.line_c.T
    cov = proj @ cov @ proj.T
    return ForwardFit(
        beam=model.beam(theta),
        camber_coefficients=theta[:nc].copy(),
        camber_knots_m=knots_c,
        kinks_m=kinks,
        stiffness_knots_m=knots_q,
        log_compliance=theta[nc:].copy(),
        covariance=0.5 * (cov + cov.T),
        misfit_m=misfit,
        case_misfit_m=np.sqrt(per / y.shape[1]),
        converged=converged and ok,
        iterations=steps,
        message=message if ok else message + "; a contact solve did not converge",
        solve_time_s=time.perf_counter() - t0,
        history_m=history,
        objective=float(model.objective(ssr, theta)),
        stiffness_resolution=resolution,
    )
