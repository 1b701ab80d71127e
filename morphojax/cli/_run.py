"""`morphojax presets | run | resume | render`: the presets and the runs of experiments.

    morphojax presets                         list the presets
    morphojax run NAME [--out F.png] [--seed N] [--quick] [--frames] [--gif F.gif] [--quiet]
    morphojax resume CHECKPOINT.npz [--out F.png]
    morphojax render FILE.npz [--species b] [--cmap inferno | --palette-from PHOTO] --out F.png

Files go next to `--out` (default `out/NAME.png`, never the working folder itself). Each run
prints one JSON line on stdout and one line for people on stderr (`--quiet`: JSON only).
`render` draws any `.npz` the tool writes: a run's result, a sweep (its montage) or an
automaton's cells (slices in 3D).

Every reaction-diffusion run writes its image and an `.npz` (final species cropped to the
active lattice, plus JSON metadata with every parameter, the seed and the step counter), so
it can be reproduced (`--seed`) or resumed (`morphojax resume`). Automaton presets write
their own files (see `morphojax.presets`).
"""

from __future__ import annotations

import dataclasses
import math
import shutil
import sys
import textwrap
import time
from pathlib import Path

import jax
import numpy as np
from PIL import Image

import morphojax as mj
from morphojax.presets import lookup
from morphojax.presets._automaton_outputs import default_scale, lattice_picture
from morphojax.presets._preset_files import load_automaton, load_solid

from morphojax._checks import check_picture, check_run_size, check_scale  # sizes checked before a run
from morphojax._run_experiment import check_progress  # a checkpoint's step against its phases
from morphojax._files import remove_stale_temporaries

from ._output import out_arg, picture_path, report

GIF_FRAMES = 24  # snapshots a run takes for `--gif` (spread over its phases)
TABLE_WIDTH = 100  # `morphojax presets` fits a terminal this wide (or the terminal, if narrower)
FIGURE_WIDTH = 24  # the figure column wraps beyond this


def register(sub) -> None:
    """Add `presets`, `run`, `resume` and `render` to an argparse subparsers object."""
    p = sub.add_parser("presets", help="list the presets")
    p.set_defaults(func=_cmd_presets)

    p = sub.add_parser("run", help="run a preset and write its image and .npz")
    p.add_argument("name", help="preset name (see `morphojax presets`)")
    p.add_argument("--out", type=out_arg, default=None,
                   help="output PNG (default out/NAME.png; a folder ending in /: NAME.png inside it); the .npz "
                        "goes next to it")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same result)")
    p.add_argument("--quick", action="store_true", help="a reduced version that runs in seconds")
    p.add_argument("--shape", type=int, nargs=2, default=None, metavar=("ROWS", "COLS"),
                   help="run the preset on a lattice of this size (static square-lattice presets only)")
    _add_run_outputs(p)
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("resume", help="continue a run from its .npz checkpoint")
    p.add_argument("checkpoint", type=Path, help="the .npz that `run --checkpoint-every` wrote")
    p.add_argument("--out", type=out_arg, default=None, help="output PNG (default: the checkpoint's name)")
    _add_run_outputs(p)
    p.set_defaults(func=_cmd_resume)

    p = sub.add_parser("render", help="draw any .npz morphojax writes (run, sweep, automaton) as a PNG")
    p.add_argument("result", type=Path, help="a .npz written by run, resume, sweep, ca, listing or a Potts preset")
    p.add_argument("--species", default=None, help="species name (default: the experiment's choice, else the last)")
    p.add_argument("--cmap", default=None, help="inferno, viridis, gray, giraffe, ...")
    p.add_argument("--palette-from", type=Path, default=None, metavar="PHOTO",
                   help="colour with a photo's main colours instead (mj.Gradient.from_photo: dark = high)")
    p.add_argument("--palette-crop", default=None, metavar="X0,Y0,X1,Y1", help="the photo's region for --palette-from")
    p.add_argument("--scale", type=int, default=None, help="pixels per cell (default 2; automata as `ca` draws them)")
    p.add_argument("--out", type=out_arg, required=True, help="output PNG")
    p.add_argument("--quiet", action="store_true", help="print only the JSON line")
    p.set_defaults(func=_cmd_render)


