"""The technician's flex sheet: wax pocket, closing load, kick-zone load, wheelbase, glide check.

What a camber device (SkiSelector, Sentax, a Gear West flex tester, a Caldwell flex sheet) reads
off a classic ski pressed onto its rigid flat, computed from any profile model that answers the
loaded gap H*(X) for a load F at x_F (docs/physics.md §4 step 1; :func:`beam_profile` for a
:class:`solvers.beam.BeamSki`). Pure kernels: arrays, SI floats and a profile callable in,
frozen dataclasses out; no I/O, no settings.

Conventions (SI inside; docs/flex.md)
-------------------------------------
Positions X [m]
    From the balance point, positive towards the tip (as :class:`solvers.beam.BeamSki`): "8 cm
    behind the balance point" is ``x_F = −0.08 m``.
Loads F [N]
    One point load on the ski at x_F, pointing down. Body weight W [N]; "half weight" is W/2
    (the skier on both skis), "full weight" W (on one ski).
Wax pocket at threshold t [m]
    The contiguous zone around the foot x_F where the loaded gap is ≥ t: from the foot, walk
    towards the tail and towards the tip until the gap first falls below t; the ends are placed
    by linear interpolation of the gap between the two nodes around the crossing (the foot is
    inserted as a node with its interpolated gap). When the gap under the foot is below t the
    pocket is closed: length 0, ends NaN. A pocket open to the end of the profile ends there.
    The shops' thresholds are :data:`WAX_GAPS_M` (≈ 2 / 3 / 4 / 6 layers of hard wax).
Wax zone
    The pocket at :data:`CLOSED_GAP_M` (0.10 mm) under half weight at :data:`POCKET_POSITION_M`:
    where the kick wax goes. The kick-zone load share and the glide check refer to this fixed
    span.
Residual camber r(F) [m]
    The loaded gap under the foot x_F: the pocket at t is open exactly while r ≥ t (a point
    load bends the ski most under itself, so the gap under the foot is the first to close and
    falls monotonically with F). "Closed" means r ≤ :data:`CLOSED_GAP_M`.
Closing load [N]
    The smallest F at x_F with r(F) ≤ 0.10 mm (the paper under the foot is clamped), by
    bisection on F to ``closing_tol_n`` (default :data:`CLOSING_TOL_N`, 0.05 kg): the answer
    is the middle of the last bracket, within ``tol/2`` of the discrete model's closing load.
    NaN when the pocket does not close up to ``max_load_n``, or is closed already at
    ``min_load_n`` (``closed_at_min``; the profile model's range ends there). At the closing load
    the wax zone ahead of and behind the foot may still stand open (``wax_zone_max_gap_m``).
Kick-zone load share [-]
    Contact force on the nodes inside the wax zone (ends included) over the total contact
    force, under full and under half weight at x_F. On the rigid flat it is zero at half
    weight by construction (the wax zone is open there); on snow (the bending ski,
    :mod:`solvers.flexible`) the service passes the row forces to :func:`span_load_share`.
Wheelbase [m]
    Distance between the rear and the front contact zones under full weight at x_F: from the
    front end of the last contact run that starts behind the wax zone to the rear end of the
    first contact run that ends ahead of it (runs: nodes with gap ≤ ``contact_gap_m``; the foot
    stands in for a closed wax zone). ``centroid_distance_m`` is the
    distance between the two zones' force centroids (their geometric midpoints without
    reactions).
Glide check
    Full weight at :data:`GLIDE_POSITION_M` (15 cm behind the balance point): the pocket stays
    open in front of the foot when the gap is ≥ 0.10 mm everywhere on the wax zone ahead of the
    foot, ``[max(x_glide, wax start), wax end]``; ``open_length_m`` is how much of that span is.

Every length is exact for the discrete profile up to the linear interpolation of the gap
between nodes (≤ one node spacing); loads are within the bisection tolerance.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from skisnow.solvers.beam import G_STANDARD, BeamFlexibility, BeamSki, solve_beam_contact
from skisnow.solvers.errors import InputError, NotConvergedError

__all__ = [
    "CLOSED_GAP_M",
    "CLOSING_TOL_N",
    "CONTACT_GAP_M",
    "GLIDE_POSITION_M",
    "POCKET_POSITION_M",
    "WAX_GAPS_M",
    "ClosingLoad",
    "ContactZones",
    "FlatProfile",
    "FlexSheet",
    "GlideCheck",
    "Pocket",
    "beam_profile",
    "closing_load",
    "contact_zones",
    "flex_sheet",
    "glide_check",
    "pocket",
    "residual_camber",
    "span_load_share",
    "wax_zone_max_gap",
]

#: the shops' wax-pocket thresholds [m]: about 2 / 3 / 4 / 6 layers of hard wax
WAX_GAPS_M = (0.10e-3, 0.15e-3, 0.20e-3, 0.30e-3)
#: "closed" means this much residual camber [m]
CLOSED_GAP_M = 0.10e-3
#: where the pocket is read: 8 cm behind the balance point [m]
POCKET_POSITION_M = -0.08
#: where the glide check loads the ski: 15 cm behind the balance point [m]
GLIDE_POSITION_M = -0.15
#: bisection tolerance of the closing load: 0.05 kg [N]
CLOSING_TOL_N = 0.05 * G_STANDARD
#: a node touches the flat when its gap is at most this [m] (the beam's contact gap is exactly 0)
CONTACT_GAP_M = 1e-9


@dataclass(frozen=True)
class FlatProfile:
    """A loaded profile on the rigid flat.

    Attributes
    ----------
    positions_m : ndarray (N,)
        X [m], increasing.
    gap_m : ndarray (N,)
        Loaded gap H*(X) ≥ 0 [m].
    reaction_n : ndarray (N,) or None
        Nodal contact forces of the flat [N] (None for a model without them, e.g. the network).
    load_n, load_position_m : float
        F [N] and x_F [m].
    """

    positions_m: np.ndarray
    gap_m: np.ndarray
    reaction_n: np.ndarray | None
    load_n: float
    load_position_m: float


#: a profile model: (F [N], x_F [m]) → the loaded profile on the rigid flat
ProfileFn = Callable[[float, float], FlatProfile]


@dataclass(frozen=True)
class Pocket:
    """The wax pocket at one threshold (module docstring).

    Attributes
    ----------
    threshold_m : float
        Gap threshold t [m].
    start_m, end_m : float
        Rear and front end [m]; NaN when closed.
    length_m : float
        ``end − start`` [m]; 0 when closed.
    foot_gap_m : float
        Gap under the foot [m].
    """

    threshold_m: float
    start_m: float
    end_m: float
    length_m: float
    foot_gap_m: float

    @property
    def is_open(self) -> bool:
        return self.length_m > 0


@dataclass(frozen=True)
class ClosingLoad:
    """Closing load and its bisection diagnostics.

    Attributes
    ----------
    load_n : float
        Closing load [N]; NaN when the pocket does not close up to ``max_load_n``.
    residual_gap_m : float
        Residual camber r at the upper end of the last bracket [m] (≤ the closed gap) or at
        ``max_load_n`` when it does not close.
    wax_zone_max_gap_m : float
        Largest gap over the wax zone at the upper end of the last bracket [m] (NaN without a
        wax zone).
    bracket_n : tuple of float
        Last bracket (open, closed) [N].
    tolerance_n : float
        Bisection tolerance [N]: ``load_n`` is within half of it of the discrete model's value.
    max_load_n : float
        Largest load tried [N].
    closes : bool
        The pocket closed at or below ``max_load_n``.
    closed_at_min : bool
        It is closed already at ``min_load_n``, the smallest load tried: ``load_n`` is NaN and
        the closing load is somewhere below (the profile model is not asked below its range).
    converged, iterations, message :
        Diagnostics (``iterations``: profile solves).
    """

    load_n: float
    residual_gap_m: float
    wax_zone_max_gap_m: float
    bracket_n: tuple[float, float]
    tolerance_n: float
    max_load_n: float
    closes: bool
    closed_at_min: bool
    converged: bool
    iterations: int
    message: str

    def closed_at(self, load_n: float) -> bool:
        """The pocket is closed under ``load_n`` [N] (by the bisection's answer)."""
        return self.closes and (self.closed_at_min or self.load_n <= load_n)


@dataclass(frozen=True)
class ContactZones:
    """Rear and front contact zones around the wax zone and the wheelbase between them.

    Attributes
    ----------
    rear_m, front_m : tuple of float
        (start, end) of the rear and front zone [m]; NaN when there is none.
    wheelbase_m : float
        Front zone start − rear zone end [m]; NaN when a zone is missing.
    centroid_distance_m : float
        Distance between the zones' force centroids [m] (geometric midpoints without
        reactions); NaN when a zone is missing.
    """

    rear_m: tuple[float, float]
    front_m: tuple[float, float]
    wheelbase_m: float
    centroid_distance_m: float


@dataclass(frozen=True)
class GlideCheck:
    """Full weight at the glide position: does the wax zone stay open in front of the foot?

    Attributes
    ----------
    load_n, load_position_m : float
        F [N] and x_F [m] of the check.
    span_m : tuple of float
        The checked span of the wax zone ahead of the foot [m]; NaN when empty.
    min_gap_m : float
        Smallest gap on the span [m]; NaN when the span is empty.
    open_length_m : float
        Length of the span where the gap is ≥ the closed gap [m].
    passed : bool
        The span is non-empty and ``min_gap_m ≥`` the closed gap.
    """

    load_n: float
    load_position_m: float
    span_m: tuple[float, float]
    min_gap_m: float
    open_length_m: float
    passed: bool


@dataclass(frozen=True)
class FlexSheet:
    """Every number of the flex sheet on the rigid flat (module docstring for definitions).

    Attributes
    ----------
    body_weight_n, pocket_position_m, glide_position_m : float
        W [N], x_F of the pocket [m], x_F of the glide check [m].
    pockets_half, pockets_full : tuple of Pocket
        Pockets at each of ``wax_gaps_m`` under W/2 and W at the pocket position.
    wax_zone : Pocket
        The pocket at the closed gap under W/2 (the span of the next quantities).
    closing : ClosingLoad
    kick_share_half, kick_share_full : float
        Kick-zone load share under W/2 and W [-]; NaN without reactions.
    zones : ContactZones
        Under W at the pocket position.
    glide : GlideCheck
    half, full : FlatProfile
        The profiles under W/2 and W at the pocket position (for plots).
    glide_profile : FlatProfile
    """

    body_weight_n: float
    pocket_position_m: float
    glide_position_m: float
    pockets_half: tuple[Pocket, ...]
    pockets_full: tuple[Pocket, ...]
    wax_zone: Pocket
    closing: ClosingLoad
    kick_share_half: float
    kick_share_full: float
    zones: ContactZones
    glide: GlideCheck
    half: FlatProfile
    full: FlatProfile
    glide_profile: FlatProfile

    def scalars(self) -> dict[str, float]:
        """The sheet's numbers by name, SI units in the names (bands and pair differences)."""
        out: dict[str, float] = {}
        for tag, pockets in (("half", self.pockets_half), ("full", self.pockets_full)):
            for p in pockets:
                key = f"pocket_{tag}_{p.threshold_m * 1e3:.2f}mm"
                out[f"{key}_length_m"] = p.length_m
                out[f"{key}_start_m"] = p.start_m
                out[f"{key}_end_m"] = p.end_m
        out["foot_gap_half_m"] = self.wax_zone.foot_gap_m
        out["closing_load_n"] = self.closing.load_n
        out["kick_share_half"] = self.kick_share_half
        out["kick_share_full"] = self.kick_share_full
        out["wheelbase_m"] = self.zones.wheelbase_m
        out["glide_min_gap_m"] = self.glide.min_gap_m
        out["glide_open_length_m"] = self.glide.open_length_m
        return out


# ----------------------------------------------------------------------------- pieces


def _check_profile(positions_m: np.ndarray, gap_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(positions_m, dtype=float)
    g = np.asarray(gap_m, dtype=float)
    if x.ndim != 1 or x.size < 2 or g.shape != x.shape:
        raise InputError(
            f"positions_m and gap_m must be 1-D of one length ≥ 2, got {x.shape}, {g.shape}"
        )
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(g))):
        raise InputError("positions_m and gap_m must be finite")
    if np.any(np.diff(x) <= 0):
        raise InputError("positions_m must be increasing")
    return x, g


