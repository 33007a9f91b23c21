"""Accuracy checks of a trained camber network: held-out metrics, beam truth, contact area.

numpy and the solvers only (no torch): :func:`evaluate_network` against measured profiles,
:func:`contact_area_check` through the macro BEM, and, for a ski that stores its design beam
(the demo skis), :func:`truth_check` against the beam's noise-free profiles.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from skisnow.solvers import camber

__all__ = [
    "beam_truth_profiles",
    "contact_area_check",
    "evaluate_network",
    "store_beam_truth_check",
    "truth_check",
]


def evaluate_network(
    network: Mapping[str, object],
    loads_n: np.ndarray,
    load_positions_m: np.ndarray,
    profiles_m: np.ndarray,
    *,
    band_m: float = camber.CONTACT_BAND_M,
    contact_threshold_m: float = 5e-6,
) -> dict[str, float]:
    """Accuracy of a network on given load cases (all in metres).

    Returns
    -------
    dict
        ``rmse_band_m`` (RMSE where the true H* < band, the target ≤ 5 µm),
        ``max_abs_error_band_m``, ``rmse_m`` (all points), ``max_rmse_band_m`` (worst case),
        ``contact_fraction_error`` (mean over cases of |predicted − true| fraction of grid
        points with H* ≤ ``contact_threshold_m``, a proxy for the apparent contact length
        until the macro BEM decides it; the exact-zero set is not used because the true gap
        leaves contact like distance², so sub-µm differences move its edge by centimetres) and
        ``n_cases``.
    """
    h = np.asarray(profiles_m, dtype=float)
    pred = camber.predict_profiles(network, loads_n, load_positions_m).gaps_m
    mask = h < band_m
    err = pred - h
    per_case = [camber.contact_band_rmse_m(p, t, band_m) for p, t in zip(pred, h, strict=True)]
    return {
        "rmse_band_m": float(np.sqrt(np.mean(err[mask] ** 2))) if mask.any() else float("nan"),
        "max_abs_error_band_m": float(np.abs(err[mask]).max()) if mask.any() else float("nan"),
        "max_rmse_band_m": float(np.nanmax(per_case)),
        "rmse_m": float(np.sqrt(np.mean(err**2))),
        "contact_fraction_error": float(
            np.mean(
                np.abs(
                    np.mean(pred <= contact_threshold_m, axis=1)
                    - np.mean(h <= contact_threshold_m, axis=1)
                )
            )
        ),
        "n_cases": int(h.shape[0]),
    }


def contact_area_check(
    network: Mapping[str, object],
    loads_n: np.ndarray,
    load_positions_m: np.ndarray,
    true_profiles_m: np.ndarray,
    *,
    width_m: float | np.ndarray,
    effective_modulus_pa: float,
    width_positions_m: np.ndarray | None = None,
) -> dict[str, np.ndarray | float]:
    """Apparent contact area from predicted vs true profiles, through the macro BEM.

    For every load case the predicted and the true loaded profile H*(X) are extruded across the
    footprint and pressed into the snow half-space (:func:`solvers.macro.solve_macro`, default
    grid, tilt on). The accuracy target is ``|A_pred / A_true − 1| ≤ 3 %``.

    Parameters
    ----------
    network : mapping
        Camber network.
    loads_n, load_positions_m : ndarray, shape (N,)
        Load cases (F [N], x_F [m]), within the trained range.
    true_profiles_m : ndarray, shape (N, M)
        True H*(X) on the network's grid [m] (noise-free, e.g. from the beam model).
    width_m : float or ndarray
        Running-surface width [m] (array: at ``width_positions_m``).
    effective_modulus_pa : float
        E' [Pa] (docs/physics.md eq. 1).
    width_positions_m : ndarray, optional
        Positions of a width profile [m].

    Returns
    -------
    dict
        ``area_pred_m2``, ``area_true_m2``, ``relative_error`` (arrays over cases),
        ``max_abs_relative_error`` and ``converged`` (all BEM solves converged).
    """
    from skisnow.solvers.macro import extrude_profile, solve_macro

    pred = camber.predict_profiles(network, loads_n, load_positions_m)
    x = pred.positions_m
    areas = np.empty((2, pred.gaps_m.shape[0]))
    converged = True
    for k, (f, xf) in enumerate(zip(pred.loads_n, pred.load_positions_m, strict=True)):
        for j, gap in enumerate((pred.gaps_m[k], np.asarray(true_profiles_m)[k])):
            gm = extrude_profile(
                x, np.maximum(gap, 0.0), width_m, width_positions_m=width_positions_m
            )
            res = solve_macro(gm, float(f), float(xf), effective_modulus_pa)
            converged &= bool(res.converged)
            areas[j, k] = res.apparent_contact_area_m2
    rel = areas[0] / areas[1] - 1.0
    return {
        "area_pred_m2": areas[0],
        "area_true_m2": areas[1],
        "relative_error": rel,
        "max_abs_relative_error": float(np.abs(rel).max()),
        "converged": converged,
    }


def beam_truth_profiles(
    beam, positions_m: np.ndarray, loads_n: np.ndarray, load_positions_m: np.ndarray
) -> np.ndarray:
    """Noise-free loaded gaps H*(X) [m] of a beam ski at load cases (F [N], x_F [m]), shape
    (K, M), interpolated onto ``positions_m`` (:func:`solvers.beam.solve_beam_contact`)."""
    from skisnow.solvers.beam import BeamFlexibility, solve_beam_contact

    flex = BeamFlexibility(beam)
    x = np.asarray(positions_m, dtype=float)
    return np.array(
        [
            np.interp(x, beam.positions_m, solve_beam_contact(beam, f, p, flexibility=flex).gap_m)
            for f, p in zip(
                np.atleast_1d(np.asarray(loads_n, dtype=float)),
                np.atleast_1d(np.asarray(load_positions_m, dtype=float)),
                strict=True,
            )
        ]
    ).reshape(-1, x.size)


def truth_check(
    network: Mapping[str, object],
    beam,
    *,
    width_m: float | np.ndarray,
    effective_modulus_pa: float,
    n_random: int = 16,
    seed: int = 0,
    extra_cases: list[tuple[float, float]] | None = None,
    width_positions_m: np.ndarray | None = None,
) -> dict[str, object]:
    """Accuracy against a ski's beam model (demo skis): noise-free truth at any load.

    Cases: the network's held-out test cases, ``n_random`` loads drawn uniformly (seeded) from
    the trained range, and ``extra_cases`` (e.g. the papers' 40 kg at −160 mm). For each the
    true H*(X) comes from :func:`solvers.beam.solve_beam_contact`; reported are the RMSE where
    the true H* < 0.2 mm and the apparent contact area through the macro BEM
    (:func:`contact_area_check`).

    Returns
    -------
    dict
        Scalar metrics (keys ``truth_*``) and per-case arrays (``truth_cases_*``).
    """
    attrs = network["attrs"]
    rng = np.random.default_rng(seed)
    f = list(np.asarray(network.get("split_test_loads_n", np.empty(0)), dtype=float))
    xf = list(np.asarray(network.get("split_test_load_positions_m", np.empty(0)), dtype=float))
    n_test = len(f)
    f += list(rng.uniform(attrs["load_min_n"], attrs["load_max_n"], n_random))
    xf += list(rng.uniform(attrs["load_position_min_m"], attrs["load_position_max_m"], n_random))
    for a, b in extra_cases or []:
        f.append(a)
        xf.append(b)
    f, xf = np.asarray(f), np.asarray(xf)
    truth = beam_truth_profiles(beam, network["positions_m"], f, xf)
    pred = camber.predict_profiles(network, f, xf).gaps_m
    rmse = np.array([camber.contact_band_rmse_m(p, t) for p, t in zip(pred, truth, strict=True)])
    area = contact_area_check(
        network,
        f,
        xf,
        truth,
        width_m=width_m,
        effective_modulus_pa=effective_modulus_pa,
        width_positions_m=width_positions_m,
    )
    band = truth < camber.CONTACT_BAND_M
    out: dict[str, object] = {
        "truth_rmse_band_test_m": float(
            np.sqrt(np.mean((pred[:n_test] - truth[:n_test])[band[:n_test]] ** 2))
        )
        if n_test
        else float("nan"),
        "truth_rmse_band_random_m": float(
            np.sqrt(np.mean((pred[n_test:] - truth[n_test:])[band[n_test:]] ** 2))
        ),
        "truth_max_case_rmse_band_m": float(np.nanmax(rmse)),
        "truth_contact_area_max_rel_error": area["max_abs_relative_error"],
        "truth_contact_area_rms_rel_error": float(np.sqrt(np.mean(area["relative_error"] ** 2))),
        "truth_bem_converged": bool(area["converged"]),
        "truth_effective_modulus_pa": float(effective_modulus_pa),
        "truth_n_test": int(n_test),
        "truth_n_random": int(n_random),
        "truth_cases_loads_n": f,
        "truth_cases_load_positions_m": xf,
        "truth_cases_rmse_band_m": rmse,
        "truth_cases_area_pred_m2": area["area_pred_m2"],
        "truth_cases_area_true_m2": area["area_true_m2"],
    }
    return out


def store_beam_truth_check(
    network: dict, beam, outline, *, seed: int = 0
) -> tuple[dict[str, object], bool]:
    """Check a network against its ski's design beam and store the results in the network.

    Runs :func:`truth_check` with 32 random loads, E_snow = 200 MPa for the contact area, and
    the papers' case (40 kg at −160 mm) when it lies in the trained range. Per-case arrays
    (``truth_cases_*``) become datasets of ``network``, scalars ``metric_truth_*`` attributes.

    Parameters
    ----------
    network : dict
        Camber network, updated in place.
    beam
        The ski's beam (:class:`solvers.beam` model stored in the ski file).
    outline
        The ski's outline (:class:`app.storage.skis.SkiOutline`): running-surface width [m].
    seed : int
        Seed of the random loads.

    Returns
    -------
    dict, bool
        The :func:`truth_check` results, and whether the papers' case is the last case.
    """
    from skisnow.solvers.beam import G_STANDARD
    from skisnow.solvers.elastic import effective_modulus

    e_eff = effective_modulus(200e6)
    papers = (40.0 * G_STANDARD, -0.160)
    extra = []
    a = network["attrs"]
    if a["load_min_n"] <= papers[0] <= a["load_max_n"] and (
        a["load_position_min_m"] <= papers[1] <= a["load_position_max_m"]
    ):
        extra.append(papers)
    t = truth_check(
        network,
        beam,
        n_random=32,
        width_m=outline.width_m,
        effective_modulus_pa=e_eff,
        width_positions_m=outline.positions_m,
        seed=seed,
        extra_cases=extra,
    )
    for key, value in t.items():
        if key.startswith("truth_cases_"):
            network[key] = np.asarray(value)
        else:
            network["attrs"][f"metric_{key}"] = value
    return t, bool(extra)
