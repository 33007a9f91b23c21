"""The loaded camber profile H*(X) of a stored ski for any load (method.md §4 step 2).

Three profile models, in the order a ski uses them (``source`` names the one that answers, as
``provenance.ski.profile_model`` of every answer does):

1. ``identified_beam``: the beam identified from the ski's own camber measurements
   (:mod:`solvers.identify`, stored in the ski file's ``identified`` group, used when its
   identification passed the held-out check), pressed on the rigid flat by the virtual device
   (:func:`solvers.beam.solve_beam_contact`, flexibility cached per ski). Measured on the demo
   skis: 0.07–0.2 µm RMS from the beam truth near contact on held-out loads, against 0.5–1.1 µm
   for the camber network (docs/camber-identification.md). A network retrained on the identified
   beam's noise-free profiles is 21–43× faster but 2.5–19× further from the truth near contact
   on the held-out cases (docs/camber-network.md, "Identified beam or network on its profiles";
   ``scripts/network_vs_identified_beam.py``), so the beam serves.
2. ``network``: the per-ski network of the papers (:mod:`solvers.camber`), for skis whose
   beam could not be identified.
3. ``design_beam``: a beam stored with the ski (demo skis), when nothing else is available.
"""

from __future__ import annotations

import numpy as np
from skisnow.app.storage.common import provenance
from skisnow.app.storage.skis import (
    CamberData,
    SkiRecord,
    identified_beam,
    identified_to_dict,
    mean_profiles,
)
from skisnow.solvers.beam import BeamFlexibility, BeamResult, BeamSki, solve_beam_contact
from skisnow.solvers.errors import DataFileError, InputError, NotConvergedError, SkisnowError
from skisnow.solvers.identify import predict_gaps, profile_sigma

__all__ = [
    "HELD_OUT_ADDED",
    "HELD_OUT_ERRORS",
    "HELD_OUT_STORED",
    "PROFILE_SIGMA_CASES",
    "SERVED_MISFIT_LIMIT",
    "ProfileModel",
    "add_held_out_errors",
    "held_out_case_errors",
    "held_out_errors_group",
    "held_out_mask",
    "identification_group",
    "no_beam_reason",
    "profile_model",
    "served_beam",
    "served_beam_note",
    "stored_held_out_errors",
]

#: cases (spread over the measured ones) and seed of the loaded profile's spread
PROFILE_SIGMA_CASES = 40
PROFILE_SIGMA_SEED = 0


#: an identified beam serves as profile model and bending beam only when its misfit is within
#: this factor of the device noise: a forward fit that stopped above it sits in a local minimum
#: (measured: the demo skis 1.000 / 1.002; the 'soft' test design from 94 cases 1.069 with
#: 1.2 µm held-out error, from 340 cases 1.000 with 0.25 µm; docs/camber-identification.md)
SERVED_MISFIT_LIMIT = 1.02


def served_beam(identified: dict | None) -> BeamSki | None:
    """The identified beam a ski answers with, or None: the identification passed (held-out
    check included) and its misfit is within :data:`SERVED_MISFIT_LIMIT` × the noise."""
    beam = identified_beam(identified)
    if beam is None:
        return None
    a = identified["attrs"]
    ratio = float(a.get("misfit_m", np.inf)) / max(float(a.get("noise_m", 0.0)), 1e-300)
    return beam if ratio <= SERVED_MISFIT_LIMIT else None