def _with_node(x: np.ndarray, g: np.ndarray, at_m: float) -> tuple[np.ndarray, np.ndarray, int]:
    """The profile with a node at ``at_m`` (gap interpolated) and that node's index."""
    if not (x[0] <= at_m <= x[-1]):
        raise InputError(f"position {at_m!r} m is outside the profile ({x[0]:g} … {x[-1]:g} m)")
    k = int(np.searchsorted(x, at_m))
    if k < x.size and x[k] == at_m:
        return x, g, k
    return np.insert(x, k, at_m), np.insert(g, k, np.interp(at_m, x, g)), k


def _crossing(x0: float, g0: float, x1: float, g1: float, t: float) -> float:
    """Where the gap, linear between (x0, g0) and (x1, g1), equals t."""
    if g1 == g0:
        return 0.5 * (x0 + x1)
    return x0 + (t - g0) / (g1 - g0) * (x1 - x0)


def pocket(positions_m: np.ndarray, gap_m: np.ndarray, foot_m: float, threshold_m: float) -> Pocket:
    """The wax pocket at ``threshold_m`` [m] around the foot ``foot_m`` [m] (module docstring).

    Parameters
    ----------
    positions_m, gap_m : ndarray (N,)
        Loaded profile X [m] and H*(X) [m].
    foot_m : float
        Foot position x_F [m] inside the profile.
    threshold_m : float
        Gap threshold t > 0 [m].
    """
    if not (math.isfinite(threshold_m) and threshold_m > 0):
        raise InputError(f"threshold_m must be finite and > 0, got {threshold_m!r}")
    x, g = _check_profile(positions_m, gap_m)
    xs, gs, m = _with_node(x, g, float(foot_m))
    foot_gap = float(gs[m])
    nan = float("nan")
    if foot_gap < threshold_m:
        return Pocket(threshold_m, nan, nan, 0.0, foot_gap)
    below = gs < threshold_m
    behind = np.flatnonzero(below[:m])
    if behind.size:
        j = int(behind[-1])
        start = _crossing(xs[j], gs[j], xs[j + 1], gs[j + 1], threshold_m)
    else:
        start = float(xs[0])
    ahead = np.flatnonzero(below[m + 1 :])
    if ahead.size:
        j = int(ahead[0]) + m + 1
        end = _crossing(xs[j - 1], gs[j - 1], xs[j], gs[j], threshold_m)
    else:
        end = float(xs[-1])
    return Pocket(threshold_m, float(start), float(end), float(end - start), foot_gap)


