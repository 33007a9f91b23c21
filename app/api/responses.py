"""Answers of the REST API (pydantic), as documented in ``/docs`` and ``/openapi.json``.

Each model is exactly what its route sends: no field more or less (``extra="forbid"``, checked
against real answers in tests/api/test_api_models.py). Nested parts whose keys depend on the case
(the ski-model decision, the solver diagnostics, the flex sheet's sections) are
``dict[str, Any]`` and described in words. Units are in the names.

Routes whose answers are large (contact, compare, flex) send them as they are
(``JSONResponse``): these models document them, they do not filter them.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

_FIXED = ConfigDict(extra="forbid")


class Health(BaseModel):
    model_config = _FIXED
    status: str = Field(..., examples=["ok"])


class Ready(BaseModel):
    model_config = _FIXED
    status: str = Field(..., examples=["ready"])
    skis: list[str]
    grinds: list[str]


# ------------------------------------------------------------------------ catalogue lists


class SkiSummary(BaseModel):
    model_config = _FIXED
    name: str
    length_mm: float
    width_mm: list[float] = Field(..., description="running-surface width, one or per position")
    load_position_range_mm: list[float] = Field(..., description="[low, high] the model covers")
    profile_model: str = Field(..., description="identified_beam, camber_network or design_beam")
    profile_model_reason: str
    network_metrics: str | None = Field(None, description="the camber network's metrics (JSON)")
    description: str | None
    file: str
    sha256: str


class FailedItem(BaseModel):
    """An upload whose job failed: no files are kept, its name may be uploaded again (the
    upload replaces it) or it can be deleted (``DELETE /v1/{skis|grinds}/{name}``)."""

    model_config = _FIXED
    name: str
    reason: str = Field(..., description="why its job failed (the job's error)")
    job: str | None = Field(None, description="the failed job's id (GET /v1/jobs/{id})")
    failed_at: str | None = Field(None, description="when the job failed (ISO 8601, UTC)")


class SkiList(BaseModel):
    model_config = _FIXED
    skis: list[SkiSummary]
    failed: list[FailedItem] = Field(
        default_factory=list, description="uploads whose job failed, with the reason"
    )


class GrindSummary(BaseModel):
    model_config = _FIXED
    name: str
    iso25178: dict[str, Any] = Field(..., description="ISO 25178 parameters, units in the keys")
    texture_pixel_size_um: float
    grid: list[int]
    pressure_ratio_range: list[float] = Field(..., description="[low, high] of P_n/E' tabulated")
    gap_floor_nm: float
    detrend: str | None = Field(..., description="removed from the heights; null: not recorded")
    provenance: str = Field(
        ...,
        description="where the texture comes from: 'measured: …' (the shipped measured ski "
        "base), 'uploaded: …' (an upload) or 'synthetic' (a shipped synthetic grind)",
    )
    file: str
    sha256: str
    code_version: str | None
    git_commit: str | None


class GrindList(BaseModel):
    model_config = _FIXED
    grinds: list[GrindSummary]
    failed: list[FailedItem] = Field(
        default_factory=list, description="uploads whose job failed, with the reason"
    )


# -------------------------------------------------------------------------- contact


class SnowEcho(BaseModel):
    """The snow preset a request named (app/snow.py) and which numbers were given instead."""

    model_config = _FIXED
    name: str
    label: str
    numbers_given_instead_of_the_preset: dict[str, float]
    preset_snow_modulus_mpa: float
    preset_porosity: float
    modulus_range_mpa: list[float]
    reference: str


class CaseEcho(BaseModel):
    """The inputs of the case as solved, with the load in N and E' in MPa."""

    model_config = _FIXED
    ski: str
    grind: str
    load_kg: float
    load_position_mm: float
    snow_modulus_mpa: float
    porosity: float
    snow: SnowEcho | None = None
    base_modulus_mpa: float
    poisson_ratio: float
    preset: str
    load_n: float
    effective_modulus_mpa: float


class Metrics(BaseModel):
    """The four functional parameters."""

    model_config = _FIXED
    total_real_contact_area_mm2: float
    average_real_contact_pressure_mpa: float
    min_average_separation_um: float
    total_reciprocal_separation_m: float


class Zone(BaseModel):
    model_config = _FIXED
    name: str = Field(
        ...,
        description="by position along the ski, whatever the load: tail, rear (behind the "
        "balance point), front, tip (ahead of it); tail and tip are the outer halves towards the "
        "ends; numbered from the tail where several share a section (front 1, front 2)",
    )
    start_mm: float
    end_mm: float
    length_mm: float
    load_n: float
    load_share: float
    apparent_area_cm2: float
    real_area_mm2: float
    load_band_90_n: list[float] | None = Field(None, description="[low, high], with a band")
    min_average_separation_um: float | None = Field(
        None, description="the smallest average separation inside this zone [µm]"
    )
    unresolved: str | None = Field(
        None,
        description="why this zone's minimum separation is not grid-converged (too short, or "
        "at the end of the measured profile); null for a resolved zone",
    )


