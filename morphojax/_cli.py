"""The `morphojax` command line.

    morphojax presets                         list the presets
    morphojax run NAME [--out F.png] [--seed N] [--quick] [--frames]
    morphojax resume CHECKPOINT.npz [--out F.png]
    morphojax render RESULT.npz [--species b] [--cmap inferno] --out F.png

Every run writes its image and an `.npz` (final species cropped to the active lattice,
plus JSON metadata with every parameter, the seed and the step counter), so it can be
reproduced (`--seed`) or resumed (`morphojax resume`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

COMMANDS = []  # (name, register function) of subcommands contributed by other modules


def _add_run_parsers(sub):
    p = sub.add_parser("presets", help="list the presets")
    p.set_defaults(func=_cmd_presets)

    p = sub.add_parser("run", help="run a preset and write its image and .npz")
    p.add_argument("name", help="preset name (see `morphojax presets`)")
    p.add_argument("--out", type=Path, default=None, help="output PNG (default NAME.png); the .npz goes next to it")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same result)")
    p.add_argument("--quick", action="store_true", help="a reduced version that runs in seconds")
    p.add_argument("--frames", action="store_true", help="also write the intermediate snapshots")
    p.add_argument("--scale", type=int, default=2, help="pixels per lattice cell in the PNG")
    p.add_argument("--checkpoint-every", type=int, default=None, metavar="STEPS",
                   help="write the .npz checkpoint every STEPS steps (resume with `morphojax resume`)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("resume", help="continue a run from its .npz checkpoint")
    p.add_argument("checkpoint", type=Path)
    p.add_argument("--out", type=Path, default=None, help="output PNG (default: the checkpoint's name)")
    p.add_argument("--frames", action="store_true")
    p.add_argument("--scale", type=int, default=2)
    p.add_argument("--checkpoint-every", type=int, default=None, metavar="STEPS")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_cmd_resume)

    p = sub.add_parser("render", help="render one species of a result .npz to PNG")
    p.add_argument("result", type=Path)
    p.add_argument("--species", default=None, help="species name (default: the experiment's choice, else the last)")
    p.add_argument("--cmap", default=None, help="inferno, viridis, gray, giraffe, ...")
    p.add_argument("--scale", type=int, default=2)
    p.add_argument("--out", type=Path, required=True)
    p.set_defaults(func=_cmd_render)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="morphojax", description="Differentiable pattern formation in JAX.")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_run_parsers(sub)
    for _, register in _contributed():
        register(sub)
    return parser


def _contributed():
    """Subcommands that live next to their features: sweeps, automata, fitting."""
    from fitting._cli import register as fit_register

    from ._automata_cli import register as ca_register
    from ._sweep_cli import register as sweep_register

    return list(COMMANDS) + [("sweep", sweep_register), ("ca", ca_register), ("fit", fit_register)]


def _ca_presets():
    from ._automata_cli import PRESETS as CA_PRESETS

    return CA_PRESETS


def _cmd_presets(args):
    from ._presets import PRESETS

    rows = [(name, p.figure, p.description) for name, p in PRESETS.items()]
    rows += [(name, getattr(p, "figure", ""), getattr(p, "description", "")) for name, p in _ca_presets().items()]
    width = max(len(r[0]) for r in rows)
    fig_w = max(len(r[1]) for r in rows)
    for name, fig, desc in rows:
        print(f"{name:<{width}}  {fig:<{fig_w}}  {desc}")
    return 0


def _stem(out: Path | None, name: str) -> Path:
    out = Path(out) if out is not None else Path(f"{name}.png")
    if out.suffix.lower() != ".png":
        out = out.with_suffix(".png")
    out.parent.mkdir(parents=True, exist_ok=True)
    return out


def _cmd_run(args):
    from ._presets import PRESETS

    if args.name in _ca_presets():
        out = _stem(args.out, args.name)
        summary = _ca_presets()[args.name].run(seed=args.seed, quick=args.quick, out=out, frames=args.frames)
        print(json.dumps({"image": str(out), **summary}, default=str))
        return 0
    if args.name not in PRESETS:
        names = ", ".join(list(PRESETS) + list(_ca_presets()))
        raise SystemExit(f"morphojax run: unknown preset {args.name!r}; choose from: {names}")
    preset = PRESETS[args.name]
    out = _stem(args.out, args.name)
    if preset.members:
        return _run_group(preset, args, out)
    exp = preset.experiment(args.quick)
    result = _run_one(exp, args, out.with_suffix(".npz"))
    _write_outputs(result, out, args)
    return 0


def _run_one(exp, args, npz: Path, resume=None):
    from ._experiment import run_experiment

    t0 = time.perf_counter()
    result = run_experiment(exp, seed=getattr(args, "seed", 0), frames=args.frames,
                            progress=not args.no_progress, checkpoint_path=npz if args.checkpoint_every else None,
                            checkpoint_every=args.checkpoint_every, resume=resume)
    result.metadata["run"]["seconds"] = time.perf_counter() - t0
    result.metadata["run"]["quick"] = bool(getattr(args, "quick", False))
    result.save(npz)
    return result


def _write_outputs(result, out: Path, args):
    from ._render import montage, render_experiment

    img = render_experiment(result.state, result.experiment, scale=args.scale)
    img.save(out)
    written = [str(out), str(out.with_suffix(".npz"))]
    if args.frames and result.frames:
        folder = out.with_name(out.stem + "_frames")
        folder.mkdir(exist_ok=True)
        tiles = []
        for k, (label, state) in enumerate(result.frames):
            frame = render_experiment(state, result.experiment, scale=args.scale) if _can_show(state, result) \
                else None
            if frame is None:
                continue
            path = folder / f"{k:03d}_{_slug(label)}.png"
            frame.save(path)
            tiles.append((label, frame))
        if tiles:
            sheet = montage([t for _, t in tiles], ncols=min(4, len(tiles)),
                            title=f"{result.experiment.name}: " + " | ".join(lbl for lbl, _ in tiles[:4]) + (
                                " ..." if len(tiles) > 4 else ""))
            sheet.save(folder / "frames.png")
        written.append(str(folder))
    size = result.state.shape
    print(json.dumps({"preset": result.experiment.name, "written": written, "size": list(size),
                      "steps": int(result.state.step), "seconds": round(result.metadata["run"]["seconds"], 2)}))


def _can_show(state, result):
    exp = result.experiment
    if exp.show == "melanin":
        return "b" in state.names and "c" in state.names
    return exp.show in state.names


def _slug(text: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in text).strip("_")


def _run_group(preset, args, out: Path):
    """A figure of several experiments: one row per member, columns = its snapshots."""
    from ._presets import PRESETS
    from ._render import montage, render_experiment

    rows, labels, cols = [], [], None
    args.frames = True if preset.name.startswith("development") else args.frames
    for member in preset.members:
        exp = PRESETS[member].experiment(args.quick)
        npz = out.with_name(f"{out.stem}_{member}.npz")
        result = _run_one(exp, args, npz)
        shots = [s for _, s in result.frames if _can_show(s, result)] if preset.name.startswith("development") else []
        tiles = [render_experiment(s, exp, scale=args.scale) for s in shots] or [
            render_experiment(result.state, exp, scale=args.scale)]
        rows.append(tiles)
        labels.append(member)
    ncols = max(len(r) for r in rows)
    images = []
    for r in rows:
        images += r + [r[-1]] * (ncols - len(r))
    if preset.name in ("fig4", "fig5"):
        from ._presets import FIG4_RATIOS

        ncols = len(FIG4_RATIOS)
        col_labels = [f"r = {r:g}" for r in FIG4_RATIOS]
        row_labels = ["B >= 0", "Ua", "Lb"]
    else:
        col_labels = None
        row_labels = [lbl.split("-")[-1] for lbl in labels]
    montage(images, ncols, row_labels=row_labels, col_labels=col_labels, title=f"{preset.name}: {preset.figure}").save(out)
    print(json.dumps({"preset": preset.name, "written": [str(out)], "members": list(preset.members)}))
    return 0


def _cmd_resume(args):
    from ._experiment import load_experiment
    from ._serialise import load_npz

    state, meta = load_npz(args.checkpoint)
    exp = load_experiment(meta)
    run = meta.get("run", {})
    if int(run.get("phase", 0)) >= len(exp.phases):
        print(f"{args.checkpoint} is already complete ({len(exp.phases)} phases done)", file=sys.stderr)
    out = _stem(args.out if args.out is not None else args.checkpoint.with_suffix(".png"), exp.name)
    args.seed = int(run["seed"]) if run.get("seed") is not None else 0  # a key-started run resumes with its key
    result = _run_one(exp, args, out.with_suffix(".npz"), resume=(state, meta))
    _write_outputs(result, out, args)
    return 0


def _cmd_render(args):
    from ._experiment import load_experiment
    from ._serialise import load_npz
    from ._render import render_experiment, to_image

    state, meta = load_npz(args.result)
    if args.species is None and args.cmap is None and "experiment" in meta:
        render_experiment(state, load_experiment(meta), scale=args.scale).save(_stem(args.out, "render"))
        return 0
    species = args.species if args.species is not None else state.names[-1]
    to_image(state.array(species), cmap=args.cmap or "inferno", scale=args.scale).save(_stem(args.out, "render"))
    return 0


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ValueError as err:  # bad input: a clear message, no traceback
        print(f"morphojax {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