def _span_gaps(x: np.ndarray, g: np.ndarray, span: tuple[float, float]) -> np.ndarray:
    """The gap at the span's ends (interpolated) and at every node inside it."""
    a, b = span
    inside = (x > a) & (x < b)
    return np.concatenate([[np.interp(a, x, g)], g[inside], [np.interp(b, x, g)]])


def residual_camber(profile: FlatProfile) -> float:
    """Residual camber r [m]: the gap under the foot of ``profile`` (module docstring)."""
    x, g = _check_profile(profile.positions_m, profile.gap_m)
    return float(np.interp(profile.load_position_m, x, g))


def wax_zone_max_gap(profile: FlatProfile, wax_zone: Pocket) -> float:
    """Largest gap [m] of ``profile`` over the wax zone (NaN when the wax zone is closed)."""
    if not wax_zone.is_open:
        return float("nan")
    x, g = _check_profile(profile.positions_m, profile.gap_m)
    return float(np.max(_span_gaps(x, g, (wax_zone.start_m, wax_zone.end_m))))


def span_load_share(
    positions_m: np.ndarray, force_n: np.ndarray, span_m: tuple[float, float]
) -> float:
    """Share [-] of the total force on the nodes (or pixel rows) inside ``span_m`` (ends
    included) over the total force; 0 for an empty (NaN) span, NaN when the total is not > 0.

    Parameters
    ----------
    positions_m : ndarray (N,)
        Node or row positions X [m].
    force_n : ndarray (N,)
        Contact force per node or row [N], ≥ 0.
    span_m : tuple of float
        (start, end) [m].
    """
    x = np.asarray(positions_m, dtype=float)
    f = np.asarray(force_n, dtype=float)
    if f.shape != x.shape:
        raise InputError(f"force_n has shape {f.shape}, expected {x.shape}")
    total = float(np.sum(f))
    if not total > 0:
        return float("nan")
    a, b = span_m
    if not (math.isfinite(a) and math.isfinite(b)):
        return 0.0
    inside = (x >= a) & (x <= b)
    return float(np.sum(f[inside]) / total)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1) - 1
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


