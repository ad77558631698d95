"""The ``frbench`` command line.

Each sub-command lives in its own module under :mod:`frbench.commands` and
exposes ``register(subparsers)``, which adds its parser and sets ``func``.
Heavy imports (simulators, torch) happen inside the commands, so ``frbench
--help`` is instant. An :class:`~frbench.errors.FrbenchError` is printed as one
line on stderr and exits with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from frbench import __version__
from frbench.errors import FrbenchError

#: Modules that register sub-commands, in the order ``--help`` lists them.
COMMAND_MODULES = (
    "frbench.commands.robots",
    "frbench.commands.terrain",
    "frbench.commands.policies",
    "frbench.commands.evaluate",
    "frbench.commands.render",
    "frbench.commands.leaderboard",
    "frbench.commands.verify",
    "frbench.commands.train",
    "frbench.commands.distill",
    "frbench.commands.analyze",
    "frbench.commands.export",
    "frbench.commands.spec",
)


class OneLineErrorParser(argparse.ArgumentParser):
    """argparse's parser (and its sub-parsers) with a usage error on one line, exit status 2:
    ``frbench evaluate: error: argument --episodes: invalid int value: 'x' (see `frbench evaluate --help`)``."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see `{self.prog} --help`)\n")


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (commands whose module is absent are skipped)."""
    parser = OneLineErrorParser(prog="frbench", description="Legged-robot fall-recovery benchmark.")
    parser.add_argument("--version", action="version", version=f"frbench {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:
                continue
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run one command; returns the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        status = args.func(args)
    except FrbenchError as exc:
        print(f"frbench {args.command}: error: {exc}", file=sys.stderr)
        return exc.exit_status
    except KeyboardInterrupt:
        print(f"frbench {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of stdout went away (`frbench ... | head`): stop printing, quietly, like other Unix tools
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    return int(status or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