def _add_run_outputs(p) -> None:
    """The options `run` and `resume` share: what they write and how they report."""
    p.add_argument("--frames", action="store_true", help="also write the intermediate snapshots")
    p.add_argument("--scale", type=int, default=2,
                   help="pixels per lattice cell in the PNG (the picture's size, not the lattice's)")
    p.add_argument("--checkpoint-every", type=int, default=None, metavar="STEPS",
                   help="write the .npz checkpoint every STEPS steps (resume with `morphojax resume`)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--gif", type=Path, default=None, metavar="F.gif",
                   help="also write the run's snapshots as an animation (.gif, or .mp4 with imageio[ffmpeg])")
    p.add_argument("--quiet", action="store_true", help="print only the JSON line")


# ---- presets ---------------------------------------------------------------------------------
def _cmd_presets(args):
    width = min(TABLE_WIDTH, shutil.get_terminal_size((TABLE_WIDTH, 24)).columns)
    print("\n".join(presets_table(mj.PRESETS.values(), width)))
    kinds = {}
    for p in mj.PRESETS.values():
        kinds[p.kind] = kinds.get(p.kind, 0) + 1
    report({"presets": len(mj.PRESETS), "kinds": kinds}, "", True)  # the closing JSON line, as every command's
    return 0


def presets_table(presets, width: int = TABLE_WIDTH) -> list[str]:
    """The presets as lines no longer than `width`: one section per kind, columns name,
    figure and description (the last two wrapped)."""
    presets = list(presets)
    name_w = max(len(p.name) for p in presets)
    fig_w = min(FIGURE_WIDTH, max(len(p.figure) for p in presets))
    desc_w = max(20, width - name_w - fig_w - 4)
    lines = []
    for kind in dict.fromkeys(p.kind for p in presets):
        if lines:
            lines.append("")
        lines += [f"{kind} presets", f"{'NAME':<{name_w}}  {'FIGURE':<{fig_w}}  DESCRIPTION"]
        for p in presets:
            if p.kind != kind:
                continue
            figure = textwrap.wrap(p.figure, fig_w) or [""]
            description = textwrap.wrap(p.description, desc_w) or [""]
            for k in range(max(len(figure), len(description))):
                name = p.name if k == 0 else ""
                fig = figure[k] if k < len(figure) else ""
                desc = description[k] if k < len(description) else ""
                lines.append(f"{name:<{name_w}}  {fig:<{fig_w}}  {desc}".rstrip())
    return lines


# ---- run: dispatch on the preset's kind ------------------------------------------------------
def _cmd_run(args):
    item = lookup(args.name)
    check_scale(args.scale, "--scale")
    if item.kind == "reaction-diffusion":  # sizes checked before anything runs
        for exp in [_experiment(mj.PRESETS[m], args) for m in item.members] or [_experiment(item, args)]:
            check_experiment_size(exp, args.scale, args.frames or args.gif is not None)
    out = picture_path(args.out if args.out is not None else Path("out") / f"{args.name}.png", args.name)
    check_animation_path(args)
    return RUNNERS[item.kind](item, args, out)


def check_animation_path(args) -> None:
    """`--gif`, checked before the run as every output is: its suffix (so it can be neither
    the run's picture nor its npz) and its folder (ValueError naming the flag)."""
    gif = getattr(args, "gif", None)
    if gif is None:
        return
    from morphojax._animation import FORMATS
    from morphojax._files import check_output_path

    if gif.suffix.lower() not in FORMATS:
        raise ValueError(f"--gif must end in one of {', '.join(FORMATS)} (got {gif.name!r})")
    check_output_path(gif)


def _experiment(item, args):
    """The preset's experiment, on the lattice `--shape` asks for (when given)."""
    exp = item.experiment(args.quick)
    shape = getattr(args, "shape", None)
    return exp if shape is None else with_shape(exp, tuple(shape))


