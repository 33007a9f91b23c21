"""The ``skisnow`` command line.

Each feature module registers its own subcommand through a ``register(subparsers)`` function;
:data:`COMMANDS` names the module and the one-line help of each. Only the module of the command
being run is imported, so ``skisnow --help`` answers at once instead of importing every solver
and plotting library first (``tests/commands/test_cli_lazy.py`` keeps the one-line helps in step
with the modules). This module dispatches and turns skisnow errors into a one-line message and
exit status 2 (never a traceback for a user mistake).

``--data-dir DIR`` (or ``SKISNOW_DATA_DIR``) points every command at the service's data folder:
``skisnow solve`` then also finds the skis and grinds uploaded to the service there.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys

#: command → (module that provides ``register(subparsers)``, one-line help); a module missing
#: from this build is simply not offered
COMMANDS: dict[str, tuple[str, str]] = {
    "micro": (
        "skisnow.app.commands.micro",
        "one micro-scale solve: a texture pressed into the snow at a nominal pressure",
    ),
    "build-tables": ("skisnow.app.commands.build_tables", "build micro-scale lookup tables (Dask)"),
    "bench": ("skisnow.app.commands.bench", "benchmarks against peers; results into docs/"),
    "macro": (
        "skisnow.app.commands.macro",
        "apparent contact of a ski on snow (macro-scale BEM)",
    ),
    "flex": (
        "skisnow.app.commands.flex",
        "flex sheet of a ski: wax pocket, closing load, kick-zone load, wheelbase",
    ),
    "identify-ski": (
        "skisnow.app.commands.identify",
        "identify a ski's beam (EI, camber) from its camber measurements",
    ),
    "train-camber": (
        "skisnow.app.commands.train_camber",
        "train the per-ski camber network and store it in the ski file",
    ),
    "serve": ("skisnow.app.commands.serve", "run the REST API and the technician web form"),
    "solve": (
        "skisnow.app.commands.solve",
        "one ski × grind case (the same answer as /v1/contact)",
    ),
    "worker": (
        "skisnow.app.commands.worker",
        "run the catalogue's jobs (uploads' tables and networks) apart from the service",
    ),
    "report": ("skisnow.app.commands.report", "generated reports in docs/"),
    "adopt": (
        "skisnow.app.commands.adopt",
        "give uploads of no team to a team (token mode)",
    ),
}

#: the modules, in the order of :data:`COMMANDS` (kept for callers that list them)
COMMAND_MODULES = [module for module, _ in COMMANDS.values()]


def _top_parser() -> tuple[argparse.ArgumentParser, argparse._SubParsersAction]:
    parser = argparse.ArgumentParser(
        prog="skisnow",
        description="Multi-scale contact mechanics of cross-country skis on snow.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress to stderr")
    parser.add_argument(
        "--data-dir",
        default=None,
        metavar="DIR",
        help="the service's data folder (default SKISNOW_DATA_DIR): its uploaded skis and "
        "grinds are usable here too",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    return parser, sub


def _register(sub: argparse._SubParsersAction, name: str) -> bool:
    module_name = COMMANDS[name][0]
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name == module_name:  # feature not present in this build
            return False
        raise
    module.register(sub)
    return True


def build_parser(commands: list[str] | None = None) -> argparse.ArgumentParser:
    """The full parser of ``commands`` (default: all, importing every command module); the
    other commands appear with their one-line help only."""
    parser, sub = _top_parser()
    wanted = list(COMMANDS) if commands is None else commands
    for name, (_, help_text) in COMMANDS.items():
        if name in wanted:
            _register(sub, name)
        else:
            sub.add_parser(name, help=help_text, add_help=False)
    return parser


def _command_in(argv: list[str]) -> str | None:
    """The subcommand named in ``argv`` (the first word that is one), or None."""
    skip = False
    for word in argv:
        if skip:
            skip = False
            continue
        if word == "--data-dir":
            skip = True
        elif word in COMMANDS:
            return word
        elif not word.startswith("-"):
            return None
    return None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    command = _command_in(argv)
    parser = build_parser([command] if command else [])
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    if args.data_dir is not None:
        os.environ["SKISNOW_DATA_DIR"] = args.data_dir  # read by Settings() in every command
    from skisnow.solvers.errors import SkisnowError

    try:
        return int(args.func(args) or 0)
    except SkisnowError as exc:
        print(f"skisnow {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except FileNotFoundError as exc:
        print(f"skisnow {args.command}: error: file not found: {exc.filename}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
