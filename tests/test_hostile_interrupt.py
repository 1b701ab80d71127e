"""Ctrl-C exits 130 every time: interrupted `morphojax resume` runs, several of them while JAX
is compiling, each leaving its checkpoint whole, and one whose interrupt lands where Python
swallows it. Each try starts a process that imports JAX and compiles, so the tries are few
and the tests are marked slow."""

from __future__ import annotations

import dataclasses
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import morphojax as mj

TRIES = 10
# the `morphojax` command (its entry point, `_morphojax_launcher.main`) as a shell starts it:
# Ctrl-C delivered and handled by Python. A test worker's process may hand its children
# SIGINT ignored or blocked (both survive exec; then every try ran to its end and exited 0 in
# CI), so the child restores both first. It says "loading" as the command begins to load.
AS_FROM_A_SHELL = ("import signal, sys\n"
                   "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
                   "signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT])\n"
                   "sys.argv[0] = 'morphojax'\n"
                   "import _morphojax_launcher\n"
                   "print('loading', flush=True)\n"
                   "sys.exit(_morphojax_launcher.main())\n")


# ... and, at the start of the run, a Ctrl-C whose handler runs inside a garbage-collection
# callback, as one did when it came while JAX's `_xla_gc_callback` ran: CPython prints
# "Exception ignored in: <function ...>" and the command ran on to its end
LANDS_IN_A_GC_CALLBACK = AS_FROM_A_SHELL.replace("import signal, sys\n", """\
import gc, os, signal, sys
import morphojax
armed = []
def collecting(phase, info):
    if armed and phase == "start":
        armed.clear()
        print("interrupted in a gc callback", file=sys.stderr, flush=True)
        os.kill(os.getpid(), signal.SIGINT)  # handled at the next bytecode: still in here
        return None
gc.callbacks.append(collecting)
run_experiment = morphojax.run_experiment
def interrupted_run(*args, **kwargs):
    armed.append(True)
    gc.collect()
    return run_experiment(*args, **kwargs)
morphojax.run_experiment = interrupted_run
""")


def _long_start(folder):
    """A checkpoint at step 0 of 2,000,000 steps of 50x50 (the preset's 10,000 end within the
    interrupts' delays once compiled): every try is still running when its interrupt comes."""
    exp = mj.preset("fig4-r4.2")
    exp = dataclasses.replace(exp, phases=(dataclasses.replace(exp.phases[0], steps=2_000_000),))
    state = mj.State.from_arrays([np.full((50, 50), 4.0), np.full((50, 50), 4.5)], names=("a", "b"))
    return mj.save_npz(folder / "start.npz", state, {
        "experiment": exp.to_dict(), "run": {"seed": 0, "phase": 0, "phase_step": 0, "phase_origin": None}})


@pytest.mark.slow
def test_ctrl_c_exits_130_every_time(tmp_path):
    start = _long_start(tmp_path)
    codes = []
    for k in range(TRIES):
        checkpoint = tmp_path / f"c{k}.npz"
        shutil.copy(start, checkpoint)
        # the compilation cache off: every try compiles, as a first run does (with the
        # programs cached the whole run ends before the first interrupt)
        proc = subprocess.Popen([sys.executable, "-c", AS_FROM_A_SHELL, "resume", str(checkpoint),
                                 "--checkpoint-every", "20000", "--no-progress", "--quiet"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                env={**os.environ, "MORPHOJAX_CACHE_DIR": "off"})
        time.sleep(1.5 + 0.5 * (k % 5))  # some while loading, some compiling, some stepping (a test under 60 s)
        proc.send_signal(signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:  # finished before the interrupt, or ignored it
            proc.kill()
            _, err = proc.communicate()
        codes.append(proc.returncode)
        assert "Traceback" not in err, err
        mj.load_npz(checkpoint)  # whatever happened, the checkpoint reads
    # never -11 (SIGSEGV), never the signal's own exit (a traceback from inside an import)
    assert codes == [130] * TRIES, codes


@pytest.mark.slow
def test_ctrl_c_while_the_command_loads_exits_130(tmp_path):
    """An interrupt while the command imports JAX (a few seconds, before the command's own
    handler) is held until the import ends, then stops the command: exit 130 and one line,
    not a traceback from inside the import, an ImportError from a half-initialised jaxlib
    extension, a crash, or (swallowed by JAX's gc callback) a run to its end."""
    checkpoint = _long_start(tmp_path)
    # the child says "loading" just before it calls the entry point, which holds interrupts from its
    # first line: an interrupt sent at once can come before that line (Python's own handler, as in
    # the interpreter's start-up), so the first waits 50 ms
    for delay in (0.05, 0.1, 0.3, 0.6, 1.0):
        proc = subprocess.Popen([sys.executable, "-c", AS_FROM_A_SHELL, "resume", str(checkpoint), "--no-progress",
                                 "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert proc.stdout.readline().strip() == "loading"
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
        assert proc.returncode == 130, (delay, proc.returncode, err[-2000:])
        assert "Traceback" not in err and "interrupted" in err.splitlines()[-1], (delay, err[-2000:])


@pytest.mark.slow
def test_a_ctrl_c_python_swallows_still_stops_the_command(tmp_path):
    """An interrupt raised inside a garbage-collection callback never reaches the command;
    the command line raises it again until it stops: exit 130 at once, not a run to its end."""
    checkpoint = tmp_path / "c.npz"
    shutil.copy(_long_start(tmp_path), checkpoint)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", LANDS_IN_A_GC_CALLBACK, "resume", str(checkpoint),
                           "--checkpoint-every", "20000", "--no-progress", "--quiet"],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=300, check=False,
                          env={**os.environ, "MORPHOJAX_CACHE_DIR": "off"})
    assert proc.returncode == 130, (proc.returncode, proc.stderr[-2000:])
    lines = proc.stderr.splitlines()
    assert lines[0] == "interrupted in a gc callback" and lines[-1].startswith("morphojax resume: interrupted"), lines
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr, proc.stderr
    assert time.perf_counter() - t0 < 60  # (the whole run, which it finished before, takes longer)
    mj.load_npz(checkpoint)


# a command whose compiled program's host callback is running when the Ctrl-C comes (as a
# fit's loss recorder is): its KeyboardInterrupt becomes the computation's runtime error
IN_A_HOST_CALLBACK = """\
import os, signal, sys, time
import jax
import morphojax.cli as cli
signal.signal(signal.SIGINT, signal.default_int_handler)
signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT])
def record(x):
    os.kill(os.getpid(), signal.SIGINT)
@jax.jit
def step(x):
    jax.debug.callback(record, x)
    return x + 1
def command(args):
    step(1.0).block_until_ready()
    jax.effects_barrier()
    time.sleep(30)
    return 0
parser = cli.build_parser
def build():
    p = parser()
    for action in p._subparsers._group_actions:
        action.choices["presets"].set_defaults(func=command)
    return p
cli.build_parser = build
sys.exit(cli.main(["presets"]))
"""


def test_a_ctrl_c_in_a_host_callback_exits_130():
    """Not exit 1 with JAX's runtime error ("CpuCallback error") and its logged traceback."""
    proc = subprocess.run([sys.executable, "-c", IN_A_HOST_CALLBACK], stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True, timeout=120, check=False)
    assert proc.returncode == 130, (proc.returncode, proc.stderr[-2000:])
    assert proc.stderr.strip() == "morphojax presets: interrupted", proc.stderr[-2000:]