def with_shape(exp, shape: tuple):
    """`exp` started on a (rows, cols) lattice of `shape`; refused, naming the reason, for an
    experiment whose sizes are part of it (growth, capacities, parameter maps, source masks)."""
    from morphojax._checks import check_shape

    shape = check_shape(shape, "--shape")
    if len(shape) != 2:
        raise ValueError(f"--shape takes ROWS COLS (got {shape})")
    reasons = []
    if exp.initial.capacity is not None or any(p.capacity is not None or p.growth is not None for p in exp.phases):
        reasons.append("it grows (its sizes are its growth schedule)")
    if exp.initial.kind not in ("paper", "thesis", "constant", "uniform", "gray-scott"):
        reasons.append(f"its initial state ({exp.initial.kind}) is drawn for its own lattice")
    for p in exp.phases:
        if any(getattr(leaf, "ndim", 0) >= 2 for leaf in jax.tree_util.tree_leaves(p.model)):
            reasons.append("a model holds a parameter map of the preset's size")
        if any(getattr(src, "mask", None) is not None for src in p.sources):
            reasons.append("a source has a mask of the preset's size")
        if getattr(p.domain, "polarity", None) is not None and getattr(p.domain.polarity, "ndim", 0) >= 2:
            reasons.append("its polarity is a map of the preset's size")
    if reasons:
        raise ValueError(f"--shape: preset {exp.name!r} runs on its own lattice only: {'; '.join(dict.fromkeys(reasons))}")
    return dataclasses.replace(exp, initial=dataclasses.replace(exp.initial, shape=shape))


def check_experiment_size(exp, scale: int, frames: bool = False) -> None:
    """Refuse an experiment whose lattice (its capacity), drawn `scale` pixels per cell, and
    its snapshots would need more memory than the limit (`MORPHOJAX_MAX_MEMORY`)."""
    initial = exp.initial
    shape = tuple(initial.capacity or initial.shape)
    species = max(p.model.n_species for p in exp.phases) + max((len(p.add_species) for p in exp.phases), default=0)
    snapshots = 1 + (sum(GIF_FRAMES if not isinstance(p.frames, int) else max(p.frames, 0) for p in exp.phases)
                     if frames else 0)
    check_run_size(shape, species, members=snapshots, scale=scale,
                   what=f"this run ({'x'.join(map(str, shape))} cells, {species} species, {snapshots} states, "
                        f"{scale} pixels per cell)")


def _run_automaton(item, args, out: Path):
    t0 = time.perf_counter()
    summary = item.run(seed=args.seed, quick=args.quick, out=out, frames=args.frames)
    report({"image": str(out), **summary}, f"{item.name}: wrote {out} ({time.perf_counter() - t0:.1f} s)",
           args.quiet)
    return 0


def _run_reaction_diffusion(item, args, out: Path):
    if item.members:
        return _run_figure(item, args, out)
    result = _run_one(_experiment(item, args), args, out.with_suffix(".npz"))
    _write_outputs(result, out, args)
    return 0


RUNNERS = {"reaction-diffusion": _run_reaction_diffusion, "automaton": _run_automaton,
           "potts": _run_automaton, "cells": _run_automaton, "solid": _run_automaton}  # by Preset.kind