class Apparent(BaseModel):
    model_config = _FIXED
    contact_area_cm2: float
    mean_pressure_kpa: float
    zones: list[Zone]


class ResultWarning(BaseModel):
    """A condition under which the answer is computed but not trustworthy (docs/limits.md)."""

    model_config = _FIXED
    code: str
    detail: str


class Distributions(BaseModel):
    """Values along the ski, one per position (finite rows)."""

    model_config = _FIXED
    position_mm: list[float | None]
    pressure_kpa: list[float | None]
    clearance_um: list[float | None]
    real_area_fraction: list[float | None]
    average_separation_um: list[float | None]
    reciprocal_separation_per_m: list[float | None]
    pressure_band_low_kpa: list[float | None] | None = None
    pressure_band_high_kpa: list[float | None] | None = None


class TableProvenance(BaseModel):
    model_config = _FIXED
    file: str
    sha256: str
    texture_pixel_size_um: float
    gap_floor_nm: float
    pixel_error_estimate: dict[str, Any] = Field(
        ..., description="estimated: false, or the table's error against the zero-pixel limit"
    )


class SkiProvenance(BaseModel):
    model_config = _FIXED
    file: str
    sha256: str
    profile_model: str = Field(
        ..., description="the model that answered this load: identified_beam, network, design_beam"
    )
    profile_model_reason: str = Field(
        ..., description="why it answered (the held-out comparison, or the load range rule)"
    )


class MacroProvenance(BaseModel):
    model_config = _FIXED
    converged: bool
    iterations: int
    residual: float
    pixel_size_mm: list[float]
    force_residual: float
    moment_residual: float


class Provenance(BaseModel):
    model_config = _FIXED
    code_version: str
    preset: dict[str, Any] = Field(..., description="the accuracy preset's settings")
    table: TableProvenance
    ski: SkiProvenance
    ski_model: dict[str, Any] = Field(
        ..., description="requested, used and why (rigid or flexible), with the solves"
    )
    macro: MacroProvenance
    multiscale: dict[str, Any] = Field(..., description="the multi-scale step's diagnostics")


class StudiedTail(BaseModel):
    """The studied answers outside their 90 % bands (docs/studies/population-bands.md; for a
    camber network's answers docs/camber-identification.md)."""

    model_config = _FIXED
    answers: int = Field(..., description="held-out answers studied in this answer's cell")
    outside_share: float = Field(
        ..., description="share of their truths outside the band (rounded up)"
    )
    farthest_over_half_width: float = Field(
        ...,
        description="the farthest truth's distance from its answer ÷ the band's half-width on "
        "its side (rounded up)",
    )
    contact_area_cm2_at_farthest: list[float | None] = Field(
        ...,
        description="this answer's apparent-area band stretched that far [cm²]: [low, high], "
        "high null when unbounded",
    )
    of: Literal["identified_beam", "network"] = Field(
        ..., description="which answers were studied: identified beams' or camber networks'"
    )
    source: str


class Band(BaseModel):
    """The 90 % error band of the answer (docs/limits.md)."""

    model_config = _FIXED
    level: float
    relative_half_width: dict[str, float | None] = Field(
        ...,
        description="relative 90 % half-width w per quantity: the interval reaches value × "
        "(1 − w) below and value ÷ (1 − w) above (symmetric in log), or value ÷ (1 − "
        "w_above) where relative_half_width_above names the quantity",
    )
    relative_half_width_above: dict[str, float | None] = Field(
        default_factory=dict,
        description="relative 90 % half-width above the answer, for the quantities whose "
        "macro-grid part is a bias (the apparent contact area: the default grid's area is too "
        "large, so the band reaches further below than above)",
    )
    grid_above_share: float | None = Field(
        None,
        description="share of the apparent area's macro-grid part kept above the answer "
        "(0 on snow of 20 MPa and softer, 1 from 200 MPa, linear in log between)",
    )
    intervals: dict[str, list[float | None] | None] = Field(
        ...,
        description="[low, high] in the answer's units: value × (1 − w) … value ÷ (1 − "
        "w_above) (w_above = w unless relative_half_width_above names the quantity; the mean "
        "apparent pressure's interval is the apparent area's, sides swapped); high is null "
        "when that width is ≥ 1 (no upper bound), null without a band",
    )
    studied_tail: StudiedTail | None = Field(
        None,
        description="how far outside their bands the own-ski studies' answers of this kind "
        "fell (a 90 % band leaves some truths outside by design); null where the studies do "
        "not stand for the answer (a design beam, the network's profile, auto comparing the "
        "ski models)",
    )
    zone_load_relative_half_width: list[float]
    components: dict[str, dict[str, float | None]]
    camber_model: dict[str, Any]
    macro_grid_factor: dict[str, float | None] | None = Field(
        None,
        description="factors on the macro grid part per quantity, calibrated per snow "
        "modulus (a bending-ski answer's, or a rigid answer's apparent area); a quantity not "
        "named has factor 1",
    )
    not_covered: list[str]
    method: str


