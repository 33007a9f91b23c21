"""The ``skisnow`` command line.

Each feature module registers its own subcommand through a ``register(subparsers)`` function
listed in :data:`COMMAND_MODULES`; this module only dispatches and turns skisnow errors into a
one-line message and exit status 2 (never a traceback for a user mistake).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from skisnow.solvers.errors import SkisnowError

#: modules that provide ``register(subparsers)``; a module missing here is simply not offered
COMMAND_MODULES = [
    "skisnow.app.commands.micro",
    "skisnow.app.commands.build_tables",
    "skisnow.app.commands.bench",
    "skisnow.app.commands.macro",
    "skisnow.app.commands.flex",
    "skisnow.app.commands.identify",
    "skisnow.app.commands.train_camber",
    "skisnow.app.commands.serve",
    "skisnow.app.commands.solve",
    "skisnow.app.commands.worker",
    "skisnow.app.commands.report",
    "skisnow.app.commands.adopt",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="skisnow",
        description="Multi-scale contact mechanics of cross-country skis on snow.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress to stderr")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:  # feature not present in this build
                continue
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
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