def contact_zones(
    profile: FlatProfile, wax_zone: Pocket, *, contact_gap_m: float = CONTACT_GAP_M
) -> ContactZones:
    """The contact zones behind and ahead of the wax zone (or of the foot when the wax zone is
    closed) and the wheelbase between them (module docstring). One run reaching from behind
    the wax zone to ahead of it (the ski touching all along) gives NaN."""
    x, g = _check_profile(profile.positions_m, profile.gap_m)
    if wax_zone.is_open:
        rear_limit, front_limit = wax_zone.start_m, wax_zone.end_m
    else:
        rear_limit = front_limit = profile.load_position_m
    runs = _runs(g <= contact_gap_m)
    # a zone may reach into the wax zone (full weight closes it from its ends): the rear zone
    # is the last run that starts behind the wax zone, the front one the first that ends ahead
    rear = [r for r in runs if x[r[0]] < rear_limit]
    front = [r for r in runs if x[r[1]] > front_limit]
    nan = float("nan")
    if not rear or not front or rear[-1] == front[0]:
        return ContactZones((nan, nan), (nan, nan), nan, nan)
    r, f = rear[-1], front[0]
    rear_m = (float(x[r[0]]), float(x[r[1]]))
    front_m = (float(x[f[0]]), float(x[f[1]]))

    def centroid(run: tuple[int, int]) -> float:
        sl = slice(run[0], run[1] + 1)
        if profile.reaction_n is not None:
            w = np.asarray(profile.reaction_n, dtype=float)[sl]
            if np.sum(w) > 0:
                return float(np.sum(w * x[sl]) / np.sum(w))
        return float(0.5 * (x[run[0]] + x[run[1]]))

    return ContactZones(rear_m, front_m, front_m[0] - rear_m[1], centroid(f) - centroid(r))


