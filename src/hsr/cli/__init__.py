"""The ``hsr`` command line. Bad input ends with one line on stderr and exit code 2.

One module per command (``render``, ``lines``, ``compare``, ``explain``, ``report``, ``batch``,
``prune``, ``visibility``, ``view``), each with ``add_parser(sub)`` and ``run(args)``;
the options several commands share are defined once in :mod:`hsr.cli.options`, the
scene, camera and state they describe are built in :mod:`hsr.cli.setup`."""

from __future__ import annotations

import argparse
import functools
import sys
import warnings

from ..errors import HsrError
from . import (
    batch,
    compare,
    explain,
    lines,
    partition,
    prune,
    render,
    report,
    view,
    visibility,
    warmup,
)
from .options import EXIT_USAGE, CliError, HelpFormatter, Parser

__all__ = ["main", "build_parser", "CliError", "EXIT_USAGE"]

# In the order ``hsr --help`` lists them.
COMMANDS = {"render": render, "lines": lines, "compare": compare, "explain": explain,
            "report": report, "batch": batch, "partition": partition, "prune": prune,
            "visibility": visibility, "view": view, "warmup": warmup}


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="hsr", description="Hidden-surface removal: render meshes headless.")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--version", action="store_true", help="print hsr's version")
    sub = parser.add_subparsers(dest="command", parser_class=Parser)
    # Every option's help ends with its default.
    sub.add_parser = functools.partial(  # type: ignore[method-assign]
        sub.add_parser, formatter_class=HelpFormatter)
    for module in COMMANDS.values():
        module.add_parser(sub)
    return parser


def _attach_negative_values(argv: list) -> list:
    """``--view -55,25`` as ``--view=-55,25``: argparse takes a value that starts with '-'
    and is not a plain number for an option and fails ("expected one argument")."""
    out, k = [], 0
    while k < len(argv):
        token = argv[k]
        if (token.startswith("--") and "=" not in token and k + 1 < len(argv)
                and len(argv[k + 1]) > 1 and argv[k + 1][0] == "-"
                and (argv[k + 1][1].isdigit() or argv[k + 1][1] == ".")):
            out.append(f"{token}={argv[k + 1]}")
            k += 2
        else:
            out.append(token)
            k += 1
    return out


def main(argv=None) -> int:
    """Run the ``hsr`` command with ``argv`` (default: the process arguments) and return
    the exit code. Raises nothing for bad input: 0 on success, 2 with one line on stderr
    (``hsr: error: ...``) for any :class:`~hsr.errors.HsrError`, 130 when interrupted, 1
    when memory runs out after all."""
    argv = _attach_negative_values(sys.argv[1:] if argv is None else list(argv))
    debug = "--debug" in argv
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_warning
        return _main(argv, debug)


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    """A warning as one line on stderr (``hsr: warning: ...``), not Python's two."""
    print(f"hsr: warning: {message}", file=sys.stderr)


def _main(argv: list, debug: bool) -> int:
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if args.version:
            from .. import __version__

            print(f"hsr {__version__}")
            return 0
        if args.command is None:
            parser.print_help()
            return EXIT_USAGE
        if args.command in COMMANDS:
            warmup.note_first_run(args.command, getattr(args, "quiet", False))
            return COMMANDS[args.command].run(args)
        raise CliError(f"unknown command {args.command!r}")
    except HsrError as exc:
        if debug:
            raise
        print(f"hsr: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("hsr: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print("hsr: error: out of memory (try a smaller --size or mesh)", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