class ContactAnswer(BaseModel):
    """One ski × grind case."""

    model_config = _FIXED
    inputs: CaseEcho
    metrics: Metrics
    apparent: Apparent
    warnings: list[ResultWarning]
    distributions: Distributions
    provenance: Provenance
    timing_ms: dict[str, float] = Field(..., description="wall-clock time per step [ms]")
    band: Band | None = None


class CompareAnswer(BaseModel):
    model_config = _FIXED
    results: list[ContactAnswer] = Field(..., description="skis × grinds, ski-major order")


# ----------------------------------------------------------------------------- flex


class FlexSheet(BaseModel):
    """The flex sheet of one ski (docs/flex.md); each section with its 90 % band."""

    model_config = _FIXED
    inputs: dict[str, Any]
    pockets: list[dict[str, Any]] = Field(..., description="wax pocket per gap, half/full weight")
    wax_zone: dict[str, Any]
    verdict: dict[str, Any] = Field(
        ...,
        description="whether the ski suits the body weight, in words, and the weights it suits",
    )
    pocket_height: dict[str, Any] = Field(
        ..., description="largest gap over the wax zone and gap under the foot, half/full weight"
    )
    foot_gap_half_weight_mm: float | None
    foot_gap_half_weight_band_mm: float | None
    closing_load: dict[str, Any]
    kick_zone: dict[str, Any]
    wheelbase: dict[str, Any]
    glide_check: dict[str, Any]
    band: dict[str, Any]
    provenance: dict[str, Any]
    timing_ms: dict[str, float] = Field(..., description="wall-clock time per step [ms]")
    profiles: dict[str, list[float]] | None = Field(
        None, description="the profile under half and full weight"
    )


class FlexPair(BaseModel):
    model_config = _FIXED
    inputs: dict[str, Any]
    left: FlexSheet
    right: FlexSheet
    flex_differences: list[dict[str, Any]]
    metric_differences: list[dict[str, Any]] | None
    flagged: bool
    flagged_quantities: list[str]
    rule: str


class FlexRanking(BaseModel):
    model_config = _FIXED
    inputs: dict[str, Any]
    criterion: dict[str, Any]
    ranking: list[dict[str, Any]]
    left_out: list[dict[str, Any]]
    qualifies: bool = Field(..., description="at least one ski suits the skier")
    message: str | None = Field(None, description="why no ski qualifies, when none does")
    rule: str


# ------------------------------------------------------------------------ items, jobs


class JobView(BaseModel):
    model_config = _FIXED
    id: str
    kind: str
    item: str | None
    item_id: str | None
    state: str = Field(..., description="queued, running, done or failed")
    progress: float = Field(..., ge=0, le=1)
    message: str
    error: str | None
    created_at: str
    updated_at: str
    lane: str = Field(
        ...,
        description="short (grind tables) or long (ski networks): the lanes "
        "run side by side, so a short job never waits behind a long one",
    )
    queue_position: int | None = Field(
        None, description="1: the next job of its lane to start; null unless queued"
    )
    ahead: int = Field(0, description="jobs of its lane running or queued before it")
    estimate_s: float | None = Field(
        None,
        description="rough seconds until done, from the median upload-to-done time of the "
        "last finished jobs of its kind [s]; null without such jobs or once finished",
    )
    estimate_basis: int = Field(0, description="finished jobs the estimate rests on")


class JobList(BaseModel):
    model_config = _FIXED
    jobs: list[JobView]


class ItemView(BaseModel):
    """A catalogue item (no server paths)."""

    model_config = _FIXED
    id: str
    kind: str
    name: str
    state: str
    read_only: bool
    team: str | None
    metadata: dict[str, Any]
    file: str | None
    sha256: str | None
    created_at: str
    updated_at: str


class ItemDetail(ItemView):
    """An item, whether it is served, its jobs and, for a usable ski, its profile model and
    beam (absent otherwise)."""

    usable: bool
    jobs: list[JobView]
    profile_model: dict[str, Any] | None = None
    beam: dict[str, Any] | None = None


class GrindAccepted(BaseModel):
    model_config = _FIXED
    item: ItemView
    job: str
    job_url: str
    iso25178: dict[str, Any] = Field(..., description="ISO 25178 of the measured points (SI)")
    preparation: dict[str, Any] = Field(
        ...,
        description="what was done to the map: measured (points cut and filled, Sq moved), "
        "reduction (for the solver's size limit), notes (what the reader skipped)",
    )


class SkiAccepted(BaseModel):
    model_config = _FIXED
    item: ItemView
    job: str
    job_url: str
    data: dict[str, Any] = Field(..., description="what the camber file holds")
