"""Ctrl-C exits 130 every time (issue 35): interrupted `morphojax resume` runs, several of them
while JAX is compiling, each leaving its checkpoint whole. Each try starts a process that
imports JAX and compiles, so the tries are few and the test is marked slow."""

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
# `python -m morphojax.cli` as a shell starts it: Ctrl-C delivered and handled by Python. A
# test worker's process may hand its children SIGINT ignored or blocked (both survive exec;
# then every try ran to its end and exited 0 in CI), so the child restores both first.
AS_FROM_A_SHELL = ("import runpy, signal, sys\n"
                   "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
                   "signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT])\n"
                   "sys.argv[0] = 'morphojax'\n"
                   "runpy.run_module('morphojax.cli', run_name='__main__', alter_sys=True)\n")


@pytest.mark.slow
def test_ctrl_c_exits_130_every_time(tmp_path):
    exp = mj.preset("fig4-r4.2")
    # 2,000,000 steps of 50x50 (the preset's 10,000 end within the interrupts' delays once
    # compiled): every try is still running when its interrupt comes
    exp = dataclasses.replace(exp, phases=(dataclasses.replace(exp.phases[0], steps=2_000_000),))
    state = mj.State.from_arrays([np.full((50, 50), 4.0), np.full((50, 50), 4.5)], names=("a", "b"))
    start = mj.save_npz(tmp_path / "start.npz", state, {
        "experiment": exp.to_dict(), "run": {"seed": 0, "phase": 0, "phase_step": 0, "phase_origin": None}})
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
        time.sleep(3.0 + 0.4 * (k % 5))  # some during compilation, some while stepping
        proc.send_signal(signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:  # finished before the interrupt, or ignored it
            proc.kill()
            _, err = proc.communicate()
        codes.append(proc.returncode)
        assert "Traceback" not in err or proc.returncode == -signal.SIGINT, err
        mj.load_npz(checkpoint)  # whatever happened, the checkpoint reads
    # 130: interrupted (-SIGINT, which a shell also reports as 130: interrupted while Python was
    # still importing JAX, before the command began); 0: the run ended first; never -11 (SIGSEGV)
    assert all(code in (0, 130, -signal.SIGINT) for code in codes), codes
    assert codes.count(130) >= TRIES // 2, codes
