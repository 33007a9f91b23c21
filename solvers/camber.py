"""Macro scale, step 2: one small neural network per ski for the loaded camber (docs/physics.md §4).

A camber measuring device presses the ski with one point load ``(F, x_F)`` against a rigid flat
and records the gap ``H*(X) ≥ 0`` between base and flat. The network, trained per ski on such
measurements (training: :mod:`app.training`, needs torch), maps ``(F, x_F)`` to the whole
loaded profile ``H*(X)``. This module is the torch-free inference: pure numpy on a plain dict.

Network (schema ``"skisnow.camber-mlp/1"``)
------------------------------------------
::

    z      = (input − input_offset) / input_scale          input = (F [N], x_F [m])
    a_0    = σ(W_0 z + b_0)                                hidden layers, σ = tanh, relu
    a_i    = σ(W_i a_{i−1} + b_i)                          or softplus (attr ``activation``)
    y      = W_L a_{L−1} + b_L                             linear output at the K_c nodes
    S_node = output_offset + output_scale · y              signed gap at the nodes [m]
    S(X)   = piecewise-linear interpolation of S_node onto positions_m
    H*(X)  = max(S(X), 0)                                  loaded gap [m]

The output is compressed **(choice)**: the network predicts a signed gap ``S`` at ``K_c`` nodes
(a subset of the sampling grid, ~5 mm apart) that is interpolated linearly onto the full
sampling grid (~1 mm, ~2000 points). The ReLU at the very end makes the contact region
``H* = 0`` exact (``S ≤ 0`` there) instead of leaving small positive or negative residues; the
training loss is one-sided where a measured gap is exactly zero (it only penalises ``S > 0``).

Dict layout
-----------
The layout of the ski file's ``network`` group (:func:`app.storage.skis.write_ski`): arrays at
the top level (HDF5 datasets) and one ``"attrs"`` dict of str, int, float and bool values (HDF5
attributes). No pickles. Arrays:

=================================== ========== ============================================
key                                 shape      meaning
=================================== ========== ============================================
``positions_m``                     (M,)       sampling grid X of the output, increasing [m]
``node_positions_m``                (K_c,)     output nodes, a subset of positions_m incl.
                                               both ends [m]
``layer{i}_weight``                 (out, in)  weights of layer i = 0 … n_layers − 1
``layer{i}_bias``                   (out,)     biases of layer i
``input_offset``                    (2,)       centre of (F [N], x_F [m])
``input_scale``                     (2,)       half-range of (F [N], x_F [m])
``output_offset``                   (K_c,)     mean training gap at each node [m]
``output_scale``                    (K_c,)     output scale at each node [m]
``split_{set}_loads_n``             (n_set,)   load cases of set ∈ {train, validation, test}
``split_{set}_load_positions_m``    (n_set,)   their load positions [m]
``history_train_loss``              (epochs,)  training loss per epoch [-]
``history_validation_loss``         (epochs,)  validation loss per epoch [-]
=================================== ========== ============================================

Required entries of ``"attrs"``: ``schema``, ``n_layers``, ``activation`` (a key of
:data:`ACTIVATIONS`),
``output_activation`` (``"relu"``), ``load_min_n``, ``load_max_n``, ``load_position_min_m``,
``load_position_max_m`` (the trained range: inference outside it raises
:class:`~solvers.errors.OutOfRangeError`).
Training metadata (seed, epochs, losses, metrics, torch version, timestamps, …) are further
attributes, listed in ``docs/camber-network.md``. The split and loss-history arrays are optional
for inference.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .errors import DataFileError, InputError, OutOfRangeError

__all__ = [
    "ACTIVATIONS",
    "SCHEMA",
    "CamberPrediction",
    "check_network",
    "contact_band_rmse_m",
    "interpolation_weights",
    "network_from_arrays",
    "network_to_dict",
    "predict_profile",
    "predict_profiles",
    "select_nodes",
    "signed_node_gaps",
]

#: schema string stored in the ``schema`` attribute of every camber network
SCHEMA = "skisnow.camber-mlp/1"

#: gap band that decides contact (accuracy targets and loss weight use it) [m]
CONTACT_BAND_M = 0.2e-3

#: relative tolerance on the edges of the trained range (float rounding of stored bounds) [-]
_RANGE_RTOL = 1e-9

#: hidden-layer activations (numpy); app.training.model has the torch twins
ACTIVATIONS = {
    "tanh": np.tanh,
    "relu": lambda a: np.maximum(a, 0.0),
    "softplus": lambda a: np.logaddexp(0.0, a),
}

_REQUIRED_ATTRS = (
    "schema",
    "n_layers",
    "activation",
    "output_activation",
    "load_min_n",
    "load_max_n",
    "load_position_min_m",
    "load_position_max_m",
)


@dataclass(frozen=True)
class CamberPrediction:
    """Loaded profiles predicted for several load cases.

    Attributes
    ----------
    positions_m : ndarray, shape (M,)
        Sampling grid X along the ski, origin at the balance point, positive to the tip [m].
    gaps_m : ndarray, shape (N, M)
        Loaded gap H*(X) ≥ 0 per load case [m]; exactly 0 in the contact zones.
    loads_n : ndarray, shape (N,)
        Equivalent loads F [N].
    load_positions_m : ndarray, shape (N,)
        Load positions x_F [m].
    """

    positions_m: np.ndarray
    gaps_m: np.ndarray
    loads_n: np.ndarray
    load_positions_m: np.ndarray


def select_nodes(positions_m: np.ndarray, node_spacing_m: float) -> np.ndarray:
    """Indices of output nodes: a subset of the grid about ``node_spacing_m`` apart.

    Parameters
    ----------
    positions_m : ndarray, shape (M,)
        Strictly increasing sampling grid [m].
    node_spacing_m : float
        Wanted spacing of the nodes [m]; 0 keeps every grid point.

    Returns
    -------
    ndarray of int
        Increasing indices into ``positions_m``, always including the first and last point.
    """
    x = _check_grid(positions_m)
    if not np.isfinite(node_spacing_m) or node_spacing_m < 0:
        raise InputError(f"node_spacing_m must be finite and >= 0, got {node_spacing_m}")
    idx = [0]
    for i in range(1, x.size - 1):
        if x[i] - x[idx[-1]] >= node_spacing_m * (1 - 1e-9):
            idx.append(i)
    if x.size > 1:
        if idx[-1] != 0 and x[-1] - x[idx[-1]] < 0.5 * node_spacing_m:
            idx.pop()  # avoid a tiny last interval: merge it with the previous one
        idx.append(x.size - 1)
    return np.asarray(idx, dtype=np.intp)


def interpolation_weights(
    node_positions_m: np.ndarray, positions_m: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Left node index and weight of the right node for linear interpolation.

    ``S(X_j) = (1 − w_j) S_node[i_j] + w_j S_node[i_j + 1]`` with ``(i, w)`` returned here.
    Points outside the node range are clamped to the end nodes (never happens for a valid
    network: the nodes include both ends of the grid).
    """
    nodes = np.asarray(node_positions_m, dtype=float)
    x = np.asarray(positions_m, dtype=float)
    if nodes.size == 1:
        return np.zeros(x.size, dtype=np.intp), np.zeros(x.size)
    i = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, nodes.size - 2)
    w = np.clip((x - nodes[i]) / (nodes[i + 1] - nodes[i]), 0.0, 1.0)
    return i.astype(np.intp), w


