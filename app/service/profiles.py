"""The loaded camber profile H*(X) of a stored ski for any load (docs/physics.md §4 step 2).

Three profile models (``source`` names the one that answers, as
``provenance.ski.profile_model`` of every answer does):

1. ``identified_beam``: the beam identified from the ski's own camber measurements
   (:mod:`solvers.identify`, stored in the ski file's ``identified`` group, when its
   identification passed the held-out check), pressed on the rigid flat by the virtual device
   (:func:`solvers.beam.solve_beam_contact`, flexibility cached per ski).
2. ``network``: the per-ski network of the papers (:mod:`solvers.camber`).
3. ``design_beam``: a beam stored with the ski (demo skis), when nothing else is available.

Which of the first two serves is decided once, in the ski job, on measured data: both are
fitted without the same held-out cases and judged on them (:func:`held_out_comparison`, the
rule :data:`CHOICE_RULE`, stored as the ``identified`` group's :data:`MODEL_CHOICE`
subgroup). A file without that comparison (the demo skis, uploads before it) serves its
identified beam when the identification passed. The loads a ski answers follow one rule
(:attr:`ProfileModel.load_range_n`, :data:`LOAD_EXTRAPOLATION_FACTOR`) whichever model serves:
above the heaviest measured load the identified beam answers, the network never extrapolates
(docs/camber-network.md, "Which model serves, and how far in load").
"""

from __future__ import annotations

import threading

import numpy as np
from skisnow.app.storage.common import provenance
from skisnow.app.storage.skis import (
    CamberData,
    SkiRecord,
    identified_beam,
    identified_to_dict,
    mean_profiles,
)
from skisnow.solvers.beam import (
    G_STANDARD,
    BeamFlexibility,
    BeamResult,
    BeamSki,
    solve_beam_contact,
)
from skisnow.solvers.errors import DataFileError, InputError, NotConvergedError, SkisnowError
from skisnow.solvers.identify import predict_gaps, profile_sigma

__all__ = [
    "CHOICE_RULE",
    "HELD_OUT_ADDED",
    "HELD_OUT_ERRORS",
    "HELD_OUT_STORED",
    "LOAD_EXTRAPOLATION_FACTOR",
    "MODEL_CHOICE",
    "PROFILE_SIGMA_CASES",
    "ProfileModel",
    "add_held_out_errors",
    "choose_profile_model",
    "held_out_case_errors",
    "held_out_comparison",
    "held_out_errors_group",
    "held_out_mask",
    "identification_group",
    "model_choice",
    "no_beam_reason",
    "profile_model",
    "served_beam",
    "served_beam_note",
    "stored_held_out_errors",
]

#: cases (spread over the measured ones) and seed of the loaded profile's spread
PROFILE_SIGMA_CASES = 40
PROFILE_SIGMA_SEED = 0


#: subgroup of the ``identified`` group: both profile models judged on the job's held-out cases
MODEL_CHOICE = "model_choice"
#: the decision rule, as stored with every choice and shown where the choice is shown
CHOICE_RULE = (
    "each model's held-out error above the device noise, e = sqrt(max(RMS² − σ², 0)) where the "
    "measured H* < 0.2 mm, on the same held-out measured cases neither model was fitted to; the "
    "camber network serves only when e_network² + t < e_beam², t = σ²·sqrt(2/n) the standard "
    "deviation of a mean of n squared noise readings (the resolution of the estimate): within "
    "it the beam is preferred (it is physics: it extrapolates in load and bends on the snow); "
    "a network that failed the job's accuracy check (held-out RMSE where H* < 0.2 mm above "
    "the service's limit) is not served"
)


