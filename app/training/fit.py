"""Train the per-ski camber network (docs/physics.md §4 step 2): :func:`train_camber_network`.

Training needs PyTorch (``pip install 'skisnow[train]'``); torch is imported lazily inside the
training functions, so the rest of skisnow (and inference, :mod:`solvers.camber`) runs without.
The data checks and the split live in :mod:`.data`, the torch network and the folding of an
ensemble in :mod:`.model`, the accuracy metrics in :mod:`.check`.

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

import datetime as _dt
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from skisnow.app.training.check import evaluate_network
from skisnow.app.training.data import check_training_data, present_unloaded, split_load_cases
from skisnow.app.training.model import (
    build_layers,
    fold_members,
    import_torch,
    node_output,
    smoothing_matrix,
    torch_threads,
)
from skisnow.solvers import camber
from skisnow.solvers.errors import InputError

__all__ = ["TrainingResult", "train_camber_network"]


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
    test_index: np.ndarray | None = None,
) -> TrainingResult:
    """Train one camber network on measured loaded profiles of one ski.

    Parameters
    ----------
    positions_m : ndarray, shape (M,)
        Sampling grid X, strictly increasing [m].
    loads_n : ndarray, shape (K,)
        Equivalent loads F of the load cases [N], ≥ 0. A case with F = 0 is the unloaded
        profile (its load position ignored): it is presented at every measured load position
        (:func:`.data.present_unloaded`), always trains, and the trained range starts at 0 N.
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
    test_index : ndarray of int, optional
        Indices into the given cases of the test cases, chosen by the caller (a ski job's one
        held-out draw for the network and the beam, :func:`.data.draw_held_out`): interior
        loaded cases, never trained on; ``test_fraction`` is then ignored.

    Returns
    -------
    TrainingResult
    """
    torch = import_torch()
    x = np.asarray(positions_m, dtype=np.float64)
    f = np.asarray(loads_n, dtype=np.float64)
    xf = np.asarray(load_positions_m, dtype=np.float64)
    h = np.asarray(profiles_m, dtype=np.float64)
    check_training_data(x, f, xf, h)
    if test_index is not None:  # indices of the loaded cases after the unloaded rows move
        rank = np.cumsum(f != 0) - 1
        test_index = np.asarray(test_index, dtype=int)
        if test_index.size and (
            test_index.min() < 0 or test_index.max() >= f.size or (f[test_index] == 0).any()
        ):
            raise InputError("test_index must name loaded cases (F > 0) of the given cases")
        test_index = rank[test_index]
    f, xf, h, n_unloaded = present_unloaded(f, xf, h)
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
        f,
        xf,
        validation_fraction=validation_fraction,
        test_fraction=test_fraction,
        seed=seed,
        test_index=test_index,
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
    # early stopping watches the validation cases and the unloaded rows: those always train
    # (never held out), but a validation loss without them picks an epoch before the network
    # has learnt the F = 0 edge (measured: 290-400 µm off the unloaded profile at F = 0 on a
    # 5 × 5 grid, 3-8 µm with them)
    stop_rows = va if va.size else tr
    if n_unloaded:
        stop_rows = np.union1d(stop_rows, np.flatnonzero(f == 0))
    members = []
    with torch_threads(torch, threads):
        for member in range(int(ensemble)):
            members.append(
                _fit_member(
                    torch,
                    seed=int(seed) + member,
                    sizes=[2, *[int(n) for n in hidden], int(nodes.size)],
                    inputs=(np.stack([f, xf], axis=1) - in_offset) / in_scale,
                    targets=h[:, node_idx],
                    rows=(tr, stop_rows),
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
    weights, biases = fold_members(members, out_offset, out_scale, smoother)
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
        "split_rule": (
            "test: the caller's held-out cases; validation: random interior load cases (seeded)"
            if test_index is not None
            else "random interior load cases held out (seeded), whole profiles"
        ),
        "unloaded_cases": int(n_unloaded),
        "unloaded_rule": (
            "the unloaded profile (F = 0) presented at every measured load position, always trained"
            if n_unloaded
            else "no unloaded profile measured"
        ),
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
    layers = build_layers(torch, sizes, gen)
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
        s = node_output(torch, layers, t_in[idx], t_off, t_scale, activation, t_smooth)
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
