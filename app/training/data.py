"""Training data of the camber network: checks, the split by load case, arrays from a ski file.

numpy only (no torch): the upload check of a camber CSV uses it where torch is not installed.
"""

from __future__ import annotations

import numpy as np
from skisnow.solvers.errors import InputError

__all__ = ["MIN_GAP_M", "camber_training_arrays", "check_training_data", "split_load_cases"]

#: most negative measured gap accepted: device noise around a touching point [m]
MIN_GAP_M = -50e-6


def split_load_cases(
    loads_n: np.ndarray,
    load_positions_m: np.ndarray,
    *,
    validation_fraction: float = 0.15,
    test_fraction: float = 0.15,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """Split load cases into train / validation / test index sets (by whole load case).

    Held-out cases are drawn only from interior cases (not at the min or max of F or x_F),
    so they lie within the range of the training cases. Every set gets at least one case when
    its fraction is > 0 and enough interior cases exist.

    Parameters
    ----------
    loads_n, load_positions_m : ndarray, shape (K,)
        Load cases (F [N], x_F [m]).
    validation_fraction, test_fraction : float
        Fractions of all K cases to hold out [-].
    seed : int
        Seed of the numpy generator that draws the held-out cases.

    Returns
    -------
    dict
        ``{"train": idx, "validation": idx, "test": idx}``, sorted int arrays.
    """
    f = np.asarray(loads_n, dtype=float)
    xf = np.asarray(load_positions_m, dtype=float)
    k = f.size
    for name, frac in (
        ("validation_fraction", validation_fraction),
        ("test_fraction", test_fraction),
    ):
        if not 0 <= frac < 1:
            raise InputError(f"{name} must be in [0, 1), got {frac}")
    if validation_fraction + test_fraction >= 0.8:
        raise InputError("validation_fraction + test_fraction must be < 0.8")
    interior = np.flatnonzero((f > f.min()) & (f < f.max()) & (xf > xf.min()) & (xf < xf.max()))
    if xf.max() == xf.min():  # a single load position: interior in F only
        interior = np.flatnonzero((f > f.min()) & (f < f.max()))
    n_val = max(1, round(validation_fraction * k)) if validation_fraction > 0 else 0
    n_test = max(1, round(test_fraction * k)) if test_fraction > 0 else 0
    if n_val + n_test > interior.size:
        raise InputError(
            f"{k} load cases have only {interior.size} interior cases, need {n_val + n_test} "
            "to hold out for validation and test; measure more load cases"
        )
    rng = np.random.default_rng(seed)
    held = rng.permutation(interior)
    val = np.sort(held[:n_val])
    test = np.sort(held[n_val : n_val + n_test])
    train = np.setdiff1d(np.arange(k), np.concatenate([val, test]))
    return {"train": train, "validation": val, "test": test}


def check_training_data(x, f, xf, h) -> None:
    """Refuse training arrays of the wrong shape, non-finite values, gaps below ``MIN_GAP_M``
    or loads <= 0 (:class:`InputError` naming the offender)."""
    if x.ndim != 1 or x.size < 2 or not np.all(np.diff(x) > 0):
        raise InputError("positions_m must be a strictly increasing 1-D grid of size >= 2")
    if f.ndim != 1 or xf.shape != f.shape:
        raise InputError(
            f"loads_n and load_positions_m must be 1-D of equal length, got {f.shape}, {xf.shape}"
        )
    if h.shape != (f.size, x.size):
        raise InputError(f"profiles_m must have shape ({f.size}, {x.size}), got {h.shape}")
    for name, arr in (
        ("positions_m", x),
        ("loads_n", f),
        ("load_positions_m", xf),
        ("profiles_m", h),
    ):
        if not np.all(np.isfinite(arr)):
            raise InputError(f"{name} contains NaN or inf")
    if (h < MIN_GAP_M).any():
        raise InputError(
            f"profiles_m must be >= {MIN_GAP_M:g} m (a gap; small negative readings are device "
            f"noise at contact), got min {h.min():g} m"
        )
    if (f <= 0).any():
        raise InputError(f"loads_n must be > 0, got min {f.min():g} N")


def camber_training_arrays(data) -> tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray, str]:
    """Training arrays from :class:`app.storage.skis.CamberData`.

    The network predicts one profile per load: the width mean **(choice)**. Cases measured on
    the ``mean`` side are used when present; else left and right profiles of the same load case
    are averaged; else the single measured side is used.

    Returns
    -------
    ski_id, positions_m, loads_n, load_positions_m, profiles_m, side
        ``side`` says what was used: ``"mean"``, ``"left+right"``, ``"left"`` or ``"right"``.
    """
    sides = np.asarray(list(data.sides))
    x = np.asarray(data.positions_m, dtype=float)
    f = np.asarray(data.loads_n, dtype=float)
    xf = np.asarray(data.load_positions_m, dtype=float)
    h = np.asarray(data.profiles_m, dtype=float)
    present = set(sides.tolist())
    if "mean" in present or len(present) == 1:
        side = "mean" if "mean" in present else present.pop()
        rows = sides == side
        return str(data.ski_id), x, f[rows], xf[rows], h[rows], side
    left = {(a, b): k for k, (a, b) in enumerate(zip(f, xf, strict=True)) if sides[k] == "left"}
    right = {(a, b): k for k, (a, b) in enumerate(zip(f, xf, strict=True)) if sides[k] == "right"}
    unmatched = sorted(set(left) ^ set(right))
    if unmatched:
        a, b = unmatched[0]
        raise InputError(
            f"load case F = {a:g} N, x_F = {b:g} m is measured on one side only; left and right "
            "need the same load cases to be averaged"
        )
    keys = sorted(left)
    profiles = np.array([(h[left[k]] + h[right[k]]) / 2 for k in keys])
    return (
        str(data.ski_id),
        x,
        np.array([k[0] for k in keys]),
        np.array([k[1] for k in keys]),
        profiles,
        "left+right",
    )