def network_from_arrays(
    *,
    positions_m: np.ndarray,
    node_positions_m: np.ndarray,
    weights: list[np.ndarray],
    biases: list[np.ndarray],
    input_offset: np.ndarray,
    input_scale: np.ndarray,
    output_offset: np.ndarray,
    output_scale: np.ndarray,
    load_range_n: tuple[float, float],
    load_position_range_m: tuple[float, float],
    activation: str = "tanh",
    metadata: Mapping[str, object] | None = None,
    extra_arrays: Mapping[str, np.ndarray] | None = None,
) -> dict:
    """Assemble (and check) the network dict of schema ``"skisnow.camber-mlp/1"``.

    Parameters
    ----------
    positions_m : ndarray, shape (M,)
        Output sampling grid [m].
    node_positions_m : ndarray, shape (K_c,)
        Output nodes [m], increasing, covering ``positions_m``.
    weights, biases : list of ndarray
        Layer weights ``(out, in)`` and biases ``(out,)`` (torch ``nn.Linear`` layout).
    input_offset, input_scale : ndarray, shape (2,)
        Normalisation of (F [N], x_F [m]).
    output_offset, output_scale : ndarray, shape (K_c,)
        De-normalisation of the node outputs [m].
    load_range_n : (float, float)
        Trained range of F [N].
    load_position_range_m : (float, float)
        Trained range of x_F [m].
    activation : str
        Hidden-layer activation, a key of :data:`ACTIVATIONS`.
    metadata : mapping, optional
        Scalar/str attributes to add to ``"attrs"`` (training metadata, metrics).
    extra_arrays : mapping, optional
        Further arrays (split, loss history).

    Returns
    -------
    dict
        Arrays at the top level, scalar attributes in ``"attrs"``.
    """
    if len(weights) != len(biases) or not weights:
        raise InputError(
            f"need as many weights as biases (>= 1), got {len(weights)}, {len(biases)}"
        )
    attrs: dict = {
        "schema": SCHEMA,
        "n_layers": len(weights),
        "activation": str(activation),
        "output_activation": "relu",
        "load_min_n": float(load_range_n[0]),
        "load_max_n": float(load_range_n[1]),
        "load_position_min_m": float(load_position_range_m[0]),
        "load_position_max_m": float(load_position_range_m[1]),
    }
    for key, value in (metadata or {}).items():
        if key in attrs:
            raise InputError(f"metadata key {key!r} clashes with a network attribute")
        attrs[key] = value
    net: dict = {
        "attrs": attrs,
        "positions_m": np.asarray(positions_m, dtype=np.float64),
        "node_positions_m": np.asarray(node_positions_m, dtype=np.float64),
        "input_offset": np.asarray(input_offset, dtype=np.float64),
        "input_scale": np.asarray(input_scale, dtype=np.float64),
        "output_offset": np.asarray(output_offset, dtype=np.float64),
        "output_scale": np.asarray(output_scale, dtype=np.float64),
    }
    for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
        net[f"layer{i}_weight"] = np.asarray(w, dtype=np.float64)
        net[f"layer{i}_bias"] = np.asarray(b, dtype=np.float64)
    for key, value in (extra_arrays or {}).items():
        if key in net:
            raise InputError(f"extra array {key!r} clashes with a network array")
        net[key] = np.asarray(value)
    return network_to_dict(net)


