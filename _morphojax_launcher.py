"""The `morphojax` command's entry point: a Ctrl-C while the command loads stops it like any other.

Loading the command imports JAX, a few seconds before `morphojax.cli.main` installs its own
handler (`morphojax.cli._interrupt`). An interrupt in those seconds printed a traceback from
inside the import and exited by the signal; one that landed in the initialisation of a jaxlib
extension became an ImportError (exit 1); one that landed in JAX's garbage-collection
callback was swallowed and the command ran to its end. So the command is loaded with
interrupts held (remembered, not raised), and a remembered one ends it as an interrupted
command ends: a line on stderr, exit 130.

A top-level module, not part of `morphojax`: importing anything in that package imports JAX.
"""

from __future__ import annotations

import signal
import sys


def main() -> int:
    """Load `morphojax.cli` with Ctrl-C held, then run it (its exit status; 130 interrupted)."""
    held = []
    # a process started in the background by a shell ignores SIGINT: it keeps ignoring it
    holding = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    if holding:
        signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
    try:
        from morphojax.cli import main as command
    finally:
        if holding:
            signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        if held:
            raise KeyboardInterrupt
        return command()
    except KeyboardInterrupt:  # held while loading, or come before the command's handler was in
        print("morphojax: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
