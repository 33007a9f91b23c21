"""The camber network in torch: layers, forward pass, smoother, and folding members into one MLP.

The torch twins of the numpy inference in :mod:`solvers.camber` (same schema
``"skisnow.camber-mlp/1"``, float64). torch is imported only inside the functions that need it
(:func:`import_torch`); :func:`smoothing_matrix`, :func:`fold_members` and :func:`sum_networks`
are numpy only.
"""

from __future__ import annotations

import contextlib
import itertools
from collections.abc import Mapping

import numpy as np
from skisnow.solvers import camber
from skisnow.solvers.errors import InputError

__all__ = [
    "TRAIN_EXTRA_HINT",
    "build_layers",
    "fold_members",
    "import_torch",
    "node_output",
    "signed_gap",
    "smoothing_matrix",
    "sum_networks",
    "torch_predict",
    "torch_threads",
]

TRAIN_EXTRA_HINT = "training the camber network needs PyTorch: pip install 'skisnow[train]'"


@contextlib.contextmanager
def torch_threads(torch, n: int):
    """Run with ``n`` torch threads and deterministic algorithms, restoring both afterwards."""
    previous = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    torch.set_num_threads(int(n))
    torch.use_deterministic_algorithms(True)
    try:
        yield
    finally:
        torch.set_num_threads(previous[0])
        torch.use_deterministic_algorithms(previous[1])


def import_torch():
    """The torch module, or an ImportError that says which extra to install."""
    try:
        import torch
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(TRAIN_EXTRA_HINT) from exc
    return torch


def build_layers(torch, sizes: list[int], generator):
    """Linear float64 layers ``sizes[0] → … → sizes[-1]``: Xavier-uniform weights drawn from
    ``generator``, zero biases."""
    layers = torch.nn.ModuleList()
    for n_in, n_out in itertools.pairwise(sizes):
        lin = torch.nn.Linear(n_in, n_out, dtype=torch.float64)
        with torch.no_grad():
            torch.nn.init.xavier_uniform_(lin.weight, generator=generator)
            lin.bias.zero_()
        layers.append(lin)
    return layers


def torch_activation(torch, name: str):
    """The torch function of a hidden-layer activation name (``camber.ACTIVATIONS``)."""
    return {
        "tanh": torch.tanh,
        "relu": torch.relu,
        "softplus": torch.nn.functional.softplus,
    }[name]


def node_output(torch, layers, z, out_offset, out_scale, activation="tanh", smoother=None):
    """Signed gap S at the output nodes [m] for normalised inputs z (N, 2).

    ``smoother`` (K_c, K_c), if given, is applied along the nodes: ``S ← S Gᵀ``.
    """
    sigma = torch_activation(torch, activation)
    a = z
    for i, lin in enumerate(layers):
        a = lin(a)
        if i < len(layers) - 1:
            a = sigma(a)
    s = out_offset + out_scale * a
    return s if smoother is None else s @ smoother.T


def smoothing_matrix(nodes_m: np.ndarray, width_m: float) -> np.ndarray:
    """Row-normalised Gaussian smoother G (K_c, K_c) along the nodes, std ``width_m`` [m].

    Truncated at 4 standard deviations and renormalised at the ski ends. ``width_m`` = 0 gives
    the identity.
    """
    x = np.asarray(nodes_m, dtype=float)
    if width_m <= 0:
        return np.eye(x.size)
    d = (x[:, None] - x[None, :]) / width_m
    g = np.where(np.abs(d) <= 4.0, np.exp(-0.5 * d * d), 0.0)
    return g / g.sum(axis=1, keepdims=True)


def signed_gap(torch, layers, z, out_offset, out_scale, idx, w, activation):
    """Signed gap S on the full grid (before ReLU) for normalised inputs z (N, 2)."""
    s_nodes = node_output(torch, layers, z, out_offset, out_scale, activation)
    if s_nodes.shape[1] == 1:
        return s_nodes.expand(-1, idx.numel())
    return s_nodes[:, idx] * (1.0 - w) + s_nodes[:, idx + 1] * w


