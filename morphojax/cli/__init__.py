"""The `morphojax` command line: parses arguments and calls the library.

    morphojax presets | run NAME | resume CKPT | render RESULT    (`_run`)
    morphojax sweep ...                                          (`_sweep`)
    morphojax ca ...                                             (`_ca`)
    morphojax mesh ...                                           (`_mesh`)
    morphojax listing FILE                                       (`_listing`)

Other packages add subcommands through the entry-point group `morphojax.commands`: each
entry is a function `register(subparsers)` that adds its parser and sets `func` (e.g.
`fitting` adds `morphojax fit`). The core never imports them.
"""

from __future__ import annotations

import argparse
import os
import sys
from importlib.metadata import entry_points

from .._compilation_cache import use_compilation_cache
from . import _ca, _listing, _mesh, _run, _sweep
from ._interrupt import Interrupts

ENTRY_POINT_GROUP = "morphojax.commands"
CORE_COMMANDS = (_run.register, _sweep.register, _ca.register, _mesh.register, _listing.register)


def build_parser() -> argparse.ArgumentParser:
    """The parser of every subcommand: the core's, then those registered by other packages."""
    parser = argparse.ArgumentParser(prog="morphojax", description="Differentiable pattern formation in JAX.")
    parser.add_argument("--debug", action="store_true",
                        help="show the full traceback of an error (default: one line)")
    parser.add_argument("--no-compilation-cache", action="store_true",
                        help="compile every program again instead of loading it from the compilation cache "
                             "(default: kept in $MORPHOJAX_CACHE_DIR or ~/.cache/morphojax/jax; see "
                             "`morphojax.use_compilation_cache`)")
    sub = parser.add_subparsers(dest="command", required=True)
    for register in CORE_COMMANDS:
        register(sub)
    for entry in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        entry.load()(sub)
    return parser


def main(argv=None) -> int:
    """Run the command line `argv` (default: `sys.argv[1:]`); returns the exit status:
    0 done, 2 bad input (a ValueError: one line saying what to change), 1 any other error
    (one line; `morphojax --debug ...` shows its traceback), 130 interrupted."""
    with Interrupts() as interrupts:  # from the start, every Ctrl-C reaches the command: see `_interrupt`
        try:
            args = build_parser().parse_args(argv)  # (loads the commands other packages add)
            if not getattr(args, "no_compilation_cache", False):
                use_compilation_cache()
        except KeyboardInterrupt:
            interrupts.stopping = True
            return _interrupted("morphojax", "interrupted", argv)
        except (SystemExit, GeneratorExit):
            interrupts.stopping = True
            raise
        try:
            return int(args.func(args) or 0)
        except KeyboardInterrupt as err:  # Ctrl-C: a line saying what is kept, no traceback
            interrupts.stopping = True
            return _interrupted(f"morphojax {args.command}", str(err) or "interrupted", argv)
        except Exception as err:  # noqa: BLE001 (every error is an exit status; --debug re-raises it)
            interrupts.stopping = True
            if interrupts.interrupted:  # what an interrupt became (a host callback's runtime error)
                return _interrupted(f"morphojax {args.command}", "interrupted", argv)
            return _failed(args, err, getattr(args, "debug", False))
        except (SystemExit, GeneratorExit):
            interrupts.stopping = True
            raise


def _interrupted(who: str, message: str, argv) -> int:
    print(f"{who}: {message}", file=sys.stderr)
    if argv is None:  # the program itself (not a caller in Python): leave now, see `_leave`
        _leave(130)
    return 130


def _failed(args, err: Exception, debug: bool) -> int:
    """The exit status of a command that raised `err`: 2 bad input (a ValueError: one line
    saying what to change), 1 anything else (one line); --debug raises it for its traceback."""
    if isinstance(err, BrokenPipeError):  # the reader went away (`morphojax presets | head`): nothing to say
        sys.stdout = open(os.devnull, "w")
        return 1
    if debug:
        raise err
    if isinstance(err, ValueError):
        print(f"morphojax {args.command}: error: {err}", file=sys.stderr)
        return 2
    text = " ".join(str(err).split()) or "no message"
    print(f"morphojax {args.command}: error: {type(err).__name__}: {text} (run `morphojax --debug "
          f"{args.command} ...` for the traceback)", file=sys.stderr)
    return 1


def _leave(code: int) -> None:
    """Exit the process at once with `code`, skipping the interpreter's teardown.

    A Ctrl-C that reaches Python while JAX is tracing or compiling leaves jaxlib's objects
    half-built; the interpreter's teardown then frees jaxlib's nanobind module under them and
    crashes in `nanobind::detail::nb_module_free` (from `module_dealloc`): 4 of 14 interrupted
    resumes ended in a segmentation fault (exit 139) after the resume message. Waiting for
    the dispatched computations first did not help (4 of 14 still crashed); leaving without
    the teardown did (14 of 14 exited 130). Every checkpoint is already complete on disk
    (written atomically before the interrupt is handled), so nothing is lost; the standard
    streams are flushed first."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


__all__ = ["build_parser", "main"]
