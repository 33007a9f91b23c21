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

from app.storage.skis import SkiRecord, identified_beam, identified_to_dict
from solvers.beam import BeamFlexibility, BeamSki, solve_beam_contact
from solvers.errors import DataFileError, NotConvergedError
from solvers.identify import profile_sigma

__all__ = [
    "PROFILE_SIGMA_CASES",
    "SERVED_MISFIT_LIMIT",
    "ProfileModel",
    "identification_group",
    "no_beam_reason",
    "profile_model",
    "served_beam",
    "served_beam_note",
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
            from solvers import camber

            return camber.predict_profile(self.record.network, load_n, load_position_m)
        if self._flex is None:
            self._flex = BeamFlexibility(self.beam)
        # no warm start from earlier requests: the answer must not depend on what this process
        # solved before (a warm start gives the same contact set up to rounding, and rounding
        # moved 3 of 1000 answers of the load test)
        res = solve_beam_contact(self.beam, load_n, load_position_m, flexibility=self._flex)
        if not res.converged:
            raise NotConvergedError(f"the ski's beam on the flat did not converge: {res.message}")
        return res.positions_m, res.gap_m


def profile_model(record: SkiRecord) -> ProfileModel:
    """The :class:`ProfileModel` of ``record``, built once and kept with the record."""
    model = record.cache.get("profile_model")
    if model is None or model.record is not record:  # a dataclasses.replace copy shares cache
        model = ProfileModel(record)
        record.cache["profile_model"] = model
    return model


def identification_group(ident, check: dict, sides: str, loads_n, positions_m, params: dict):
    """The ``identified`` group of a ski file: the identification, its held-out check in the
    provenance, and (when it passed) the loaded profile's spread along the ski over the
    measured cases, the error band's camber-model part (:func:`solvers.identify.profile_sigma`;
    at most PROFILE_SIGMA_CASES cases, spread over the measured ones)."""
    sd = None
    if ident.ok:
        pick = np.unique(np.linspace(0, loads_n.size - 1, PROFILE_SIGMA_CASES).round().astype(int))
        sd = profile_sigma(ident, loads_n[pick], positions_m[pick], rng=PROFILE_SIGMA_SEED)
    out = identified_to_dict(ident, {**params, "profiles": sides, **check}, sd)
    rms = check.get("held_out_rms_m")
    out["attrs"]["held_out_rms_m"] = float("nan") if rms is None else float(rms)
    out["attrs"]["held_out_cases"] = int(check.get("held_out_cases", 0))
    out["held_out_index"] = np.asarray(check.get("held_out_index", []), dtype=int)
    return out
