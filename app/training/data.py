"""Training data of the camber network: checks, the split by load case, arrays from a ski file.

numpy only (no torch): the upload check of a camber CSV uses it where torch is not installed.
"""

from __future__ import annotations

import numpy as np
from skisnow.solvers.errors import InputError

__all__ = [
    "HELD_OUT_FRACTION",
    "HELD_OUT_SEED",
    "MIN_GAP_M",
    "camber_training_arrays",
    "check_training_data",
    "draw_held_out",
    "job_held_out",
    "present_unloaded",
    "same_cases",
    "split_load_cases",
]

#: most negative measured gap accepted: device noise around a touching point [m]
MIN_GAP_M = -50e-6

#: fraction of the loaded cases a ski job holds out from both of its models, and the seed of
#: the draw (:func:`draw_held_out`; the identification's former own draw was 20 %, seed 0)
HELD_OUT_FRACTION = 0.2
HELD_OUT_SEED = 0


def _interior(f: np.ndarray, xf: np.ndarray) -> np.ndarray:
    """Indices of the loaded cases (F > 0) that are neither at the smallest nor the largest
    loaded F nor x_F (with one load position: interior in F only). The unloaded cases (F = 0)
    are never interior: they are never held out."""
    loaded = f > 0
    if not loaded.any():
        return np.zeros(0, dtype=int)
    fl, xl = f[loaded], xf[loaded]
    inner = loaded & (f > fl.min()) & (f < fl.max())
    if xl.max() > xl.min():
        inner &= (xf > xl.min()) & (xf < xl.max())
    return np.flatnonzero(inner)


def draw_held_out(
    loads_n: np.ndarray,
    load_positions_m: np.ndarray,
    *,
    fraction: float = HELD_OUT_FRACTION,
    seed: int = HELD_OUT_SEED,
) -> np.ndarray:
    """The load cases a ski job holds out from both its models (the camber network and the
    identified beam), so that both are judged on the same measured cases they have not seen.

    Drawn (``numpy.random.default_rng(seed)``) only from the interior loaded cases (neither the
    smallest nor the largest loaded F nor x_F, :func:`split_load_cases`'s rule): the network
    does not extrapolate, so a held-out case must lie inside its training range. The unloaded
    profile (F = 0) is never held out. ``round(fraction × number of loaded cases)`` cases, at
    least one when ``fraction > 0``.

    Returns
    -------
    ndarray of int
        Sorted indices into ``loads_n``.

    Raises
    ------
    InputError
        ``fraction`` outside [0, 0.5), or too few interior cases to hold that many out.
    """
    f = np.asarray(loads_n, dtype=float)
    xf = np.asarray(load_positions_m, dtype=float)
    if not 0 <= fraction < 0.5:
        raise InputError(f"held-out fraction must be in [0, 0.5), got {fraction}")
    n_loaded = int((f > 0).sum())
    count = max(1, round(fraction * n_loaded)) if fraction > 0 else 0
    interior = _interior(f, xf)
    if count > interior.size:
        raise InputError(
            f"{n_loaded} loaded cases have only {interior.size} interior cases (neither the "
            f"lightest nor the heaviest load, nor the first or last position), need {count} to "
            "hold out; measure more load cases"
        )
    return np.sort(np.random.default_rng(seed).permutation(interior)[:count])