def glide_check(profile: FlatProfile, wax_zone: Pocket, closed_gap_m: float = CLOSED_GAP_M):
    """The glide check of ``profile`` (full weight at the glide position) against the wax zone
    (module docstring)."""
    x, g = _check_profile(profile.positions_m, profile.gap_m)
    nan = float("nan")
    a = max(profile.load_position_m, wax_zone.start_m) if wax_zone.is_open else nan
    b = wax_zone.end_m if wax_zone.is_open else nan
    if not (math.isfinite(a) and math.isfinite(b) and b > a):
        return GlideCheck(profile.load_n, profile.load_position_m, (nan, nan), nan, 0.0, False)
    xs = np.concatenate([[a], x[(x > a) & (x < b)], [b]])
    gs = _span_gaps(x, g, (a, b))
    # open length: integrate the indicator gap ≥ closed with the crossings interpolated
    open_len = 0.0
    for i in range(xs.size - 1):
        g0, g1 = gs[i], gs[i + 1]
        o0, o1 = g0 >= closed_gap_m, g1 >= closed_gap_m
        if o0 and o1:
            open_len += xs[i + 1] - xs[i]
        elif o0 != o1:
            c = _crossing(xs[i], g0, xs[i + 1], g1, closed_gap_m)
            open_len += (c - xs[i]) if o0 else (xs[i + 1] - c)
    min_gap = float(np.min(gs))
    return GlideCheck(
        profile.load_n,
        profile.load_position_m,
        (float(a), float(b)),
        min_gap,
        float(open_len),
        bool(min_gap >= closed_gap_m),
    )