def choose_profile_model(
    beam_excess_m: float, network_excess_m: float, tie_m2: float, network_refused: str = ""
) -> tuple[str, str]:
    """The profile model a ski serves from the held-out comparison (:data:`CHOICE_RULE`):
    ``("identified_beam" | "network", why)``. ``beam_excess_m`` is NaN when no beam passed
    the identification; ``network_excess_m`` NaN when there is no network.
    ``network_refused``: why the network may not serve (its failed accuracy check; without a
    network, why there is none), or ''."""
    b, n = float(beam_excess_m), float(network_excess_m)
    if not np.isfinite(n) and np.isfinite(b):
        why = f" ({network_refused})" if network_refused else ""
        return "identified_beam", "no camber network to compare" + why
    if network_refused and np.isfinite(b):
        return "identified_beam", (
            f"the camber network failed its accuracy check ({network_refused}): the identified "
            f"beam serves (it predicts the held-out cases to {b * 1e6:.2f} µm above the device "
            "noise where H* < 0.2 mm)"
        )
    if not np.isfinite(b):
        return "network", "no identified beam to compare"
    if not np.isfinite(n):
        return "identified_beam", "no camber network to compare"
    if n * n + tie_m2 < b * b:
        return "network", (
            f"the camber network predicts the held-out cases to {n * 1e6:.2f} µm above the device "
            f"noise where H* < 0.2 mm, the identified beam to {b * 1e6:.2f} µm: the network is "
            "better by more than the resolution of the estimate"
        )
    better = "better than" if b <= n else "within the resolution of the estimate of"
    return "identified_beam", (
        f"the identified beam predicts the held-out cases to {b * 1e6:.2f} µm above the device "
        f"noise where H* < 0.2 mm, the camber network to {n * 1e6:.2f} µm: the beam is "
        f"{better} the network"
    )


def _excess(rms_m: float, noise_m: float) -> float:
    return float(np.sqrt(max(rms_m * rms_m - noise_m * noise_m, 0.0)))


def held_out_comparison(
    network: dict | None,
    beam: BeamSki | None,
    loads_n: np.ndarray,
    positions_m: np.ndarray,
    profiles_m: np.ndarray,
    case_index: np.ndarray,
    noise_m: float,
    params: dict | None,
    network_refused: str = "",
    nodes_m: np.ndarray | None = None,
) -> dict:
    """The :data:`MODEL_CHOICE` group: the camber network and the identified beam judged on the
    same held-out measured cases (neither was fitted to them), and the model the ski serves.

    Parameters
    ----------
    network : dict or None
        The ski's camber network (:mod:`solvers.camber`), trained without the held-out cases.
    beam : BeamSki or None
        The identified beam (None: the identification failed), identified without them.
    loads_n, positions_m : ndarray (K,)
        F [N] and x_F [m] of every case (:func:`app.storage.skis.mean_profiles`).
    profiles_m : ndarray (K, N)
        Measured profiles [m] on the network's and the identification's nodes.
    case_index : ndarray of int
        The held-out cases (indices into the K cases).
    noise_m : float
        Device noise σ [m] (the identification's estimate, or
        :func:`solvers.identify.estimate_noise`).
    params : dict
        Provenance parameters; its ``seed`` and ``fraction`` (the held-out draw's) are also
        stored as the attributes ``seed`` and ``held_out_fraction``.
    network_refused : str
        Why the network may not serve (the job's failed accuracy check), or ''; kept as the
        attribute ``network_refused``. The network is still judged (its errors are stored).
    nodes_m : ndarray (N,), optional
        The measurement nodes X [m], where the beam's gaps are read (a beam identified on a
        finer model grid than the samples'); default: the beam's own nodes.

    Returns
    -------
    dict
        Attributes ``served``, ``reason``, ``rule``, the held-out errors of each model (RMS where
        the measured H* < 0.2 mm and over the whole profile, and the same above the noise) [m],
        ``tie_m2``, counts; arrays of the held-out cases and each model's per-case RMS [m].
    """
    from skisnow.solvers import camber

    idx = np.asarray(case_index, dtype=int)
    f = np.asarray(loads_n, dtype=float)[idx]
    xf = np.asarray(positions_m, dtype=float)[idx]
    y = np.asarray(profiles_m, dtype=float)[idx]
    band = y < camber.CONTACT_BAND_M
    n_band = int(band.sum())
    preds = {}
    if network is not None and idx.size:
        preds["network"] = camber.predict_profiles(network, f, xf).gaps_m
    if beam is not None and idx.size:
        preds["beam"] = predict_gaps(beam, f, xf, nodes_m)
    attrs: dict = {
        "description": "the camber network and the identified beam judged on the same held-out "
        "measured cases (fitted without them); the served model is the one with the lower "
        "held-out error above the device noise",
        "rule": CHOICE_RULE,
        "units": "m",
        "noise_m": float(noise_m),
        "held_out_cases": int(idx.size),
        "band_points": n_band,
        "tie_m2": float(noise_m**2 * np.sqrt(2.0 / max(n_band, 1))),
        **provenance(params),
    }
    for key in ("seed", "fraction"):  # the draw, readable without parsing the provenance
        if params and key in params:
            attrs[f"held_out_{key}" if key == "fraction" else key] = params[key]
    out: dict = {
        "case_index": idx,
        "held_out_loads_n": f,
        "held_out_load_positions_m": xf,
    }
    for name in ("beam", "network"):
        pred = preds.get(name)
        if pred is None:
            for key in ("rms_band_m", "rms_all_m", "excess_band_m", "excess_all_m"):
                attrs[f"{name}_{key}"] = float("nan")
            continue
        d = pred - y
        rms_band = float(np.sqrt(np.mean(d[band] ** 2))) if n_band else float("nan")
        rms_all = float(np.sqrt(np.mean(d**2)))
        attrs[f"{name}_rms_band_m"] = rms_band
        attrs[f"{name}_rms_all_m"] = rms_all
        attrs[f"{name}_excess_band_m"] = _excess(rms_band, noise_m)
        attrs[f"{name}_excess_all_m"] = _excess(rms_all, noise_m)
        out[f"{name}_case_rms_m"] = np.sqrt(np.mean(d**2, axis=1))
    if network_refused:
        attrs["network_refused"] = network_refused
    served, why = choose_profile_model(
        attrs["beam_excess_band_m"],
        attrs["network_excess_band_m"],
        attrs["tie_m2"],
        network_refused,
    )
    attrs["served"] = served
    attrs["reason"] = why
    out["attrs"] = attrs
    return out