def _run_one(exp, args, npz: Path, resume=None):
    t0 = time.perf_counter()
    if getattr(args, "gif", None) is not None:  # a movie wants more snapshots than a figure
        exp = dataclasses.replace(exp, phases=tuple(
            dataclasses.replace(p, frames=max(p.frames, GIF_FRAMES // len(exp.phases)))
            if isinstance(p.frames, int) else p for p in exp.phases))
    try:
        result = mj.run_experiment(exp, seed=getattr(args, "seed", 0), frames=args.frames or args.gif is not None,
                                   progress=not args.no_progress,
                                   checkpoint_path=npz if args.checkpoint_every else None,
                                   checkpoint_every=args.checkpoint_every, resume=resume)
    except KeyboardInterrupt:
        saved = args.checkpoint_every and npz.exists()
        raise KeyboardInterrupt(f"interrupted; the last checkpoint is {npz}: continue with `morphojax resume {npz}`"
                                if saved else "interrupted (no checkpoint: pass --checkpoint-every STEPS to keep "
                                "one)") from None
    result.metadata["run"]["seconds"] = time.perf_counter() - t0
    result.metadata["run"]["quick"] = bool(getattr(args, "quick", False))
    result.save(npz)
    return result


def _write_outputs(result, out: Path, args):
    img = mj.render_experiment(result.state, result.experiment, scale=args.scale)
    img.save(out)
    written = [str(out), str(out.with_suffix(".npz"))]
    if args.gif is not None:
        written.append(str(_write_movie(result, args)))
    if args.frames and result.frames:
        folder = out.with_name(out.stem + "_frames")
        folder.mkdir(exist_ok=True)
        tiles = []
        for k, (label, state) in enumerate(result.frames):
            if not _can_show(state, result.experiment):
                continue
            frame = mj.render_experiment(state, result.experiment, scale=args.scale)
            frame.save(folder / f"{k:03d}_{_slug(label)}.png")
            tiles.append((label, frame))
        if tiles:
            sheet = mj.montage([t for _, t in tiles], ncols=min(4, len(tiles)),
                               title=f"{result.experiment.name}: " + " | ".join(lbl for lbl, _ in tiles[:4]) + (
                                   " ..." if len(tiles) > 4 else ""))
            sheet.save(folder / "frames.png")
        written.append(str(folder))
    size, seconds = result.state.shape, result.metadata["run"]["seconds"]
    report({"preset": result.experiment.name, "written": written, "size": list(size),
            "steps": int(result.state.step), "seconds": round(seconds, 2)},
           f"{result.experiment.name}: {int(result.state.step)} steps, {'x'.join(map(str, size))} "
           f"{'lattice' if len(size) > 1 else 'vertices'}, {seconds:.1f} s; "
           f"wrote {', '.join(written)}", args.quiet)


def _write_movie(result, args) -> Path:
    """The run's snapshots (and its final state) as one animation, in one colour range."""
    exp = result.experiment
    states = [s for _, s in result.frames if _can_show(s, exp)] + [result.state]
    pictures = [mj.experiment_picture(s, exp) for s in states]
    style = pictures[-1][1]
    return mj.save_animation(args.gif, [a for a, _ in pictures], cmap=style["cmap"], vmin=style.get("vmin"),
                             vmax=style.get("vmax"), scale=args.scale)


def _can_show(state, exp) -> bool:
    """Whether a snapshot holds the species the experiment shows."""
    if exp.show == "melanin":
        return "b" in state.names and "c" in state.names
    return exp.show in state.names


def _slug(text: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in text).strip("_")


def _run_figure(item, args, out: Path):
    """A figure of several experiments: one row per member; its columns are the member's
    snapshots (`item.snapshots`) or, otherwise, one tile per member, `len(col_labels)` to a row."""
    rows, described = [], []
    args.frames = True if item.snapshots else args.frames
    for member in item.members:
        exp = _experiment(mj.PRESETS[member], args)
        result = _run_one(exp, args, out.with_name(f"{out.stem}_{member}.npz"))
        described.append({"member": member, "size": list(result.state.shape), **_descriptors(result)})
        shots = [s for _, s in result.frames if _can_show(s, exp)] if item.snapshots else []
        rows.append([mj.render_experiment(s, exp, scale=args.scale) for s in shots]
                    or [mj.render_experiment(result.state, exp, scale=args.scale)])
    images, ncols, row_labels = figure_layout(item, rows)
    mj.montage(images, ncols, row_labels=row_labels, col_labels=list(item.col_labels or []) or None,
               title=f"{item.name}: {item.figure}").save(out)
    report({"preset": item.name, "written": [str(out)], "members": list(item.members), "descriptors": described},
           f"{item.name}: {len(item.members)} runs; wrote {out}; "
           + ", ".join(f"{d['member']} {d['pattern']} ({d['spots']} spots, {d['holes']} holes)" for d in described),
           args.quiet)
    return 0


def figure_layout(item, rows):
    """(tiles, columns, row labels) of a figure's montage from its members' pictures `rows`
    (one list per member). Each member is a row of its own when it shows snapshots or the
    figure has no column labels, labelled `row_labels` or the last word of its name;
    otherwise the members are tiles, `len(col_labels)` to a row, and only the figure's own
    `row_labels` label the rows. Every tile is brought to the widest tile's width (nearest
    neighbour, its aspect kept), so lattices drawn differently (a square lattice's cells
    `scale` pixels wide, a hexagonal lattice's hexagons 8 x `scale`) come out the same size."""
    width = max(t.width for r in rows for t in r)
    rows = [[t if t.width == width else t.resize((width, max(1, round(t.height * width / t.width))),
                                                 Image.NEAREST) for t in r] for r in rows]
    ncols = max(len(r) for r in rows)
    images = [tile for r in rows for tile in r + [r[-1]] * (ncols - len(r))]
    if item.col_labels and not item.snapshots:  # one tile per member
        return images, len(item.col_labels), list(item.row_labels) if item.row_labels else None
    return images, len(item.col_labels or ()) or ncols, list(item.row_labels or [m.split("-")[-1] for m in item.members])


def _descriptors(result) -> dict:
    """The final pattern of the shown species (`Result.describe`), as JSON numbers."""
    d = result.describe()
    return {"pattern": d.pattern, "spots": d.spots, "holes": d.holes,
            "wavelength": round(float(d.wavelength), 2) if math.isfinite(d.wavelength) else None,
            "dark_fraction": round(float(d.dark_fraction), 4)}


# ---- resume and render -----------------------------------------------------------------------
def _cmd_resume(args):
    check_scale(args.scale, "--scale")
    remove_stale_temporaries(args.checkpoint)  # what a killed write of it left, even if nothing is written now
    state, meta = mj.load_npz(args.checkpoint)
    if "experiment" not in meta:
        raise ValueError(f"{args.checkpoint} holds no experiment to resume (a result of `simulate`, not of "
                         "`morphojax run`)")
    exp = mj.load_experiment(meta)
    check_experiment_size(exp, args.scale, args.frames or args.gif is not None)
    check_progress(exp, meta)
    run = meta.get("run", {})
    if int(run.get("phase", 0)) >= len(exp.phases):
        print(f"{args.checkpoint} is already complete ({len(exp.phases)} phases done)", file=sys.stderr)
    out = picture_path(args.out if args.out is not None else args.checkpoint, args.checkpoint.stem)
    check_animation_path(args)
    args.seed = int(run["seed"]) if run.get("seed") is not None else 0  # a key-started run resumes with its key
    result = _run_one(exp, args, out.with_suffix(".npz"), resume=(state, meta))
    _write_outputs(result, out, args)
    return 0


def _cmd_render(args):
    t0 = time.perf_counter()
    code = _render(args)
    out = picture_path(args.out, args.result.stem)
    report({"image": str(out), "result": str(args.result), "seconds": round(time.perf_counter() - t0, 3)},
           f"wrote {out}", args.quiet)
    return code


def _render(args):
    if args.scale is not None:
        check_scale(args.scale, "--scale")
    out = picture_path(args.out, args.result.stem)
    kind = file_kind(args.result)
    if args.palette_from is not None:
        if args.cmap is not None:
            raise ValueError("give --cmap or --palette-from, not both")
        crop = None
        if args.palette_crop:
            crop = [int(v) for v in args.palette_crop.split(",")]
            if len(crop) != 4:
                raise ValueError(f"--palette-crop takes X0,Y0,X1,Y1 (got {args.palette_crop!r})")
        args.cmap = mj.Gradient.from_photo(args.palette_from, crop=crop)
    if kind == "sweep":
        mj.load_sweep(args.result).montage(species=args.species if args.species is not None else -1,
                                           cmap=args.cmap or "inferno").save(out)
        return 0
    if kind == "automaton":
        automaton_picture(args.result, args.scale).save(out)
        return 0
    if kind == "potts":
        from morphojax.presets._potts import potts_picture

        potts_picture(args.result, args.scale).save(out)
        return 0
    if kind == "solid":
        from morphojax.presets._solids import slices_picture

        field, _ = load_solid(args.result, args.species or "v")
        slices_picture(field, args.cmap or "viridis").save(out)
        return 0
    if kind == "cells":
        cells, _ = mj.load_cells(args.result)
        mj.render_cells(cells, args.species, cmap=args.cmap or "inferno").save(out)
        return 0
    state, meta = mj.load_npz(args.result)
    if state.ndim == 1 and "mesh" in meta:  # a `morphojax mesh` result: per-vertex values on its mesh
        from morphojax.cli._mesh import load_mesh

        try:
            mesh = load_mesh(str(meta["mesh"]), float(meta.get("scale", 1.0)))
        except (ValueError, OSError) as err:
            raise ValueError(f"{args.result} holds values on the mesh {meta['mesh']!r}, which cannot be read here "
                             f"({err}); `morphojax mesh` wrote its picture beside it") from None
        if mesh.n_vertices != state.shape[0]:
            raise ValueError(f"{args.result} holds {state.shape[0]} values; the mesh {meta['mesh']!r} now has "
                             f"{mesh.n_vertices} vertices")
        species = args.species if args.species is not None else state.names[-1]
        mj.mesh_image(mesh, state.array(species), cmap=args.cmap or "inferno").save(out)
        return 0
    args.scale = 2 if args.scale is None else args.scale
    check_picture(state.capacity, args.scale, f"the picture of {args.result}")
    if args.species is None and args.cmap is None and "experiment" in meta:
        mj.render_experiment(state, mj.load_experiment(meta), scale=args.scale).save(out)
        return 0
    species = args.species if args.species is not None else state.names[-1]
    mj.to_image(state.array(species), cmap=args.cmap or "inferno", scale=args.scale).save(out)
    return 0


def file_kind(path: Path) -> str:
    """What a morphojax `.npz` holds: "result" (a run's species), "sweep", "automaton", "potts", "cells"
    or "solid" (a 3D lattice's fields)."""
    from morphojax._files import check_regular_file, open_npz, read_metadata

    check_regular_file(path, "result")
    with open_npz(path, ".npz") as data:
        names = set(data.files)
        meta = read_metadata(data, path) if "metadata" in names else {}
    if str(meta.get("format", "")).startswith("morphojax-cells/"):
        return "cells"
    if meta.get("kind") == "solid" and "v" in names:
        return "solid"
    if "cells" in names:
        return "automaton"
    if "ids" in names and meta.get("kind") == "potts":
        return "potts"
    if "config" in meta and "table" in meta:
        return "sweep"
    if "species" in meta:
        return "result"
    raise ValueError(f"{path} is not a file morphojax writes (a run's result, a sweep or an automaton's cells)")


def automaton_picture(path: Path, scale: int | None):
    """An automaton's saved cells as `morphojax ca` draws them (3D: slices); a preset's stack
    of runs (one more axis than its `lattice`) as a montage of the runs."""
    cells, meta = load_automaton(path)
    lattice = meta.get("lattice")
    runs = cells if lattice is not None and cells.ndim == len(lattice) + 1 else cells[None]
    scale = default_scale(runs.shape[1:]) if scale is None else scale
    slices = runs.shape[-2:] if runs.ndim == 3 else (8,) + runs.shape[-2:]  # what one run's picture draws
    check_picture((len(runs) * slices[0],) + slices[1:], scale, f"the picture of {path}")
    if meta.get("automaton") == "LifeLike":
        pictures = [lattice_picture(1 - run, 1, scale) for run in runs]
    else:
        params = meta.get("params")
        k = max(len(p["species"]) for p in (params if isinstance(params, list) else [params])) if params \
            else int(cells.max())
        steps = (meta.get("summary") or {}).get("steps")
        pictures = [lattice_picture(run, k, scale, title=None if steps is None else f"t = {steps}") for run in runs]
    return pictures[0] if len(pictures) == 1 else mj.montage(pictures, min(5, len(pictures)))