def closing_load(
    profile_fn: ProfileFn,
    load_position_m: float,
    *,
    open_load_n: float,
    max_load_n: float,
    min_load_n: float = 0.0,
    wax_zone: Pocket | None = None,
    closed_gap_m: float = CLOSED_GAP_M,
    tol_n: float = CLOSING_TOL_N,
    max_iterations: int = 60,
) -> ClosingLoad:
    """The closing load at ``load_position_m`` [m] by bisection (module docstring).

    Parameters
    ----------
    profile_fn : callable
        (F [N], x_F [m]) → :class:`FlatProfile`.
    load_position_m : float
        Foot position x_F [m].
    open_load_n : float
        Where the search starts [N], > 0 (half the body weight): the bracket grows ×2 from there
        until the pocket is closed, or the search goes down to 0 when it is closed already.
    max_load_n : float
        Largest load to try [N] (the profile model's range).
    min_load_n : float
        Smallest load to try [N], ≥ 0 (the profile model's range).
    wax_zone : Pocket, optional
        Reports ``wax_zone_max_gap_m`` at the closing load.
    closed_gap_m, tol_n : float
        Closed gap [m] and bisection tolerance [N].
    """
    for name, v in (("open_load_n", open_load_n), ("max_load_n", max_load_n), ("tol_n", tol_n)):
        if not (math.isfinite(v) and v > 0):
            raise InputError(f"{name} must be finite and > 0, got {v!r}")
    if not (math.isfinite(min_load_n) and 0 <= min_load_n < max_load_n):
        raise InputError(f"min_load_n must be in [0, max_load_n), got {min_load_n!r}")
    solves = 0
    zone = wax_zone if wax_zone is not None else Pocket(closed_gap_m, math.nan, math.nan, 0, 0)

    def solve(f: float) -> tuple[float, float]:
        nonlocal solves
        solves += 1
        p = profile_fn(f, load_position_m)
        return residual_camber(p), wax_zone_max_gap(p, zone)

    lo = min(max(open_load_n, min_load_n), max_load_n)
    r_lo, z_lo = solve(lo)
    if r_lo <= closed_gap_m:
        if min_load_n > 0:
            r_min, z_min = solve(min_load_n) if lo > min_load_n else (r_lo, z_lo)
            if r_min <= closed_gap_m:
                return ClosingLoad(
                    float("nan"),
                    r_min,
                    z_min,
                    (float("nan"), min_load_n),
                    tol_n,
                    max_load_n,
                    True,
                    True,
                    True,
                    solves,
                    f"closed already at {min_load_n:.4g} N, the smallest load tried "
                    f"(residual camber {r_min * 1e3:.3f} mm)",
                )
        lo, hi, r_hi, z_hi = min_load_n, lo, r_lo, z_lo
    else:
        hi, r_hi, z_hi = lo, r_lo, z_lo
        while r_hi > closed_gap_m:
            if hi >= max_load_n:
                return ClosingLoad(
                    float("nan"),
                    r_hi,
                    z_hi,
                    (hi, float("nan")),
                    tol_n,
                    max_load_n,
                    False,
                    False,
                    True,
                    solves,
                    f"the pocket does not close up to {max_load_n:.4g} N "
                    f"(residual camber {r_hi * 1e3:.3f} mm)",
                )
            lo = hi
            hi = min(2.0 * hi, max_load_n)
            r_hi, z_hi = solve(hi)
    it = 0
    while hi - lo > tol_n and it < max_iterations:
        mid = 0.5 * (lo + hi)
        r_mid, z_mid = solve(mid)
        if r_mid <= closed_gap_m:
            hi, r_hi, z_hi = mid, r_mid, z_mid
        else:
            lo = mid
        it += 1
    converged = hi - lo <= tol_n
    return ClosingLoad(
        0.5 * (lo + hi),
        r_hi,
        z_hi,
        (lo, hi),
        tol_n,
        max_load_n,
        True,
        False,
        converged,
        solves,
        "bracket within tolerance" if converged else f"stopped after {it} bisections",
    )