def torch_predict(
    network: Mapping[str, object], loads_n: np.ndarray, load_positions_m: np.ndarray
) -> np.ndarray:
    """Reference forward pass in torch (float64) of a network dict: gaps (N, M) [m].

    Used to check that the numpy inference of :mod:`solvers.camber` reproduces torch.
    """
    torch = import_torch()
    n_layers = int(network["attrs"]["n_layers"])
    sizes = [2] + [int(np.asarray(network[f"layer{i}_weight"]).shape[0]) for i in range(n_layers)]
    layers = build_layers(torch, sizes, torch.Generator().manual_seed(0))
    with torch.no_grad():
        for i, lin in enumerate(layers):
            lin.weight.copy_(torch.as_tensor(np.asarray(network[f"layer{i}_weight"])))
            lin.bias.copy_(torch.as_tensor(np.asarray(network[f"layer{i}_bias"])))
        x = torch.as_tensor(
            np.stack([np.asarray(loads_n, float), np.asarray(load_positions_m, float)], axis=1)
        )
        z = (x - torch.as_tensor(network["input_offset"])) / torch.as_tensor(network["input_scale"])
        idx, w = camber.interpolation_weights(network["node_positions_m"], network["positions_m"])
        s = signed_gap(
            torch,
            layers,
            z,
            torch.as_tensor(network["output_offset"]),
            torch.as_tensor(network["output_scale"]),
            torch.as_tensor(idx),
            torch.as_tensor(w),
            network["attrs"]["activation"],
        )
        return torch.relu(s).numpy()


def fold_members(members, out_offset, out_scale, smoother):
    """One MLP equal to the mean of the members' outputs, with scale and smoother folded in.

    Member j gives ``S_j = G (off + scale ⊙ (W_j a_j + b_j))``; their mean is one network
    with stacked first layers, block-diagonal hidden layers and a last layer
    ``[G diag(scale) W_1, …, G diag(scale) W_n] / n``, bias ``G (scale ⊙ mean_j b_j)`` and
    output offset ``G off`` (set by the caller) with unit output scale.
    """
    n = len(members)
    scaled = []
    for m in members:
        w, b = list(m["weights"]), list(m["biases"])
        w[-1] = smoother @ (out_scale[:, None] * w[-1]) / n
        b[-1] = smoother @ (out_scale * b[-1]) / n
        scaled.append((w, b))
    return sum_networks(scaled)


def sum_networks(
    members: list[tuple[list[np.ndarray], list[np.ndarray]]],
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Weights and biases of one MLP whose output is the sum of the members' outputs.

    Each member is ``(weights, biases)`` with the same number of layers and activation: the
    first layers are stacked, hidden layers block-diagonal, the last layers concatenated
    (biases summed). A single-layer (linear) member set is summed directly.
    """
    n_layers = len(members[0][0])
    if any(len(w) != n_layers for w, _ in members):
        raise InputError("sum_networks needs members with the same number of layers")
    if n_layers == 1:
        return [sum(w[0] for w, _ in members)], [sum(b[0] for _, b in members)]
    weights, biases = [], []
    for i in range(n_layers):
        ws = [w[i] for w, _ in members]
        bs = [b[i] for _, b in members]
        if i == 0:
            weights.append(np.vstack(ws))
            biases.append(np.concatenate(bs))
        elif i < n_layers - 1:
            weights.append(_block_diag(ws))
            biases.append(np.concatenate(bs))
        else:
            weights.append(np.hstack(ws))
            biases.append(np.sum(bs, axis=0))
    return weights, biases


def _block_diag(blocks: list[np.ndarray]) -> np.ndarray:
    """Block-diagonal matrix of ``blocks`` (numpy only)."""
    rows = sum(b.shape[0] for b in blocks)
    cols = sum(b.shape[1] for b in blocks)
    out = np.zeros((rows, cols))
    r = c = 0
    for b in blocks:
        out[r : r + b.shape[0], c : c + b.shape[1]] = b
        r += b.shape[0]
        c += b.shape[1]
    return out