def model_choice(identified: dict | None) -> dict | None:
    """The attributes of the stored :data:`MODEL_CHOICE` group, or None (a file written before
    the comparison, or no identification)."""
    group = (identified or {}).get(MODEL_CHOICE)
    if not isinstance(group, dict) or "served" not in group.get("attrs", {}):
        return None
    return group["attrs"]


def served_beam(identified: dict | None) -> BeamSki | None:
    """The identified beam a ski answers with, or None: the identification passed (held-out
    check included) and the held-out comparison (:data:`MODEL_CHOICE`) chose it. A file
    written before the comparison was stored (the demo skis' shipped identification, uploads
    before it) has none: its beam serves when its identification passed (the fallback)."""
    beam = identified_beam(identified)
    if beam is None:
        return None
    choice = model_choice(identified)
    if choice is None:
        return beam
    return beam if choice["served"] == "identified_beam" else None


def served_beam_note(identified: dict | None) -> str:
    """Why an identification that passed is not served ('' when it is, or did not pass)."""
    if identified_beam(identified) is None or served_beam(identified) is not None:
        return ""
    return str(model_choice(identified)["reason"])


def no_beam_reason(identified: dict | None) -> str:
    """Why a ski has no identified beam to serve: the identification's own reason, the note of
    :func:`served_beam_note`, or that none was run ('' when the identified beam is served)."""
    if served_beam(identified) is not None:
        return ""
    return (
        served_beam_note(identified)
        or (identified or {}).get("attrs", {}).get("reason")
        or "no identification was run"
    )