def present_unloaded(
    loads_n: np.ndarray, load_positions_m: np.ndarray, profiles_m: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The training cases with the unloaded profile (F = 0) presented at every measured load
    position **(choice)**.

    With no load the profile does not depend on x_F (the ski rests on its two unloaded
    contacts), so the one measured unloaded profile is the network's answer at F = 0 for every
    x_F. Presented at every distinct x_F of the loaded cases, it pins the whole F = 0 edge of
    the network's input range; a single sample at its recorded (ignored, conventionally 0)
    position would leave that edge free elsewhere. Several unloaded cases (e.g. recorded at
    different positions) are averaged into one profile first. The loaded cases keep their
    indices (the unloaded rows come after them).

    Returns
    -------
    loads_n, load_positions_m, profiles_m, n_unloaded
        The loaded cases in their order, then the unloaded profile once per load position;
        ``n_unloaded`` the number of unloaded cases measured (0: arrays unchanged).
    """
    f = np.asarray(loads_n, dtype=float)
    xf = np.asarray(load_positions_m, dtype=float)
    h = np.asarray(profiles_m, dtype=float)
    zero = f == 0
    if not zero.any():
        return f, xf, h, 0
    loaded = ~zero
    positions = np.unique(xf[loaded]) if loaded.any() else np.zeros(1)
    unloaded = h[zero].mean(axis=0)
    return (
        np.concatenate([f[loaded], np.zeros(positions.size)]),
        np.concatenate([xf[loaded], positions]),
        np.concatenate([h[loaded], np.repeat(unloaded[None, :], positions.size, axis=0)]),
        int(zero.sum()),
    )


def split_load_cases(
    loads_n: np.ndarray,
    load_positions_m: np.ndarray,
    *,
    validation_fraction: float = 0.15,
    test_fraction: float = 0.15,
    seed: int = 0,
    test_index: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Split load cases into train / validation / test index sets (by whole load case).

    Held-out cases are drawn only from interior loaded cases (not at the min or max of the
    loaded F or of x_F), so they lie within the range of the training cases; the unloaded
    profile (F = 0) always trains. Every set gets at least one case when its fraction is > 0
    and enough interior cases exist.

    Parameters
    ----------
    loads_n, load_positions_m : ndarray, shape (K,)
        Load cases (F [N], x_F [m]).
    validation_fraction, test_fraction : float
        Fractions of the loaded cases (F > 0) to hold out [-].
    seed : int
        Seed of the numpy generator that draws the held-out cases.
    test_index : ndarray of int, optional
        The test cases, chosen by the caller (a ski job's one held-out draw for both its
        models, :func:`draw_held_out`); ``test_fraction`` is then ignored and the validation
        cases are drawn from the other interior cases.

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
    interior = _interior(f, xf)
    n_loaded = int((f > 0).sum())  # fractions of the measured loaded cases (F = 0 always trains)
    n_val = max(1, round(validation_fraction * n_loaded)) if validation_fraction > 0 else 0
    if test_index is not None:
        test = np.unique(np.asarray(test_index, dtype=int))
        if test.size and (test.min() < 0 or test.max() >= k or not np.isin(test, interior).all()):
            raise InputError(
                "test_index must name interior loaded cases (neither the lightest nor the "
                "heaviest load, nor the first or last position, never the unloaded profile)"
            )
        rest = np.setdiff1d(interior, test)
        if n_val > rest.size:
            raise InputError(
                f"{k} load cases have only {rest.size} interior cases besides the {test.size} "
                f"held out, need {n_val} for validation; measure more load cases"
            )
        val = np.sort(np.random.default_rng(seed).permutation(rest)[:n_val])
        train = np.setdiff1d(np.arange(k), np.concatenate([val, test]))
        return {"train": train, "validation": val, "test": test}
    n_test = max(1, round(test_fraction * n_loaded)) if test_fraction > 0 else 0
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
    or loads < 0 (:class:`InputError` naming the offender). A load of 0 N is the unloaded
    profile (its load position is ignored), which trains the network's F = 0 edge."""
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
    if (f < 0).any():
        raise InputError(f"loads_n must be >= 0 (0 N: the unloaded profile), got min {f.min():g} N")
    if not (f > 0).any():
        raise InputError("loads_n has no loaded case (F > 0): the unloaded profile alone")


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


def same_cases(f_n, xf_m, loads_n, positions_m) -> np.ndarray:
    """Indices into (``loads_n`` [N], ``positions_m`` [m]) of the cases (``f_n``, ``xf_m``)
    (the network's cases and the identification's may be ordered differently)."""
    keys = {
        (round(float(a), 9), round(float(b), 9)): k
        for k, (a, b) in enumerate(zip(loads_n, positions_m, strict=True))
    }
    return np.array(
        [keys[(round(float(a), 9), round(float(b), 9))] for a, b in zip(f_n, xf_m, strict=True)],
        dtype=int,
    )


def job_held_out(data, mean_cases) -> tuple[np.ndarray, np.ndarray]:
    """The cases a ski job holds out of both its models: the seeded draw
    (:func:`draw_held_out`, HELD_OUT_FRACTION, HELD_OUT_SEED) on the network's cases of
    ``data`` (:func:`camber_training_arrays`), and the same cases as indices into
    ``mean_cases`` = (F [N], x_F [m]) of :func:`app.storage.skis.mean_profiles`, the
    identification's cases. Returns (network indices, identification indices, sorted)."""
    _, _, f, xf, _, _ = camber_training_arrays(data)
    held_t = draw_held_out(f, xf, fraction=HELD_OUT_FRACTION, seed=HELD_OUT_SEED)
    fm, xfm = mean_cases
    return held_t, np.sort(same_cases(f[held_t], xf[held_t], fm, xfm))
