"""`morphojax mesh FILE`: reaction-diffusion on a triangle mesh, written as a coloured mesh.

    morphojax mesh bunny.obj --model gray-scott --set feed=0.0545 --set kill=0.062 --steps 10000 --out bunny.ply
    morphojax mesh sphere --model turing --set ratio=12 --set scale=3 --set lower_b=3 --out spots.ply
    morphojax mesh sphere --operator umbrella --set diffusion_a=1 --set diffusion_b=0.5 --dt 1 --out worms.ply

FILE is an OBJ, PLY, STL or OFF file (PLY read with trimesh, the others by morphojax),
or one of the primitives "sphere", "torus", "capsule" (sized so an edge is about one
unit). Writes the mesh with
per-vertex colours of the shown species (PLY, or OBJ with `v x y z r g b` lines), a PNG
picture next to it (or `--png`), and the per-vertex values of every species as an .npz.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import jax
import numpy as np

import morphojax as mj
from morphojax._checks import STEP_COUNTER_MAX
from morphojax._serialise import save_npz
from morphojax._files import check_output_path

from ._output import report

PRIMITIVES = {"sphere": lambda: mj.Mesh.icosphere(5, 26.0), "torus": lambda: mj.Mesh.torus(20.0, 8.0, 1.0),
              "capsule": lambda: mj.Mesh.capsule(14.0, 40.0, 1.0)}
DT_SAFETY = 0.8  # default dt = DT_SAFETY x the mesh's explicit-Euler limit


def register(subparsers) -> None:
    """Add the `mesh` subcommand."""
    p = subparsers.add_parser("mesh", help="run a reaction-diffusion model on a triangle mesh; write a coloured mesh",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", help="a mesh file (.obj, .ply, .stl, .off) or sphere / torus / capsule")
    p.add_argument("--model", default="gray-scott", help="turing, bard, gray-scott, ... (default gray-scott)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="a model parameter (repeatable), e.g. feed=0.0367")
    p.add_argument("--steps", type=int, default=10000, help="forward-Euler steps (default 10000)")
    p.add_argument("--dt", type=float, default=None, help=f"time step (default: {DT_SAFETY} x the stable limit, "
                   "at most 1)")
    p.add_argument("--operator", choices=("cotangent", "umbrella"), default="cotangent",
                   help="the mesh's Laplacian: cotangent Laplace-Beltrami (default) or the uniform umbrella "
                        "(Lundelius's equally weighted one)")
    p.add_argument("--scale", type=float, default=1.0,
                   help="multiply the mesh's coordinates by this (diffusion lengths are in mesh units)")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same result)")
    p.add_argument("--species", default=None, help="species coloured (default: the last)")
    p.add_argument("--cmap", default="inferno", help="colour map (default inferno)")
    p.add_argument("--view", type=float, nargs=2, default=(30.0, 20.0), metavar=("AZIMUTH", "ELEVATION"),
                   help="the picture's view direction in degrees")
    p.add_argument("--out", type=Path, required=True, help="output mesh: F.ply or F.obj")
    p.add_argument("--png", type=Path, default=None, help="picture (default: next to --out)")
    p.add_argument("--texture-size", type=int, default=1024,
                   help="side of the texture written with an .obj whose mesh has UVs (default 1024)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--quiet", action="store_true", help="print only the JSON line")
    p.set_defaults(func=run)


def load_mesh(text: str, scale: float = 1.0, operator: str = "cotangent") -> mj.Mesh:
    """A primitive by name or a mesh file, its coordinates times `scale`, with `operator`."""
    mesh = PRIMITIVES[text]() if text in PRIMITIVES else mj.Mesh.from_file(text)
    if not (scale > 0 and math.isfinite(scale)):
        raise ValueError(f"--scale must be a positive number (got {scale})")
    if scale != 1.0 or operator != mesh.operator:
        mesh = mj.Mesh(mesh.vertices * scale, mesh.faces, mesh.mass, uv=mesh.uv, uv_faces=mesh.uv_faces,
                       operator=operator)
    return mesh


def mesh_state(model, mesh: mj.Mesh, key) -> mj.State:
    """The model's customary start with one value per vertex: Gray-Scott seeded on 12
    patches (as the mesh presets), every other model its `initial_state`."""
    from morphojax.presets._meshes import seed_patches

    n = mesh.n_vertices
    if isinstance(model, mj.GrayScott):
        return mj.gray_scott_state(key, (n,), seeded=seed_patches(mesh))
    return mj.initial_state(model, key, (n,))


def run(args) -> int:
    out = Path(args.out)
    if out.suffix.lower() not in (".ply", ".obj"):
        raise ValueError(f"--out must end in .ply or .obj (got {out.name!r})")
    params = {}
    for item in args.set:
        name, sep, text = item.partition("=")
        if not sep:
            raise ValueError(f"--set needs NAME=VALUE (got {item!r})")
        try:
            params[name.strip()] = float(text)
        except ValueError:
            raise ValueError(f"--set {name}: {text!r} is not a number") from None
    if not 0 <= args.steps <= STEP_COUNTER_MAX:
        raise ValueError(f"--steps must lie in [0, {STEP_COUNTER_MAX}] (got {args.steps})")
    check_output_path(out)  # before the run, not after it
    model = mj.model_from_name(args.model, **params)
    mesh = load_mesh(args.file, args.scale, args.operator)
    limit = mesh.max_stable_dt(float(model.max_diffusion()))
    dt = args.dt if args.dt is not None else min(1.0, DT_SAFETY * limit)
    state = mesh_state(model, mesh, jax.random.key(args.seed))
    final = mj.simulate(model, state, args.steps, dt, domain=mesh,
                        progress=False if args.no_progress or args.quiet else args.model)
    species = args.species if args.species is not None else final.names[-1]
    values = final.array(species)
    colours = mj.vertex_colours(values, cmap=args.cmap)
    out.parent.mkdir(parents=True, exist_ok=True)
    comment = f"morphojax {args.model} on {Path(args.file).name}"
    written = [out]
    if out.suffix.lower() == ".ply":
        mj.write_ply(out, mesh.vertices, mesh.faces, colour=colours, comment=comment)
    elif mesh.uv is None:
        mj.write_obj(out, mesh.vertices, mesh.faces, colour=colours, comment=comment)
    else:  # the mesh's own UV layout: a texture beside the OBJ (and its material)
        texture = mj.texture_image(mesh, values, size=args.texture_size, cmap=args.cmap)
        mj.write_obj(out, mesh.vertices, mesh.faces, colour=colours, comment=comment, uv=mesh.uv,
                     uv_faces=mesh.uv_faces, texture=texture)
        written += [out.with_suffix(".mtl"), out.with_name(f"{out.stem}_texture.png")]
    png = args.png if args.png is not None else out.with_suffix(".png")
    mj.mesh_image(mesh, values, cmap=args.cmap, view=tuple(args.view)).save(png)
    npz = out.with_suffix(".npz")
    save_npz(npz, final, {"mesh": str(args.file), "model": mj.model_to_dict(model), "dt": dt, "steps": args.steps,
                          "seed": args.seed, "scale": args.scale, "operator": args.operator})
    summary = {"mesh": str(args.file), "vertices": mesh.n_vertices, "operator": args.operator, "model": args.model,
               "dt": dt,
               "max_stable_dt": limit, "steps": args.steps, "species": species,
               "min": float(np.min(values)), "max": float(np.max(values)),
               "written": [str(p) for p in (*written, png, npz)]}
    report(summary, f"{args.model} on {mesh.n_vertices} vertices, {args.steps} steps at dt {dt:.4g}: wrote "
                    f"{', '.join(str(p) for p in (*written, png, npz))}", args.quiet)
    return 0
