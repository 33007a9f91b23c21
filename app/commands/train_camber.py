"""``skisnow train-camber``: train a ski's camber network and store it in the ski file.

Reads the measurements of a stored ski (or a neutral camber CSV), trains the network
(:func:`app.training.fit.train_camber_network`, needs ``pip install 'skisnow[train]'``), prints
the held-out accuracy and, for a ski that stores its design beam, the check against that beam
(:func:`app.training.check.store_beam_truth_check`), and writes the network into the ski file
(or a copy, ``--out``).
"""

from __future__ import annotations

import argparse
import logging
import shutil
from pathlib import Path

from skisnow.app.training.check import store_beam_truth_check
from skisnow.app.training.data import camber_training_arrays
from skisnow.app.training.files import write_network_to_ski
from skisnow.app.training.fit import train_camber_network
from skisnow.solvers import camber
from skisnow.solvers.errors import DataFileError

log = logging.getLogger(__name__)


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


def run(args: argparse.Namespace) -> int:
    """Entry point of ``skisnow train-camber``."""
    from skisnow.app.storage import skis
    from skisnow.app.storage.common import provenance

    ski_path = _resolve_ski_path(args.ski)
    if not ski_path.is_file():
        raise DataFileError(f"ski file not found: {ski_path}")
    record = skis.read_ski(ski_path)
    data = skis.read_camber_csv(args.csv) if args.csv else record.measurements
    for note in skis.reading_notes(data) if args.csv else []:
        log.warning("%s: %s", args.csv, note)
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
        t, papers_case = store_beam_truth_check(net, record.beam, record.outline, seed=args.seed)
        print(
            "  vs beam truth (noise-free): RMSE(H*<0.2 mm) test "
            f"{t['truth_rmse_band_test_m'] * 1e6:.2f} µm, {t['truth_n_random']} random loads "
            f"{t['truth_rmse_band_random_m'] * 1e6:.2f} µm;"
            f" apparent contact area (BEM, E_snow 200 MPa) max |error| "
            f"{t['truth_contact_area_max_rel_error'] * 100:.2f} %, rms "
            f"{t['truth_contact_area_rms_rel_error'] * 100:.2f} %"
        )
        if papers_case:
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
