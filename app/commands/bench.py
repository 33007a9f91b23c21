"""``skisnow bench STAGE``: run one benchmark stage and write it to ``docs/bench/`` and
``docs/benchmarks.md`` (:mod:`app.evidence`; stages ``micro``, ``macro``, ``accuracy``)."""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace
from pathlib import Path

from skisnow.app.evidence import macro, micro, peers, peers_md, writer
from skisnow.app.evidence.accuracy import bench_accuracy, keep_previous_stages
from skisnow.app.evidence.accuracy_common import QUICK, AccuracyConfig
from skisnow.app.evidence.accuracy_plots import plot_accuracy


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``bench`` with its stages ``micro``, ``macro`` and ``accuracy``."""
    p = sub.add_parser("bench", help="benchmarks against peers; results into docs/")
    bsub = p.add_subparsers(dest="stage", required=True, metavar="STAGE")
    m = bsub.add_parser("micro", help="micro-scale solver against installed peers")
    m.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
    m.add_argument("--repeats", type=int, default=3)
    m.add_argument(
        "--peers",
        nargs="*",
        default=[],
        choices=list(micro.PEERS),
        help="old single-run peer rows (not like-for-like; --work-precision replaces them)",
    )
    m.add_argument(
        "--work-precision",
        action="store_true",
        help="the fair peer benchmark instead: work-precision curves of every installed solver "
        "(app/evidence/peers.py), written to docs/bench/micro-peers.json and .png",
    )
    m.add_argument("--wp-sizes", type=int, nargs="+", default=[256, 512])
    m.add_argument("--wp-repeats", type=int, default=5)
    m.add_argument("--threads", type=int, default=2, help="threads pinned for every solver")
    m.add_argument("--process-repeats", type=int, default=5)
    m.add_argument(
        "--solvers",
        nargs="*",
        default=["skisnow", "contactmechanics", "tamaas", "aspher"],
        choices=["skisnow", "contactmechanics", "tamaas", "aspher"],
    )
    m.add_argument("--aspher-probe-size", type=int, default=1024, help="0 skips the ASPHER probe")
    m.add_argument("--table-size", type=int, default=1024)
    m.add_argument("--table-points", type=int, default=12, help="0 skips the table sweep")
    m.add_argument(
        "--table-peers",
        nargs="*",
        default=[],
        choices=list(micro.PEERS),
        help="peers that solve the table sweep cold (slow peers take tens of minutes at 1024²)",
    )
    m.set_defaults(func=_run_micro)
    mac = bsub.add_parser("macro", help="macro BEM per demo ski: default grid vs fine reference")
    mac.add_argument("--repeats", type=int, default=7)
    mac.add_argument(
        "--no-identification",
        dest="identification",
        action="store_false",
        help="leave out the beam identification (demo skis and study designs; minutes per ski)",
    )
    mac.add_argument(
        "--no-job",
        dest="job",
        action="store_false",
        help="leave out the ski job end to end (upload to done with the default network; about "
        "a minute per ski)",
    )
    only = mac.add_mutually_exclusive_group()
    only.add_argument(
        "--only-identification",
        action="store_true",
        help="run only the beam identification; the other parts are kept from the last run "
        "(docs/bench/macro.json), with the provenance of the run that measured each",
    )
    only.add_argument(
        "--only-job",
        action="store_true",
        help="run only the ski job end to end; the other parts are kept from the last run",
    )
    mac.set_defaults(func=_run_macro)
    _register_accuracy(bsub)


def _register_accuracy(bsub: argparse._SubParsersAction) -> None:
    a = bsub.add_parser("accuracy", help="error against a converged reference versus time")
    a.add_argument("--quick", action="store_true", help="CI-sized smoke run (tiny sizes)")
    a.add_argument(
        "--stages",
        nargs="+",
        choices=list(AccuracyConfig.stages),
        help="run only these stages (default: all)",
    )
    a.add_argument(
        "--micro-sizes", type=int, nargs="+", help="micro grid sizes, finest is the reference"
    )
    a.add_argument(
        "--out",
        type=Path,
        help="docs directory to write (default: docs/; with --quick a temporary directory, "
        "so a smoke run never replaces the committed results)",
    )
    a.set_defaults(func=_run_accuracy)


def _run_micro(args: argparse.Namespace) -> int:
    if args.work_precision:
        with tempfile.TemporaryDirectory(prefix="skisnow-wp-") as tmp:
            data = peers.bench_work_precision(
                args.wp_sizes,
                args.wp_repeats,
                args.solvers,
                args.threads,
                args.process_repeats,
                args.aspher_probe_size or None,
                Path(tmp),
            )
        path = writer.write_stage("micro-peers", data, peers_md.plot_work_precision)
        print(f"wrote {path} and {writer.DOCS / 'benchmarks.md'}")
        return 0
    data = micro.bench_micro(
        args.sizes,
        args.repeats,
        args.peers,
        args.table_size,
        args.table_points,
        args.table_peers,
    )
    path = writer.write_stage("micro", data, micro.plot_micro)
    print(f"wrote {path} and {writer.DOCS / 'benchmarks.md'}")
    return 0


def _run_macro(args: argparse.Namespace) -> int:
    from skisnow.app.api.factory import create_api
    from skisnow.app.evidence import identification, ski_job

    previous = writer.DOCS / "bench" / "macro.json"
    if args.only_identification:
        data = macro.rerun_only(previous, "identification", identification.bench_identification)
    elif args.only_job:
        data = macro.rerun_only(previous, "ski_job", lambda: ski_job.bench_ski_job(create_api))
    else:
        data = macro.bench_macro_stage(
            args.repeats,
            identification=args.identification,
            make_app=create_api if args.job else None,
        )
    path = writer.write_stage("macro", data, None)
    print(f"wrote {path} and {writer.DOCS / 'benchmarks.md'}")
    return 0


def _run_accuracy(args: argparse.Namespace) -> int:
    cfg = QUICK if args.quick else AccuracyConfig()
    if args.stages:
        cfg = replace(cfg, stages=tuple(args.stages))
    if args.micro_sizes:
        cfg = replace(cfg, micro_sizes=tuple(sorted(args.micro_sizes)))
    data = bench_accuracy(cfg)
    if args.out is not None:
        docs_dir = args.out
    elif args.quick:
        docs_dir = Path(tempfile.gettempdir()) / "skisnow-bench-accuracy-quick"
    else:
        docs_dir = writer.DOCS
    if args.stages:  # keep the stages not re-run from the last run
        keep_previous_stages(data, docs_dir / "bench" / "accuracy.json", args.stages)
    path = writer.write_stage("accuracy", data, plot_accuracy, docs_dir=docs_dir)
    print(f"wrote {path} and {path.parent.parent / 'benchmarks.md'}")
    return 0
