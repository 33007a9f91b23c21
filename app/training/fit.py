"""Train the per-ski camber network (method.md §4 step 2) and the ``skisnow train-camber`` command.

Training needs PyTorch (``pip install 'skisnow[train]'``); torch is imported lazily inside the
training functions, so the rest of skisnow (and inference, :mod:`solvers.camber`) runs without.

Recipe (documented in ``docs/camber-network.md``):

- Data: K measured load cases ``(F_k, x_F,k) → H*_k(X)`` on one sampling grid X (M points).
- Split by load case (whole profiles held out): a validation set (early stopping) and a test
  set (reported accuracy), both drawn only from *interior* cases (neither the smallest nor the
  largest F, nor the smallest nor the largest x_F), so that every held-out case lies inside the
  range spanned by the training cases and the metrics measure interpolation, not extrapolation.
- Model: MLP 2 → 64 → 64 → K_c (ReLU hidden by default), float64; the K_c outputs are the
  signed gap at nodes ~5 mm apart, smoothed along the ski by a fixed Gaussian (std 10 mm),
  linearly interpolated onto X, then ReLU (see :mod:`solvers.camber`). An ensemble of members
  (default 1 here, 3 in the command) is averaged and folded into one MLP of the same schema.
- Normalisation: inputs to [−1, 1] over the trained range; node outputs as
  ``offset + scale · y`` with the mean training gap per node and a per-node scale.
- Loss: mean over the nodes of ``r²`` with ``r = (S − H*) / max(H*, b)`` where ``H* ≠ 0``
  and ``r = max(S, 0) / b`` where ``H* = 0`` exactly (one-sided: contact only needs
  ``S ≤ 0``). Noisy readings around contact, negative ones included, are fitted two-sided: a
  one-sided rule for ``H* ≤ 0`` would bias the fitted gap upwards by about half the noise
  where the ski touches and shrink the apparent contact;
  ``b = 0.2 mm`` is the band that decides contact. Below ``b`` the loss is the absolute error
  in units of ``b``, above it the relative error, so the small gaps that decide contact weigh
  most and the centimetre tip rise does not dominate.
- Optimiser: full-batch Adam (one step per epoch, learning rate decayed on plateaus) with
  early stopping on the validation loss, then full-batch L-BFGS (strong Wolfe line search,
  one iteration per epoch) with early stopping; the weights of the best validation epoch win.
- Determinism: all randomness from ``seed`` (``numpy.random.default_rng(seed)`` for the
  split, a ``torch.Generator`` seeded with ``manual_seed(seed + member)`` for the initial
  weights),
  ``torch.use_deterministic_algorithms(True)``; same seed, data and thread count → same
  weights.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import itertools
import logging
import math
import os
import shutil
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from skisnow.app.storage.skis import replace_ski_group
from skisnow.solvers import camber
from skisnow.solvers.errors import DataFileError, InputError

__all__ = [
    "TrainingResult",
    "beam_truth_profiles",
    "camber_training_arrays",
    "contact_area_check",
    "evaluate_network",
    "register",
    "run",
    "split_load_cases",
    "sum_networks",
    "torch_predict",
    "train_camber_network",
    "truth_check",
    "write_network_to_ski",
]

log = logging.getLogger(__name__)

#: most negative measured gap accepted: device noise around a touching point [m]
MIN_GAP_M = -50e-6

TRAIN_EXTRA_HINT = "training the camber network needs PyTorch: pip install 'skisnow[train]'"


@dataclass
class TrainingResult:
    """Outcome of :func:`train_camber_network`.

    Attributes
    ----------
    network : dict
        Network dict of schema ``"skisnow.camber-mlp/1"`` (weights, normalisation, metadata).
    metrics : dict
        Accuracy on the train, validation and test cases (keys as in the network attrs).
    converged : bool
        True if early stopping ended training (the validation loss stopped improving) rather
        than the epoch limit.
    epochs : int
        Epochs run (Adam + L-BFGS).
    message : str
        Human-readable summary.
    """

    network: dict
    metrics: dict = field(default_factory=dict)
    converged: bool = False
    epochs: int = 0
    message: str = ""


@contextlib.contextmanager
def _torch_threads(torch, n: int):
    """Run with ``n`` torch threads and deterministic algorithms, restoring both afterwards."""
    previous = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    torch.set_num_threads(int(n))
    torch.use_deterministic_algorithms(True)
    try:
        yield
    finally:
        torch.set_num_threads(previous[0])
        torch.use_deterministic_algorithms(previous[1])


def _import_torch():
    try:
        import torch
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(TRAIN_EXTRA_HINT) from exc
    return torch


# --------------------------------------------------------------------------------------------
# split


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


# --------------------------------------------------------------------------------------------
# torch model


def _build_layers(torch, sizes: list[int], generator):
    layers = torch.nn.ModuleList()
    for n_in, n_out in itertools.pairwise(sizes):
        lin = torch.nn.Linear(n_in, n_out, dtype=torch.float64)
        with torch.no_grad():
            torch.nn.init.xavier_uniform_(lin.weight, generator=generator)
            lin.bias.zero_()
        layers.append(lin)
    return layers


def _torch_activation(torch, name: str):
    return {
        "tanh": torch.tanh,
        "relu": torch.relu,
        "softplus": torch.nn.functional.softplus,
    }[name]


def _node_output(torch, layers, z, out_offset, out_scale, activation="tanh", smoother=None):
    """Signed gap S at the output nodes [m] for normalised inputs z (N, 2).

    ``smoother`` (K_c, K_c), if given, is applied along the nodes: ``S ← S Gᵀ``.
    """
    sigma = _torch_activation(torch, activation)
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


def _signed_gap(torch, layers, z, out_offset, out_scale, idx, w, activation):
    """Signed gap S on the full grid (before ReLU) for normalised inputs z (N, 2)."""
    s_nodes = _node_output(torch, layers, z, out_offset, out_scale, activation)
    if s_nodes.shape[1] == 1:
        return s_nodes.expand(-1, idx.numel())
    return s_nodes[:, idx] * (1.0 - w) + s_nodes[:, idx + 1] * w


def torch_predict(
    network: Mapping[str, object], loads_n: np.ndarray, load_positions_m: np.ndarray
) -> np.ndarray:
    """Reference forward pass in torch (float64) of a network dict: gaps (N, M) [m].

    Used to check that the numpy inference of :mod:`solvers.camber` reproduces torch.
    """
    torch = _import_torch()
    n_layers = int(network["attrs"]["n_layers"])
    sizes = [2] + [int(np.asarray(network[f"layer{i}_weight"]).shape[0]) for i in range(n_layers)]
    layers = _build_layers(torch, sizes, torch.Generator().manual_seed(0))
    with torch.no_grad():
        for i, lin in enumerate(layers):
            lin.weight.copy_(torch.as_tensor(np.asarray(network[f"layer{i}_weight"])))
            lin.bias.copy_(torch.as_tensor(np.asarray(network[f"layer{i}_bias"])))
        x = torch.as_tensor(
            np.stack([np.asarray(loads_n, float), np.asarray(load_positions_m, float)], axis=1)
        )
        z = (x - torch.as_tensor(network["input_offset"])) / torch.as_tensor(network["input_scale"])
        idx, w = camber.interpolation_weights(network["node_positions_m"], network["positions_m"])
        s = _signed_gap(
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


# --------------------------------------------------------------------------------------------
# training


def train_camber_network(
    positions_m: np.ndarray,
    loads_n: np.ndarray,
    load_positions_m: np.ndarray,
    profiles_m: np.ndarray,
    *,
    epochs: int = 4000,
    lbfgs_epochs: int = 1500,
    seed: int = 0,
    hidden: tuple[int, ...] = (64, 64),
    activation: str = "relu",
    node_spacing_m: float = 5e-3,
    smoothing_m: float = 10e-3,
    ensemble: int = 1,
    contact_band_m: float = camber.CONTACT_BAND_M,
    validation_fraction: float = 0.15,
    test_fraction: float = 0.15,
    learning_rate: float = 1e-2,
    patience: int = 400,
    threads: int = 1,
    ski_id: str = "",
    metadata: Mapping[str, object] | None = None,
    progress: Callable[[str, int, float, float], None] | None = None,
) -> TrainingResult:
    """Train one camber network on measured loaded profiles of one ski.

    Parameters
    ----------
    positions_m : ndarray, shape (M,)
        Sampling grid X, strictly increasing [m].
    loads_n : ndarray, shape (K,)
        Equivalent loads F of the load cases [N].
    load_positions_m : ndarray, shape (K,)
        Load positions x_F of the load cases [m].
    profiles_m : ndarray, shape (K, M)
        Measured loaded gaps H*(X) [m]; readings down to ``MIN_GAP_M`` (−50 µm) are accepted as
        device noise at contact and fitted as they are (the output is clipped at zero).
    epochs : int
        Maximum number of full-batch Adam epochs (early stopping may end sooner).
    lbfgs_epochs : int
        Maximum number of L-BFGS iterations after Adam (0 disables the refinement).
    seed : int
        Seed of the split and the initial weights.
    hidden : tuple of int
        Widths of the hidden layers.
    activation : str
        Hidden-layer activation: ``"tanh"``, ``"relu"`` or ``"softplus"``.
    node_spacing_m : float
        Spacing of the output nodes [m] (0: one output per grid point).
    smoothing_m : float
        Standard deviation of the Gaussian smoother applied along the output nodes during
        training and folded into the last layer [m] (0: none). It keeps the node-to-node
        noise of the measurements out of the predicted profile, which the apparent contact
        area of the macro BEM is very sensitive to (0.3 µm of white noise on H* removes ~10 %
        of it); smooth (long-wave) errors hardly matter because the rigid approach absorbs them.
    ensemble : int
        Number of members trained from seeds ``seed, seed + 1, …`` on the same split and
        averaged; the average is folded into one MLP of the same schema (stacked first layer,
        block-diagonal hidden layers), so inference stays one forward pass.
    contact_band_m : float
        Gap band b that decides contact, weighted most by the loss [m].
    validation_fraction, test_fraction : float
        Fractions of load cases held out for early stopping and for the reported metrics.
    learning_rate : float
        Initial Adam learning rate [-].
    patience : int
        Epochs without validation improvement before a phase stops.
    threads : int
        Torch threads during training (1: small full-batch problems gain nothing from more,
        and a fixed count keeps the weights bit-reproducible).
    ski_id : str
        Identifier stored in the metadata.
    metadata : mapping, optional
        Further scalar attributes to store (e.g. provenance).
    progress : callable, optional
        ``progress(phase, epoch, train_loss, validation_loss)`` called every epoch.

    Returns
    -------
    TrainingResult
    """
    torch = _import_torch()
    x = np.asarray(positions_m, dtype=np.float64)
    f = np.asarray(loads_n, dtype=np.float64)
    xf = np.asarray(load_positions_m, dtype=np.float64)
    h = np.asarray(profiles_m, dtype=np.float64)
    _check_training_data(x, f, xf, h)
    if epochs < 1 or lbfgs_epochs < 0 or patience < 1:
        raise InputError(
            f"epochs >= 1, lbfgs_epochs >= 0, patience >= 1 required, got {epochs}, "
            f"{lbfgs_epochs}, {patience}"
        )
    if activation not in camber.ACTIVATIONS:
        raise InputError(
            f"activation must be one of {sorted(camber.ACTIVATIONS)}, got {activation!r}"
        )
    if int(ensemble) < 1:
        raise InputError(f"ensemble must be >= 1, got {ensemble}")
    if not contact_band_m > 0:
        raise InputError(f"contact_band_m must be > 0, got {contact_band_m}")
    t_start = time.perf_counter()
    started_utc = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")

    split = split_load_cases(
        f, xf, validation_fraction=validation_fraction, test_fraction=test_fraction, seed=seed
    )
    tr, va, te = split["train"], split["validation"], split["test"]

    # normalisation from the training cases only
    f_lo, f_hi = float(f[tr].min()), float(f[tr].max())
    x_lo, x_hi = float(xf[tr].min()), float(xf[tr].max())
    in_offset = np.array([(f_lo + f_hi) / 2, (x_lo + x_hi) / 2])
    in_scale = np.array([max((f_hi - f_lo) / 2, 1e-12), max((x_hi - x_lo) / 2, 1e-12)])
    node_idx = camber.select_nodes(x, node_spacing_m)
    nodes = x[node_idx]
    h_nodes = h[tr][:, node_idx]
    out_offset = h_nodes.mean(axis=0)
    # per-node scale: spread over the load cases, floored at a tenth of the contact band so
    # that nodes which hardly move (always in contact) keep a usable range
    out_scale = np.maximum(h_nodes.std(axis=0), 0.1 * contact_band_m)

    smoother = smoothing_matrix(nodes, smoothing_m)
    members = []
    with _torch_threads(torch, threads):
        for member in range(int(ensemble)):
            members.append(
                _fit_member(
                    torch,
                    seed=int(seed) + member,
                    sizes=[2, *[int(n) for n in hidden], int(nodes.size)],
                    inputs=(np.stack([f, xf], axis=1) - in_offset) / in_scale,
                    targets=h[:, node_idx],
                    rows=(tr, va if va.size else tr),
                    out_offset=out_offset,
                    out_scale=out_scale,
                    smoother=smoother,
                    activation=activation,
                    contact_band_m=contact_band_m,
                    epochs=epochs,
                    lbfgs_epochs=lbfgs_epochs,
                    learning_rate=learning_rate,
                    patience=patience,
                    progress=progress,
                )
            )
    train_time = time.perf_counter() - t_start
    weights, biases = _fold_members(members, out_offset, out_scale, smoother)
    out_offset = smoother @ out_offset
    out_scale = np.ones_like(out_offset)
    history_tr = np.concatenate([m["history_train"] for m in members])
    history_va = np.concatenate([m["history_validation"] for m in members])
    best = {
        "epoch": int(np.mean([m["best_epoch"] for m in members])),
        "loss": float(np.mean([m["best_validation_loss"] for m in members])),
    }
    adam_epochs = int(sum(m["adam_epochs"] for m in members))
    stopped_early = all(m["stopped_early"] for m in members)
    extra = {
        "history_train_loss": history_tr,
        "history_validation_loss": history_va,
    }
    for name, rows in split.items():
        extra[f"split_{name}_loads_n"] = f[rows]
        extra[f"split_{name}_load_positions_m"] = xf[rows]
    meta: dict[str, object] = {
        "ski_id": str(ski_id),
        "seed": int(seed),
        "dtype": "float64",
        "hidden_layers": ",".join(str(n) for n in hidden),
        "node_spacing_m": float(node_spacing_m),
        "smoothing_m": float(smoothing_m),
        "n_nodes": int(nodes.size),
        "contact_band_m": float(contact_band_m),
        "loss": "mean r^2; r=(S-H)/max(H,b) where H!=0, r=relu(S)/b where H==0 exactly",
        "optimizer": "full-batch Adam + ReduceLROnPlateau, then L-BFGS (strong Wolfe)",
        "learning_rate": float(learning_rate),
        "patience": int(patience),
        "epochs_max": int(epochs),
        "lbfgs_epochs_max": int(lbfgs_epochs),
        "epochs_adam": int(adam_epochs),
        "epochs_run": int(history_va.size),
        "best_epoch": int(best["epoch"]),
        "stopped_early": bool(stopped_early),
        "ensemble_members": int(ensemble),
        "member_epochs_run": ",".join(str(m["history_train"].size) for m in members),
        "member_best_epochs": ",".join(str(m["best_epoch"]) for m in members),
        "member_validation_loss_best": ",".join(
            f"{m['best_validation_loss']:.6e}" for m in members
        ),
        "train_loss_best": float(np.mean([m["best_train_loss"] for m in members])),
        "validation_loss_best": float(best["loss"]),
        "validation_fraction": float(validation_fraction),
        "test_fraction": float(test_fraction),
        "split_rule": "random interior load cases held out (seeded), whole profiles",
        "n_cases_train": int(tr.size),
        "n_cases_validation": int(va.size),
        "n_cases_test": int(te.size),
        "torch_version": str(torch.__version__),
        "numpy_version": np.__version__,
        "torch_threads": int(threads),
        "trained_started_utc": started_utc,
        "trained_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "training_time_s": float(train_time),
    }
    network = camber.network_from_arrays(
        positions_m=x,
        node_positions_m=nodes,
        weights=weights,
        biases=biases,
        input_offset=in_offset,
        input_scale=in_scale,
        output_offset=out_offset,
        output_scale=out_scale,
        load_range_n=(f_lo, f_hi),
        load_position_range_m=(x_lo, x_hi),
        activation=activation,
        metadata=meta,
        extra_arrays=extra,
    )
    metrics: dict[str, object] = {}
    for name, rows in split.items():
        if rows.size:
            m = evaluate_network(network, f[rows], xf[rows], h[rows], band_m=contact_band_m)
            metrics.update({f"{name}_{k}": v for k, v in m.items()})
    for key, value in (metadata or {}).items():
        network["attrs"].setdefault(key, value)
    network["attrs"].update({f"metric_{k}": v for k, v in metrics.items()})
    camber.check_network(network)
    message = (
        f"{ensemble} member(s), {history_va.size} epochs ({adam_epochs} Adam), "
        f"mean best epoch {best['epoch']}, "
        f"validation loss {best['loss']:.3e}, "
        + (
            f"test RMSE(H*<{contact_band_m * 1e3:g} mm) = "
            f"{metrics.get('test_rmse_band_m', float('nan')) * 1e6:.2f} µm, "
            if te.size
            else ""
        )
        + f"{train_time:.1f} s"
    )
    return TrainingResult(
        network=network,
        metrics=metrics,
        converged=stopped_early,
        epochs=int(history_va.size),
        message=message,
    )


def _fit_member(
    torch,
    *,
    seed,
    sizes,
    inputs,
    targets,
    rows,
    out_offset,
    out_scale,
    smoother,
    activation,
    contact_band_m,
    epochs,
    lbfgs_epochs,
    learning_rate,
    patience,
    progress,
    base=None,
) -> dict:
    """Train one MLP (Adam, then L-BFGS) with early stopping; the best-validation weights win.

    ``base`` (K, K_c), if given, is a fixed signed gap added to the network's output for each
    load case before the loss (a second network trained on what a first one leaves).
    """
    gen = torch.Generator().manual_seed(int(seed))
    layers = _build_layers(torch, sizes, gen)
    with torch.no_grad():  # small last layer: start near the mean profile
        layers[-1].weight.mul_(0.1)
    # the loss is evaluated at the nodes (grid points ~node_spacing_m apart): the network's
    # output lives there, the linear interpolation in between is fixed; metrics use every point
    t_in = torch.as_tensor(inputs)
    t_h = torch.as_tensor(targets)
    # exact zeros (a device or model that reports contact) ask only S <= 0; noisy readings,
    # negative ones included, are fitted two-sided so the fit stays unbiased at contact
    t_zero = t_h == 0.0
    t_wt = 1.0 / torch.clamp(t_h, min=contact_band_m)
    t_off = torch.as_tensor(out_offset)
    t_base = None if base is None else torch.as_tensor(base)
    t_scale = torch.as_tensor(out_scale)
    t_smooth = torch.as_tensor(smoother)
    t_tr, t_va = torch.as_tensor(rows[0]), torch.as_tensor(rows[1])

    def loss_on(idx):
        s = _node_output(torch, layers, t_in[idx], t_off, t_scale, activation, t_smooth)
        if t_base is not None:
            s = s + t_base[idx]
        r = torch.where(t_zero[idx], torch.relu(s), s - t_h[idx]) * t_wt[idx]
        return torch.mean(r * r)

    params = list(layers.parameters())
    history_tr: list[float] = []
    history_va: list[float] = []
    best = {"loss": math.inf, "epoch": -1, "state": None}

    def record(phase: str, loss_tr: float) -> bool:
        with torch.no_grad():
            loss_va = float(loss_on(t_va))
        history_tr.append(loss_tr)
        history_va.append(loss_va)
        improved = loss_va < best["loss"] * (1 - 1e-6)
        if loss_va < best["loss"]:
            best.update(
                loss=loss_va,
                epoch=len(history_va) - 1,
                state=[p.detach().clone() for p in params],
            )
        if progress is not None:
            progress(phase, len(history_va) - 1, loss_tr, loss_va)
        return improved

    # phase 1: Adam with learning-rate decay on plateaus of the training loss
    opt = torch.optim.Adam(params, lr=learning_rate)
    sched = torch.optim.lr_scheduler.ReduceLROnPlateau(opt, factor=0.5, patience=100, min_lr=1e-5)
    stale = 0
    stopped_early = False
    for _ in range(epochs):
        opt.zero_grad()
        loss = loss_on(t_tr)
        loss.backward()
        opt.step()
        sched.step(float(loss.detach()))
        stale = 0 if record("adam", float(loss.detach())) else stale + 1
        if stale >= patience:
            stopped_early = True
            break
    adam_epochs = len(history_va)
    # phase 2: L-BFGS from the best Adam weights
    if lbfgs_epochs > 0:
        with torch.no_grad():
            for p, b in zip(params, best["state"], strict=True):
                p.copy_(b)
        lbfgs = torch.optim.LBFGS(
            params,
            lr=1.0,
            max_iter=1,
            history_size=50,
            line_search_fn="strong_wolfe",
            tolerance_grad=1e-12,
            tolerance_change=1e-15,
        )

        def closure():
            lbfgs.zero_grad()
            value = loss_on(t_tr)
            value.backward()
            return value

        stale = 0
        stopped_early = False
        for _ in range(lbfgs_epochs):
            loss = lbfgs.step(closure)
            if not math.isfinite(float(loss.detach())):
                break
            stale = 0 if record("lbfgs", float(loss.detach())) else stale + 1
            run_tr = history_tr[adam_epochs:]
            if len(run_tr) > 20 and run_tr[-20] - run_tr[-1] <= 1e-9 * abs(run_tr[-1]):
                break  # L-BFGS stalled (line search makes no progress)
            if stale >= patience:
                stopped_early = True
                break
    with torch.no_grad():
        for p, b in zip(params, best["state"], strict=True):
            p.copy_(b)
    return {
        "weights": [lin.weight.detach().numpy().copy() for lin in layers],
        "biases": [lin.bias.detach().numpy().copy() for lin in layers],
        "history_train": np.asarray(history_tr),
        "history_validation": np.asarray(history_va),
        "best_epoch": int(best["epoch"]),
        "best_validation_loss": float(best["loss"]),
        "best_train_loss": float(history_tr[best["epoch"]]),
        "adam_epochs": int(adam_epochs),
        "stopped_early": bool(stopped_early),
    }


def _fold_members(members, out_offset, out_scale, smoother):
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
        E' [Pa] (method.md eq. 1).
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


def _check_training_data(x, f, xf, h) -> None:
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


# --------------------------------------------------------------------------------------------
# storage


def write_network_to_ski(path: str | os.PathLike, network: Mapping[str, object]) -> None:
    """Store ``network`` as the ``network`` group of an existing ski HDF5 file, atomically.

    The file is copied beside itself, the group replaced in the copy, and the copy renamed onto
    the original only on success; the rest of the file (measurements, provenance of the ski) is
    untouched. Same group layout as :func:`app.storage.skis.write_ski`: arrays as datasets,
    ``network["attrs"]`` as attributes.
    """
    replace_ski_group(path, "network", camber.network_to_dict(network))


def read_network_from_ski(path: str | os.PathLike) -> dict:
    """Read the ``network`` group of a ski HDF5 file into a network dict."""
    import h5py

    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"ski file not found: {path}")
    with h5py.File(path, "r") as fh:
        if "network" not in fh:
            raise DataFileError(f"{path} has no camber network (run skisnow train-camber)")
        grp = fh["network"]
        net: dict = {key: grp[key][()] for key in grp}
        net["attrs"] = dict(grp.attrs)
    return camber.network_to_dict(net)


# --------------------------------------------------------------------------------------------
# command line


def register(subparsers) -> None:
    """Add the ``train-camber`` subcommand."""
    p = subparsers.add_parser(
        "train-camber",
        help="train the per-ski camber network and store it in the ski file",
        description=(
            "Train the neural network that maps an equivalent load (F, x_F) to the loaded "
            "camber profile H*(X) of one ski, evaluate it on held-out load cases and write it "
            "into the ski's HDF5 file (group 'network'). Needs pip install 'skisnow[train]'."
        ),
    )
    p.add_argument("--ski", required=True, help="ski name (tables/skis/NAME.h5) or a .h5 path")
    p.add_argument(
        "--csv", help="camber measurements (neutral CSV); default: those in the ski file"
    )
    p.add_argument("--epochs", type=int, default=4000, help="max Adam epochs (default 4000)")
    p.add_argument(
        "--lbfgs-epochs",
        type=int,
        default=1500,
        help="max L-BFGS iterations after Adam (default 1500)",
    )
    p.add_argument(
        "--activation",
        choices=sorted(camber.ACTIVATIONS),
        default="relu",
        help="hidden-layer activation (default relu)",
    )
    p.add_argument(
        "--smoothing-mm",
        type=float,
        default=10.0,
        help="Gaussian smoothing of the output along the ski, std in mm (default 10)",
    )
    p.add_argument(
        "--ensemble",
        type=int,
        default=3,
        help="members averaged into the network (default 3)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of split and weights (default 0)")
    p.add_argument("--out", help="write the trained ski file here instead of updating --ski")
    p.set_defaults(func=run)


def _resolve_ski_path(name: str) -> Path:
    p = Path(name)
    if p.suffix in (".h5", ".hdf5") or p.exists():
        return p
    from skisnow.app.storage.common import tables_dir

    return tables_dir() / "skis" / f"{name}.h5"


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


def run(args: argparse.Namespace) -> int:
    """Entry point of ``skisnow train-camber``."""
    from skisnow.app.storage import skis
    from skisnow.app.storage.common import provenance
    from skisnow.solvers.beam import G_STANDARD
    from skisnow.solvers.elastic import effective_modulus

    ski_path = _resolve_ski_path(args.ski)
    if not ski_path.is_file():
        raise DataFileError(f"ski file not found: {ski_path}")
    record = skis.read_ski(ski_path)
    data = skis.read_camber_csv(args.csv) if args.csv else record.measurements
    ski_id, x, f, xf, h, side = camber_training_arrays(data)
    log.info("training camber network for %s: %d load cases x %d points", ski_id, f.size, x.size)
    bar = _progress_bar(args.ensemble * (args.epochs + args.lbfgs_epochs))
    try:
        result = train_camber_network(
            x,
            f,
            xf,
            h,
            epochs=args.epochs,
            lbfgs_epochs=args.lbfgs_epochs,
            seed=args.seed,
            activation=args.activation,
            smoothing_m=args.smoothing_mm * 1e-3,
            ensemble=args.ensemble,
            ski_id=ski_id,
            metadata={
                "measured_side": side,
                "measurements_source": str(args.csv or ski_path),
                **{f"provenance_{k}": v for k, v in provenance().items()},
            },
            progress=bar.update,
        )
    finally:
        bar.close()
    net = result.network
    m = result.metrics
    print(f"{ski_id}: {result.message}")
    for name in ("train", "validation", "test"):
        if f"{name}_n_cases" in m:
            print(
                f"  {name:10s} {m[f'{name}_n_cases']:3d} cases  "
                f"RMSE(H*<0.2 mm) {m[f'{name}_rmse_band_m'] * 1e6:6.2f} µm  "
                f"max|err|(H*<0.2 mm) {m[f'{name}_max_abs_error_band_m'] * 1e6:6.2f} µm  "
                f"RMSE(all) {m[f'{name}_rmse_m'] * 1e6:7.2f} µm  (vs measured, with noise)"
            )
    if record.beam is not None and not args.csv:
        e_eff = effective_modulus(200e6)
        papers = (40.0 * G_STANDARD, -0.160)
        extra = []
        a = net["attrs"]
        if a["load_min_n"] <= papers[0] <= a["load_max_n"] and (
            a["load_position_min_m"] <= papers[1] <= a["load_position_max_m"]
        ):
            extra.append(papers)
        t = truth_check(
            net,
            record.beam,
            n_random=32,
            width_m=record.outline.width_m,
            effective_modulus_pa=e_eff,
            width_positions_m=record.outline.positions_m,
            seed=args.seed,
            extra_cases=extra,
        )
        for key, value in t.items():
            if key.startswith("truth_cases_"):
                net[key] = np.asarray(value)
            else:
                net["attrs"][f"metric_{key}"] = value
        print(
            "  vs beam truth (noise-free): RMSE(H*<0.2 mm) test "
            f"{t['truth_rmse_band_test_m'] * 1e6:.2f} µm, {t['truth_n_random']} random loads "
            f"{t['truth_rmse_band_random_m'] * 1e6:.2f} µm;"
            f" apparent contact area (BEM, E_snow 200 MPa) max |error| "
            f"{t['truth_contact_area_max_rel_error'] * 100:.2f} %, rms "
            f"{t['truth_contact_area_rms_rel_error'] * 100:.2f} %"
        )
        if extra:
            print(
                f"  papers' case 40 kg at -160 mm: A_app predicted "
                f"{t['truth_cases_area_pred_m2'][-1] * 1e4:.2f} cm², true "
                f"{t['truth_cases_area_true_m2'][-1] * 1e4:.2f} cm²"
            )
    out = Path(args.out) if args.out else ski_path
    if out != ski_path:
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(ski_path, out)
    write_network_to_ski(out, net)
    print(f"  written to {out}")
    return 0


class _Bar:
    def __init__(self, total: int):
        from tqdm import tqdm

        self._bar = tqdm(total=total, unit="epoch", leave=False, mininterval=0.5)

    def update(self, phase: str, epoch: int, loss_tr: float, loss_va: float) -> None:
        self._bar.update(1)
        if epoch % 50 == 0:
            self._bar.set_postfix_str(f"{phase} train {loss_tr:.2e} val {loss_va:.2e}")

    def close(self) -> None:
        self._bar.close()


def _progress_bar(total: int) -> _Bar:
    return _Bar(total)