def network_to_dict(network: Mapping[str, object]) -> dict:
    """Checked copy of a network in the plain layout stored under a ski file's ``network``.

    Accepts what :func:`app.storage.skis.read_ski` returns (numpy scalars, bytes, 0-d arrays)
    and normalises it: arrays stay float/int ndarrays, attributes become Python scalars or str.

    Raises
    ------
    DataFileError
        Not a valid ``"skisnow.camber-mlp/1"`` network.
    """
    if not isinstance(network, Mapping) or not isinstance(network.get("attrs"), Mapping):
        raise DataFileError("camber network must be a mapping with an 'attrs' mapping")
    out: dict = {"attrs": {key: _plain(value) for key, value in network["attrs"].items()}}
    for key, value in network.items():
        if key == "attrs":
            continue
        if isinstance(value, Mapping):
            raise DataFileError(f"camber network entry {key!r} is a group; expected an array")
        out[key] = np.array(value)
    check_network(out)
    return out


def check_network(network: Mapping[str, object]) -> None:
    """Raise :class:`~solvers.errors.DataFileError` unless ``network`` is a valid camber MLP."""
    attrs = network.get("attrs")
    if not isinstance(attrs, Mapping):
        raise DataFileError("camber network lacks its 'attrs' mapping")
    missing = [k for k in _REQUIRED_ATTRS if k not in attrs]
    if missing:
        raise DataFileError(f"camber network lacks attributes {missing}")
    if attrs["schema"] != SCHEMA:
        raise DataFileError(f"camber network schema must be {SCHEMA!r}, got {attrs['schema']!r}")
    if attrs["activation"] not in ACTIVATIONS or attrs["output_activation"] != "relu":
        raise DataFileError(
            f"camber network activation must be one of {sorted(ACTIVATIONS)} with a relu "
            f"output, got {attrs['activation']!r}/{attrs['output_activation']!r}"
        )
    for key in ("load_min_n", "load_max_n", "load_position_min_m", "load_position_max_m"):
        if not np.isfinite(float(attrs[key])):
            raise DataFileError(f"camber network attribute {key} is not finite")
    if not (attrs["load_min_n"] <= attrs["load_max_n"]) or not (
        attrs["load_position_min_m"] <= attrs["load_position_max_m"]
    ):
        raise DataFileError("camber network trained range has min > max")
    n_layers = int(attrs["n_layers"])
    keys = ["positions_m", "node_positions_m", "input_offset", "input_scale"]
    keys += ["output_offset", "output_scale"]
    keys += [f"layer{i}_{p}" for i in range(n_layers) for p in ("weight", "bias")]
    absent = [k for k in keys if k not in network]
    if absent:
        raise DataFileError(f"camber network lacks arrays {absent}")
    n_in = 2
    for i in range(n_layers):
        w = np.asarray(network[f"layer{i}_weight"])
        b = np.asarray(network[f"layer{i}_bias"])
        if w.ndim != 2 or w.shape[1] != n_in or b.shape != (w.shape[0],):
            raise DataFileError(
                f"camber network layer {i}: weight {w.shape}, bias {b.shape} do not chain "
                f"from {n_in} inputs"
            )
        n_in = w.shape[0]
    nodes = np.asarray(network["node_positions_m"])
    if nodes.shape != (n_in,):
        raise DataFileError(f"camber network has {n_in} outputs but {nodes.size} nodes")
    for key in ("output_offset", "output_scale"):
        if np.asarray(network[key]).shape != (n_in,):
            raise DataFileError(f"camber network {key} must have shape ({n_in},)")
    for key in ("input_offset", "input_scale"):
        if np.asarray(network[key]).shape != (2,):
            raise DataFileError(f"camber network {key} must have shape (2,)")
    x = np.asarray(network["positions_m"])
    if x.ndim != 1 or x.size < 2 or not np.all(np.diff(x) > 0):
        raise DataFileError("camber network positions_m must be strictly increasing, size >= 2")
    if nodes.size >= 2 and not np.all(np.diff(nodes) > 0):
        raise DataFileError("camber network node_positions_m must be strictly increasing")
    if nodes[0] > x[0] or nodes[-1] < x[-1]:
        raise DataFileError("camber network nodes must cover positions_m")
    for key in keys:
        if not np.all(np.isfinite(np.asarray(network[key], dtype=float))):
            raise DataFileError(f"camber network {key} contains NaN or inf")
    if not np.all(np.asarray(network["input_scale"]) > 0):
        raise DataFileError("camber network input_scale must be > 0")