def beam_profile(ski: BeamSki, flexibility: BeamFlexibility | None = None) -> ProfileFn:
    """A :data:`ProfileFn` of a beam ski on the rigid flat (:func:`solvers.beam.solve_beam_contact`;
    raises :class:`NotConvergedError` when a solve does not converge)."""
    flex = flexibility if flexibility is not None else BeamFlexibility(ski)

    def fn(load_n: float, load_position_m: float) -> FlatProfile:
        res = solve_beam_contact(ski, load_n, load_position_m, flexibility=flex)
        if not res.converged:
            raise NotConvergedError(f"beam on the flat did not converge: {res.message}")
        return FlatProfile(res.positions_m, res.gap_m, res.reaction_n, load_n, load_position_m)

    return fn


def flex_sheet(
    profile_fn: ProfileFn,
    body_weight_n: float,
    *,
    pocket_position_m: float = POCKET_POSITION_M,
    glide_position_m: float = GLIDE_POSITION_M,
    wax_gaps_m: Sequence[float] = WAX_GAPS_M,
    closed_gap_m: float = CLOSED_GAP_M,
    closing_tol_n: float = CLOSING_TOL_N,
    max_closing_load_n: float | None = None,
    min_closing_load_n: float = 0.0,
    contact_gap_m: float = CONTACT_GAP_M,
) -> FlexSheet:
    """The flex sheet of one ski on the rigid flat (module docstring).

    Parameters
    ----------
    profile_fn : callable
        (F [N], x_F [m]) → :class:`FlatProfile` (:func:`beam_profile`).
    body_weight_n : float
        Skier's weight W [N], > 0.
    pocket_position_m, glide_position_m : float
        Foot positions of the pocket and of the glide check [m] (negative: behind the balance
        point).
    wax_gaps_m : sequence of float
        Pocket thresholds [m].
    closed_gap_m : float
        "Closed" residual camber [m].
    closing_tol_n : float
        Bisection tolerance of the closing load [N].
    max_closing_load_n : float, optional
        Largest load the closing search tries [N]; default 3 W.
    min_closing_load_n : float
        Smallest load the closing search tries [N] (the profile model's range).
    contact_gap_m : float
        A node touches when its gap is at most this [m] (wheelbase): 0 for a beam, about the
        model's error for a profile model whose contact is not exactly 0.
    """
    if not (math.isfinite(body_weight_n) and body_weight_n > 0):
        raise InputError(f"body_weight_n must be finite and > 0, got {body_weight_n!r}")
    if not all(math.isfinite(t) and t > 0 for t in wax_gaps_m) or not wax_gaps_m:
        raise InputError(f"wax_gaps_m must be finite and > 0, got {list(wax_gaps_m)!r}")
    w = float(body_weight_n)
    half = profile_fn(0.5 * w, pocket_position_m)
    full = profile_fn(w, pocket_position_m)
    glide_p = profile_fn(w, glide_position_m)
    pockets_half = tuple(
        pocket(half.positions_m, half.gap_m, pocket_position_m, t) for t in wax_gaps_m
    )
    pockets_full = tuple(
        pocket(full.positions_m, full.gap_m, pocket_position_m, t) for t in wax_gaps_m
    )
    wax = pocket(half.positions_m, half.gap_m, pocket_position_m, closed_gap_m)
    closing = closing_load(
        profile_fn,
        pocket_position_m,
        wax_zone=wax,
        open_load_n=0.5 * w,
        max_load_n=3.0 * w if max_closing_load_n is None else max_closing_load_n,
        min_load_n=min_closing_load_n,
        closed_gap_m=closed_gap_m,
        tol_n=closing_tol_n,
    )
    span = (wax.start_m, wax.end_m)

    def share(p: FlatProfile) -> float:
        if p.reaction_n is None:
            return float("nan")
        return span_load_share(p.positions_m, p.reaction_n, span)

    return FlexSheet(
        body_weight_n=w,
        pocket_position_m=float(pocket_position_m),
        glide_position_m=float(glide_position_m),
        pockets_half=pockets_half,
        pockets_full=pockets_full,
        wax_zone=wax,
        closing=closing,
        kick_share_half=share(half),
        kick_share_full=share(full),
        zones=contact_zones(full, wax, contact_gap_m=contact_gap_m),
        glide=glide_check(glide_p, wax, closed_gap_m),
        half=half,
        full=full,
        glide_profile=glide_p,
    )