#: a ski with an identified beam that passed its held-out check answers loads up to this × its
#: heaviest measured load, whichever model serves inside the measured range (above it the beam
#: answers); without one, nothing beyond the heaviest measured load. Nothing below the lightest
#: measured load (the unloaded profile aside). Measured with the heaviest levels held out
#: (scripts/load_extrapolation_study.py, docs/camber-network.md "How far each model may answer
#: in load", demo skis and six designs): 10 % beyond its edge the camber network errs 1.2–2.8 ×
#: its error there, at 1.5 × 2.6–12 × (up to 36 µm); the identified beam 1.02–2.3 × at 1.5 ×
LOAD_EXTRAPOLATION_FACTOR = 1.5


class ProfileModel:
    """The profile model of one ski record (build once per process and ski).

    Parameters
    ----------
    record : SkiRecord
        The ski file's content.

    Attributes
    ----------
    source : str
        ``identified_beam``, ``network`` or ``design_beam``.
    reason : str
        Why this model serves (the words of ``GET /v1/skis`` and the ski's page).
    extrapolation_beam : BeamSki or None
        The identified beam that answers loads above the heaviest measured one (the served beam,
        or, when the network serves, the identified beam that passed its held-out check).
    """

    def __init__(self, record: SkiRecord) -> None:
        self.record = record
        self.beam: BeamSki | None = served_beam(record.identified)
        self.extrapolation_beam: BeamSki | None = self.beam
        self._flex: BeamFlexibility | None = None
        self._xflex: BeamFlexibility | None = None
        #: one build of the flexibility at a time: concurrent first requests of a ski each built
        #: their own 61 MB copy (one of two workers at 1148 MB after 100 answers to 8 clients)
        self._build_lock = threading.Lock()
        if self.beam is not None:
            self.source = "identified_beam"
            a = record.identified["attrs"]
            choice = model_choice(record.identified)
            if choice is not None:
                self.reason = f"held-out comparison: {choice['reason']}"
                return
            held = float(a.get("held_out_rms_m", np.nan))
            self.reason = (
                f"the beam identified from the ski's camber measurements fits them to "
                f"{a['misfit_m'] * 1e6:.2f} µm against device noise {a['noise_m'] * 1e6:.2f} µm"
                + (
                    f" and predicts {int(a.get('held_out_cases', 0))} held-out cases to "
                    f"{held * 1e6:.2f} µm RMS"
                    if np.isfinite(held)
                    else ""
                )
                + " (no held-out comparison with the camber network stored: an identified beam "
                "that passed serves)"
            )
            return
        why = no_beam_reason(record.identified)
        if record.network is not None:
            self.source = "network"
            self.extrapolation_beam = identified_beam(record.identified)
            choice = model_choice(record.identified)
            if choice is not None and choice["served"] == "network":
                self.reason = f"held-out comparison: {choice['reason']}"
            else:
                self.reason = f"no identified beam ({why}): the camber network trained on the "
                self.reason += "ski's measurements answers"
        elif record.beam is not None:
            self.beam = record.beam
            self.source = "design_beam"
            self.reason = (
                f"no identified beam ({why}) and no camber network: the design beam stored with "
                "the ski answers"
            )
        else:
            raise DataFileError(
                f"ski {record.ski_id!r} has no profile model: no identified beam, no camber "
                "network and no design beam"
            )

    @property
    def measured_load_range_n(self) -> tuple[float, float]:
        """Lightest and heaviest measured loaded case [N] (the unloaded profile, F = 0, aside)."""
        f = np.asarray(self.record.measurements.loads_n, dtype=float)
        f = f[f > 0]
        if not f.size:  # cannot happen for a stored ski; guards a hand-made record
            raise DataFileError(f"ski {self.record.ski_id!r} has no loaded camber case")
        return float(f.min()), float(f.max())

    @property
    def load_range_n(self) -> tuple[float, float]:
        """Loads this ski answers [N], the one rule of :data:`LOAD_EXTRAPOLATION_FACTOR`: from
        the lightest measured load to the heaviest, × the factor when an identified beam passed
        its held-out check (whichever model serves inside the measured range)."""
        lo, hi = self.measured_load_range_n
        if self.extrapolation_beam is not None:
            hi *= LOAD_EXTRAPOLATION_FACTOR
        return lo, hi

    @property
    def load_range_rule(self) -> str:
        """The load range's rule in words (the refusal of an out-of-range load quotes it)."""
        lo, hi = self.measured_load_range_n
        if self.extrapolation_beam is not None:
            return (
                f"measured {lo / G_STANDARD:.4g} … {hi / G_STANDARD:.4g} kg; the identified beam "
                f"answers up to {LOAD_EXTRAPOLATION_FACTOR:g}× the heaviest measured load, "
                "nothing lighter than the lightest is answered"
            )
        return (
            f"measured {lo / G_STANDARD:.4g} … {hi / G_STANDARD:.4g} kg; without an identified "
            "beam the camber model is not extrapolated"
        )

    def answer_source(self, load_n: float) -> str:
        """The model that answers ``load_n`` [N]: :attr:`source`, or ``identified_beam`` for a
        load above the heaviest measured one when the network serves (the beam extrapolates)."""
        if self._extrapolates(load_n):
            return "identified_beam"
        return self.source

    def answer_reason(self, load_n: float) -> str:
        """Why :meth:`answer_source` answers ``load_n`` [N]."""
        if self._extrapolates(load_n):
            return (
                f"{load_n / G_STANDARD:.4g} kg is above the heaviest measured load: the camber "
                "network is not extrapolated, the identified beam answers up to "
                f"{LOAD_EXTRAPOLATION_FACTOR:g}× it ({self.reason})"
            )
        return self.reason

    def _extrapolates(self, load_n: float) -> bool:
        return (
            self.beam is None
            and self.extrapolation_beam is not None
            and float(load_n) > self.measured_load_range_n[1] * (1 + 1e-9)
        )

    def __call__(self, load_n: float, load_position_m: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions X [m] and loaded gap H*(X) [m] under F [N] at x_F [m] on the rigid flat."""
        if self._extrapolates(load_n):
            if self._xflex is None:
                with self._build_lock:
                    if self._xflex is None:
                        self._xflex = BeamFlexibility(self.extrapolation_beam)
            res = _solve_flat(self.extrapolation_beam, load_n, load_position_m, self._xflex)
            return res.positions_m, res.gap_m
        if self.beam is None:
            from skisnow.solvers import camber

            return camber.predict_profile(self.record.network, load_n, load_position_m)
        res = self.beam_result(load_n, load_position_m)
        return res.positions_m, res.gap_m

    @property
    def flexibility(self) -> BeamFlexibility | None:
        """The beam's flexibility, built on first use and kept (its columns only,
        :attr:`solvers.beam.BeamFlexibility.columns`); None for a network."""
        if self.beam is None:
            return None
        if self._flex is None:
            with self._build_lock:
                if self._flex is None:
                    self._flex = BeamFlexibility(self.beam)
        return self._flex

    def beam_result(self, load_n: float, load_position_m: float) -> BeamResult:
        """The beam's full solve on the rigid flat (gap and nodal reactions; the flex sheet of
        :mod:`app.service.flex` needs the reactions). Raises :class:`InputError` for a network."""
        if self.beam is None:
            raise InputError("the camber network has no beam: no reactions on the flat")
        return _solve_flat(self.beam, load_n, load_position_m, self.flexibility)


def _solve_flat(beam: BeamSki, load_n, load_position_m, flexibility) -> BeamResult:
    # no warm start from earlier requests: the answer must not depend on what this process
    # solved before (a warm start gives the same contact set up to rounding, and rounding
    # moved 3 of 1000 answers of the load test)
    res = solve_beam_contact(beam, load_n, load_position_m, flexibility=flexibility)
    if not res.converged:
        raise NotConvergedError(f"the ski's beam on the flat did not converge: {res.message}")
    return res


def profile_model(record: SkiRecord) -> ProfileModel:
    """The :class:`ProfileModel` of ``record``, built once and kept with the record."""
    model = record.cache.get("profile_model")
    if model is None or model.record is not record:  # a dataclasses.replace copy shares cache
        model = ProfileModel(record)
        record.cache["profile_model"] = model
    return model


#: subgroup of the ``identified`` group with the error of every held-out case
HELD_OUT_ERRORS = "held_out_errors"
#: its ``source`` when written with the identification (``identify-ski --store``, upload job)
HELD_OUT_STORED = "stored with the identification"
#: its ``source`` when added to an identification stored without it (no re-identification)
HELD_OUT_ADDED = (
    "added to an existing identification (skisnow identify-ski --add-held-out-errors): "
    "predicted from the stored beam, the identification itself unchanged"
)


def held_out_mask(identified: dict, n_cases: int) -> np.ndarray | None:
    """The held-out cases of a stored identification as a mask over the ``n_cases`` cases of
    :func:`app.storage.skis.mean_profiles`, or None when the stored indices and misfits do not
    match those cases (an identification of other data)."""
    held = np.zeros(n_cases, dtype=bool)
    index = np.asarray(identified.get("held_out_index", []), dtype=int)
    if index.size and (index.min() < 0 or index.max() >= n_cases):
        return None
    held[index] = True
    if int((~held).sum()) != np.asarray(identified.get("case_misfit_m", [])).size:
        return None
    return held


def held_out_case_errors(
    identified: dict,
    loads_n: np.ndarray,
    positions_m: np.ndarray,
    profiles_m: np.ndarray,
    *,
    nodes_m: np.ndarray | None = None,
) -> np.ndarray:
    """The error of every held-out case of a stored identification: RMS over X of the stored
    beam's loaded gap minus the measured profile [m] (the device model,
    :func:`solvers.identify.predict_gaps`), in case order.

    Parameters
    ----------
    identified : dict
        The ``identified`` group (beam arrays, ``held_out_index``, ``case_misfit_m``).
    loads_n, positions_m : ndarray (K,)
        F [N] and x_F [m] of every case (:func:`app.storage.skis.mean_profiles`).
    profiles_m : ndarray (K, N)
        Measured profiles [m] on the identification's nodes.
    nodes_m : ndarray (N,), optional
        The measurement nodes X [m] (default: the identification's); checked to be among the
        identification's nodes (the measured ones, or a finer model grid).

    Raises
    ------
    DataFileError
        The held-out indices do not match the cases, or the identification is on another grid.
    InputError
        The stored beam cannot predict (a failed identification may hold NaN arrays).
    """
    held = held_out_mask(identified, np.asarray(loads_n).size)
    if held is None:
        raise DataFileError("the identification's held-out cases do not match the measurements")
    x = np.asarray(identified.get("positions_m", []), dtype=float)
    if nodes_m is None:
        nodes_m = x
    nodes_m = np.asarray(nodes_m, dtype=float)
    # the beam's nodes are the measured ones, or a finer model grid that holds them
    on_grid = np.isin(nodes_m, x).all() if x.size >= nodes_m.size else False
    if nodes_m.size != np.shape(profiles_m)[1] or not on_grid:
        raise DataFileError("the identification is on other nodes than the measurements")
    beam = BeamSki(
        x,
        np.asarray(identified["bending_stiffness_nm2"], dtype=float),
        np.asarray(identified["unloaded_gap_m"], dtype=float),
    )
    pred = predict_gaps(beam, np.asarray(loads_n)[held], np.asarray(positions_m)[held], nodes_m)
    return np.sqrt(np.mean((pred - np.asarray(profiles_m)[held]) ** 2, axis=1))


def held_out_errors_group(
    error_m: np.ndarray, case_index: np.ndarray, source: str, params: dict | None
) -> dict:
    """The :data:`HELD_OUT_ERRORS` subgroup: each held-out case's error [m], the cases it
    belongs to (indices into the cases of :func:`app.storage.skis.mean_profiles`), how it was
    stored (``source``) and provenance."""
    return {
        "attrs": {
            "description": "RMS over X of the identified beam's loaded gap minus the measured "
            "profile, per held-out case (device model, solvers.identify.predict_gaps)",
            "units": "m",
            "source": source,
            **provenance(params),
        },
        "rms_error_m": np.asarray(error_m, dtype=float),
        "case_index": np.asarray(case_index, dtype=int),
    }


def stored_held_out_errors(identified: dict, held: np.ndarray) -> tuple[np.ndarray, dict] | None:
    """The held-out errors [m] stored with an identification and the attributes saying where
    they come from; None when there are none (a file written before they were stored) or they
    belong to other cases than ``held`` (the mask of :func:`held_out_mask`)."""
    group = identified.get(HELD_OUT_ERRORS)
    if not isinstance(group, dict) or "rms_error_m" not in group:
        return None
    index = np.asarray(group.get("case_index", []), dtype=int)
    error = np.asarray(group["rms_error_m"], dtype=float)
    if not np.array_equal(index, np.flatnonzero(held)) or error.shape != index.shape:
        return None
    return error, dict(group.get("attrs", {}))


def identification_group(
    ident,
    check: dict,
    sides: str,
    loads_n,
    positions_m,
    params: dict,
    profiles_m: np.ndarray | None = None,
    nodes_m: np.ndarray | None = None,
):
    """The ``identified`` group of a ski file: the identification, its held-out check in the
    provenance, (when it passed) the loaded profile's spread along the ski over the measured
    cases, the error band's camber-model part (:func:`solvers.identify.profile_sigma`; at most
    PROFILE_SIGMA_CASES cases, spread over the measured ones), and, given the measured
    ``profiles_m`` [m] (K, N), each held-out case's error (:data:`HELD_OUT_ERRORS`, what
    ``GET /v1/skis/{name}`` and the ski's page show; about a second for 85 cases); ``nodes_m``
    [m]: the measured nodes of ``profiles_m`` (default: the beam's; a beam identified on a finer
    model grid is read at them)."""
    sd = None
    if ident.ok:
        pick = np.unique(np.linspace(0, loads_n.size - 1, PROFILE_SIGMA_CASES).round().astype(int))
        sd = profile_sigma(ident, loads_n[pick], positions_m[pick], rng=PROFILE_SIGMA_SEED)
    out = identified_to_dict(ident, {**params, "profiles": sides, **check}, sd)
    rms = check.get("held_out_rms_m")
    out["attrs"]["held_out_rms_m"] = float("nan") if rms is None else float(rms)
    rms_band = check.get("held_out_rms_band_m")
    out["attrs"]["held_out_rms_band_m"] = float("nan") if rms_band is None else float(rms_band)
    out["attrs"]["held_out_cases"] = int(check.get("held_out_cases", 0))
    out["held_out_index"] = np.asarray(check.get("held_out_index", []), dtype=int)
    if profiles_m is not None and out["held_out_index"].size:
        try:  # a failed identification may hold NaN arrays: no errors to store
            error = held_out_case_errors(out, loads_n, positions_m, profiles_m, nodes_m=nodes_m)
        except SkisnowError:
            return out
        index = np.flatnonzero(held_out_mask(out, np.asarray(loads_n).size))
        out[HELD_OUT_ERRORS] = held_out_errors_group(error, index, HELD_OUT_STORED, params)
    return out


def add_held_out_errors(identified: dict, data: CamberData, params: dict | None) -> dict:
    """A copy of a stored ``identified`` group with each held-out case's error added
    (:data:`HELD_OUT_ADDED` in its provenance), for files identified before the errors were
    stored; the identification itself is not changed.

    Raises
    ------
    InputError
        No identification, or one without held-out cases.
    DataFileError, InputError
        As :func:`held_out_case_errors`.
    """
    if not identified or not np.asarray(identified.get("held_out_index", [])).size:
        raise InputError("the ski has no stored identification with held-out cases")
    loads_n, positions_m, profiles_m, _ = mean_profiles(data)
    error = held_out_case_errors(
        identified, loads_n, positions_m, profiles_m, nodes_m=data.positions_m
    )
    index = np.flatnonzero(held_out_mask(identified, loads_n.size))
    return {
        **identified,
        HELD_OUT_ERRORS: held_out_errors_group(error, index, HELD_OUT_ADDED, params),
    }