def predict_profiles(
    network: Mapping[str, object],
    loads_n: np.ndarray,
    load_positions_m: np.ndarray,
) -> CamberPrediction:
    """Loaded camber profiles H*(X) for many equivalent loads (vectorised).

    Parameters
    ----------
    network : mapping
        Camber network dict of schema ``"skisnow.camber-mlp/1"``.
    loads_n : array_like, shape (N,)
        Equivalent loads F [N], within the trained range.
    load_positions_m : array_like, shape (N,)
        Load positions x_F relative to the balance point, positive to the tip [m], within the
        trained range.

    Returns
    -------
    CamberPrediction
        Grid and gaps ``(N, M)`` [m], non-negative.

    Raises
    ------
    InputError
        Inputs not finite, not 1-D or of different lengths.
    OutOfRangeError
        A load or position outside the range the network was trained on (no extrapolation).
    """
    f = np.atleast_1d(np.asarray(loads_n, dtype=float))
    xf = np.atleast_1d(np.asarray(load_positions_m, dtype=float))
    if f.ndim != 1 or xf.shape != f.shape:
        raise InputError(
            f"loads_n and load_positions_m must be 1-D of equal length, got {f.shape}, {xf.shape}"
        )
    attrs = network["attrs"]
    _check_in_range(f, "loads_n", attrs["load_min_n"], attrs["load_max_n"], "N")
    _check_in_range(
        xf, "load_positions_m", attrs["load_position_min_m"], attrs["load_position_max_m"], "m"
    )
    gaps = _forward(network, np.stack([f, xf], axis=1))
    return CamberPrediction(
        positions_m=np.asarray(network["positions_m"], dtype=float),
        gaps_m=gaps,
        loads_n=f,
        load_positions_m=xf,
    )