def served_beam_note(identified: dict | None) -> str:
    """Why an identification that passed is not served ('' when it is, or did not pass)."""
    if identified_beam(identified) is None or served_beam(identified) is not None:
        return ""
    a = identified["attrs"]
    return (
        f"misfit {a['misfit_m'] * 1e6:.2f} µm is {a['misfit_m'] / a['noise_m']:.3f}× the device "
        f"noise (more than {SERVED_MISFIT_LIMIT:g}×): the fit stopped in a local minimum, so the "
        "beam is not used"
    )


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
    """

    def __init__(self, record: SkiRecord) -> None:
        self.record = record
        self.beam: BeamSki | None = served_beam(record.identified)
        self._flex: BeamFlexibility | None = None
        if self.beam is not None:
            self.source = "identified_beam"
            a = record.identified["attrs"]
            held = float(a.get("held_out_rms_m", np.nan))
            self.reason = (
                f"the beam identified from the ski's camber measurements fits them to "
                f"{a['misfit_m'] * 1e6:.2f} µm against device noise {a['noise_m'] * 1e6:.2f} µm "
                f"(within {SERVED_MISFIT_LIMIT:g}× the noise)"
                + (
                    f" and predicts {int(a.get('held_out_cases', 0))} held-out cases to "
                    f"{held * 1e6:.2f} µm RMS"
                    if np.isfinite(held)
                    else ""
                )
            )
            return
        why = no_beam_reason(record.identified)
        if record.network is not None:
            self.source = "network"
            self.reason = f"no identified beam ({why}): the camber network trained on the ski's "
            self.reason += "measurements answers"
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

    def __call__(self, load_n: float, load_position_m: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions X [m] and loaded gap H*(X) [m] under F [N] at x_F [m] on the rigid flat."""
        if self.beam is None:
            from skisnow.solvers import camber

            return camber.predict_profile(self.record.network, load_n, load_position_m)
        res = self.beam_result(load_n, load_position_m)
        return res.positions_m, res.gap_m

    @property
    def flexibility(self) -> BeamFlexibility | None:
        """The beam's flexibility, built on first use and kept (None for a network)."""
        if self.beam is None:
            return None
        if self._flex is None:
            self._flex = BeamFlexibility(self.beam)
        return self._flex

    def beam_result(self, load_n: float, load_position_m: float) -> BeamResult:
        """The beam's full solve on the rigid flat (gap and nodal reactions; the flex sheet of
        :mod:`app.service.flex` needs the reactions). Raises :class:`InputError` for a network."""
        if self.beam is None:
            raise InputError("the camber network has no beam: no reactions on the flat")
        # no warm start from earlier requests: the answer must not depend on what this process
        # solved before (a warm start gives the same contact set up to rounding, and rounding
        # moved 3 of 1000 answers of the load test)
        res = solve_beam_contact(self.beam, load_n, load_position_m, flexibility=self.flexibility)
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
        The measurement nodes X [m]; checked equal to the identification's.

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
    if x.size != np.shape(profiles_m)[1] or (
        nodes_m is not None and not np.array_equal(x, nodes_m)
    ):
        raise DataFileError("the identification is on other nodes than the measurements")
    beam = BeamSki(
        x,
        np.asarray(identified["bending_stiffness_nm2"], dtype=float),
        np.asarray(identified["unloaded_gap_m"], dtype=float),
    )
    pred = predict_gaps(beam, np.asarray(loads_n)[held], np.asarray(positions_m)[held])
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
):
    """The ``identified`` group of a ski file: the identification, its held-out check in the
    provenance, (when it passed) the loaded profile's spread along the ski over the measured
    cases, the error band's camber-model part (:func:`solvers.identify.profile_sigma`; at most
    PROFILE_SIGMA_CASES cases, spread over the measured ones), and, given the measured
    ``profiles_m`` [m] (K, N), each held-out case's error (:data:`HELD_OUT_ERRORS`, what
    ``GET /v1/skis/{name}`` and the ski's page show; about a second for 85 cases)."""
    sd = None
    if ident.ok:
        pick = np.unique(np.linspace(0, loads_n.size - 1, PROFILE_SIGMA_CASES).round().astype(int))
        sd = profile_sigma(ident, loads_n[pick], positions_m[pick], rng=PROFILE_SIGMA_SEED)
    out = identified_to_dict(ident, {**params, "profiles": sides, **check}, sd)
    rms = check.get("held_out_rms_m")
    out["attrs"]["held_out_rms_m"] = float("nan") if rms is None else float(rms)
    out["attrs"]["held_out_cases"] = int(check.get("held_out_cases", 0))
    out["held_out_index"] = np.asarray(check.get("held_out_index", []), dtype=int)
    if profiles_m is not None and out["held_out_index"].size:
        try:  # a failed identification may hold NaN arrays: no errors to store
            error = held_out_case_errors(out, loads_n, positions_m, profiles_m)
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
