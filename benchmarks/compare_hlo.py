"""Do two checkouts compile the same programs? A refactor's noise-free speed check.

Timings on a shared 2-core machine drift by tens of percent; the optimised XLA program does
not. For three runs (the Turing step at 250x250, a growing run with planned segments, Young's
2D automaton) this compiles `jax.jit` of the whole run in each tree, drops what only names
where the code lives (metadata, stack-frame tables, instruction names, the order of a loop's
carried values) and compares the instructions that remain. Equal programs run at equal speed.

    git worktree add /tmp/before <rev>
    python benchmarks/compare_hlo.py /tmp/before .
"""

from __future__ import annotations

import argparse
import collections
import os
import re
import subprocess
import sys
from pathlib import Path

DUMP = r'''
import sys, jax, jax.numpy as jnp
import morphojax as mj
which, key = sys.argv[1], jax.random.key(0)
if which == "turing 250x250, 512 steps":
    state = mj.paper_state(key, (250, 250))
    f = jax.jit(lambda r: mj.simulate(mj.Turing(r, 3.0), state, 512, 0.008, check_dt=False).fields)
    print(f.lower(jnp.float32(12.0)).compile().as_text())
elif which == "growing 130x130 -> 150x150, 1000 steps":
    state = mj.paper_state(key, (130, 130), capacity=(200, 200))
    g = mj.Growth(rate=1.0 / (50 * 0.004))
    f = jax.jit(lambda r: mj.simulate(mj.Turing(r, 5.0, lower=(0, 2)), state, 1000, 0.004, growth=g,
                                      key=jax.random.key(1), check_dt=False).fields)
    print(f.lower(jnp.float32(40.0)).compile().as_text())
else:
    ca = mj.YoungCA(species=[(2.30, 6.01, 1.0, -0.2)])
    cells = mj.random_cells(key, (120, 120), 1)
    print(jax.jit(lambda c: ca.run(c, 30).cells).lower(cells).compile().as_text())
'''
CASES = ("turing 250x250, 512 steps", "growing 130x130 -> 150x150, 1000 steps", "young 2D 120x120, 30 steps")


def instructions(tree: Path, case: str) -> collections.Counter:
    """The compiled program's instructions, with names, metadata and tuple orders dropped."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    text = subprocess.run([sys.executable, "-c", DUMP, case], capture_output=True, text=True, env=env,
                          check=True).stdout
    out = collections.Counter()
    for line in text.splitlines():
        if re.match(r"^\s*\d+ ", line) or line.startswith(("FileNames", "FunctionNames", "FileLocations",
                                                               "StackFrames", "HloModule")):
            continue
        line = re.sub(r", metadata=\{[^}]*\}", "", line)
        line = re.sub(r"%[\w.\-]+", "%x", line)
        line = re.sub(r"index=\d+", "index=n", line)
        line = re.sub(r"\((?:s32|f32|u32|pred|f64|s8|u8)[^)]*\)", "(tuple)", line.replace("/*index=5*/", ""))
        out[line.strip()] += 1
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("before", type=Path)
    p.add_argument("after", type=Path)
    args = p.parse_args()
    for case in CASES:
        a, b = instructions(args.before.resolve(), case), instructions(args.after.resolve(), case)
        fusions = sum(n for line, n in b.items() if " fusion(" in line)
        verdict = "same program" if a == b else f"DIFFERENT ({sum((a - b).values())} instructions only before, " \
                                                  f"{sum((b - a).values())} only after)"
        print(f"{case}: {sum(b.values())} instructions, {fusions} fusions: {verdict}")


if __name__ == "__main__":
    main()