def predict_profile(
    network: Mapping[str, object], load_n: float, load_position_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Loaded camber profile H*(X) for one equivalent load.

    Parameters
    ----------
    network : mapping
        Camber network dict of schema ``"skisnow.camber-mlp/1"``.
    load_n : float
        Equivalent load F [N], within the trained range.
    load_position_m : float
        Load position x_F relative to the balance point, positive to the tip [m].

    Returns
    -------
    positions_m : ndarray, shape (M,)
        Sampling grid X [m].
    gap_m : ndarray, shape (M,)
        Loaded gap H*(X) ≥ 0 [m], exactly 0 in the contact zones.
    """
    if np.ndim(load_n) != 0 or np.ndim(load_position_m) != 0:
        raise InputError("load_n and load_position_m must be scalars; use predict_profiles")
    pred = predict_profiles(network, np.array([load_n]), np.array([load_position_m]))
    return pred.positions_m, pred.gaps_m[0]


def contact_band_rmse_m(
    predicted_m: np.ndarray, true_m: np.ndarray, band_m: float = CONTACT_BAND_M
) -> float:
    """RMSE of H* over the points where the true gap is below ``band_m`` [m].

    This is the accuracy target of the camber network (≤ 5 µm for ``band_m`` = 0.2 mm on
    held-out load cases). NaN if no point lies in the band.
    """
    p = np.asarray(predicted_m, dtype=float)
    t = np.asarray(true_m, dtype=float)
    if p.shape != t.shape:
        raise InputError(f"predicted_m and true_m shapes differ: {p.shape} vs {t.shape}")
    mask = t < band_m
    if not mask.any():
        return float("nan")
    return float(np.sqrt(np.mean((p[mask] - t[mask]) ** 2)))


def signed_node_gaps(network: Mapping[str, object], inputs: np.ndarray) -> np.ndarray:
    """Signed gap S at the output nodes [m], shape (N, K_c), before interpolation and ReLU.

    ``inputs`` (N, 2) are (F [N], x_F [m]) in physical units; no range check (use
    :func:`predict_profiles` for answers).
    """
    a = (np.asarray(inputs, dtype=float) - network["input_offset"]) / network["input_scale"]
    n_layers = int(network["attrs"]["n_layers"])
    sigma = ACTIVATIONS[network["attrs"]["activation"]]
    for i in range(n_layers):
        a = a @ np.asarray(network[f"layer{i}_weight"]).T + network[f"layer{i}_bias"]
        if i < n_layers - 1:
            a = sigma(a)
    return network["output_offset"] + network["output_scale"] * a


def _forward(network: Mapping[str, object], inputs: np.ndarray) -> np.ndarray:
    """Gaps (N, M) for inputs (N, 2) = (F [N], x_F [m])."""
    s_nodes = signed_node_gaps(network, inputs)
    i, w = interpolation_weights(network["node_positions_m"], network["positions_m"])
    if s_nodes.shape[1] == 1:
        s = np.repeat(s_nodes, i.size, axis=1)
    else:
        s = s_nodes[:, i] * (1.0 - w) + s_nodes[:, i + 1] * w
    return np.maximum(s, 0.0)


def _plain(value):
    """HDF5 attribute value → Python scalar or str (arrays of size > 1 kept as lists)."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray):
        return value.item() if value.size == 1 else value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def _check_in_range(values: np.ndarray, name: str, lo, hi, unit: str) -> None:
    lo, hi = float(lo), float(hi)
    if not np.all(np.isfinite(values)):
        raise InputError(f"{name} must be finite, got {values[~np.isfinite(values)][0]}")
    tol = _RANGE_RTOL * max(hi - lo, abs(hi), abs(lo), 1e-300)
    bad = (values < lo - tol) | (values > hi + tol)
    if bad.any():
        raise OutOfRangeError(
            f"{name} = {values[bad][0]:g} {unit} is outside the trained range "
            f"[{lo:g}, {hi:g}] {unit} of this camber network (no extrapolation)"
        )


def _check_grid(positions_m: np.ndarray) -> np.ndarray:
    x = np.asarray(positions_m, dtype=float)
    if x.ndim != 1 or x.size < 2 or not np.all(np.isfinite(x)) or not np.all(np.diff(x) > 0):
        raise InputError("positions_m must be a finite, strictly increasing 1-D grid of size >= 2")
    return x
