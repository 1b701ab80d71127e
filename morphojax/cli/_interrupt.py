"""Ctrl-C in the command line: every interrupt stops the command, also one Python would swallow.

Python runs a signal's handler at the main thread's next bytecode, wherever that is. When it
is the bytecode of a garbage-collection callback (JAX registers one, `_xla_gc_callback`, that
runs at every collection), a finalizer (`__del__`, a weakref callback) or a host callback of
a compiled program, the KeyboardInterrupt raised there never reaches the command: CPython
prints "Exception ignored in ..." and goes on (a host callback's interrupt becomes a runtime
error of its computation instead). The command then runs on as if no Ctrl-C had come.
Sampled during a `resume` (a SIGINT every 3 ms, counted where its handler ran), about 1 in
100 landed in JAX's gc callback.

The rule kept here: the handler remembers every interrupt before raising it, and until the
command has begun to stop (`stopping`), a watcher thread raises it again in the main thread
every REPEAT seconds; an error that ends a command after an interrupt is that interrupt.
"""

from __future__ import annotations

import _thread
import logging
import signal
import sys
import threading
from typing import Self

REPEAT = 0.5  # seconds between re-raised interrupts that have not stopped the command yet
# where JAX logs the traceback of a host callback that raised (a Ctrl-C is not such an error)
CALLBACK_LOGGERS = ("jax._src.callback", "jax._src.debugging")


def _not_an_interrupt(record: logging.LogRecord) -> bool:
    return not (record.exc_info and isinstance(record.exc_info[1], KeyboardInterrupt))


class Interrupts:
    """While entered: SIGINT raises KeyboardInterrupt (as Python's own handler does), is
    remembered (`interrupted`) and is raised again until `stopping` is set; neither CPython
    (for a swallowed one) nor JAX (for one raised in a host callback) prints its traceback.
    A process that ignores SIGINT (started in the background by a shell) keeps ignoring it;
    the handler and hooks before are restored on exit."""

    def __init__(self):
        self.interrupted = False
        # set by the command as the first thing it does once it stops: a plain attribute,
        # so that setting it runs no bytecode where another interrupt could land
        self.stopping = False
        self._done = threading.Event()
        self._before = None
        self._hook = None

    def __enter__(self) -> Self:
        if threading.current_thread() is threading.main_thread() and \
                signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            self._before = signal.signal(signal.SIGINT, self._handler)
            self._hook = sys.unraisablehook
            sys.unraisablehook = self._unraisable
        for name in CALLBACK_LOGGERS:
            logging.getLogger(name).addFilter(_not_an_interrupt)
        return self

    def __exit__(self, *exc) -> None:
        self.stopping = True
        self._done.set()
        if self._before is not None:
            signal.signal(signal.SIGINT, self._before)
            sys.unraisablehook = self._hook
        for name in CALLBACK_LOGGERS:
            logging.getLogger(name).removeFilter(_not_an_interrupt)

    def _handler(self, signum, frame):
        if self.stopping:  # already on its way out: a second Ctrl-C changes nothing
            return
        if not self.interrupted:
            self.interrupted = True
            threading.Thread(target=self._repeat, name="morphojax-interrupt", daemon=True).start()
        raise KeyboardInterrupt

    def _unraisable(self, unraisable) -> None:
        """A swallowed interrupt is not reported ("Exception ignored in ..."): it is raised again."""
        if not isinstance(unraisable.exc_value, KeyboardInterrupt) or not self.interrupted:
            self._hook(unraisable)

    def _repeat(self) -> None:
        while not self._done.wait(REPEAT):
            if self.stopping:
                return
            _thread.interrupt_main(signal.SIGINT)  # runs `_handler` at the main thread's next bytecode
