"""Pictures and meshes of cellular-automaton lattices.

2D lattices become images with one colour per state (`cells_image`); 3D lattices a
montage of slices (`slice_montage`) and, per species, a closed surface mesh from
scikit-image's marching cubes (`species_mesh`), written as PLY or OBJ by the small
writers here (`write_ply`, `write_obj`). Mesh coordinates are in lattice cells.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageColor

from ._render import colormap_table, montage, to_image

# species colours (paper 002 style: distinct hues), then the undifferentiated state
SPECIES_COLOURS = ("#1d1208", "#d0743c", "#3b6ea5", "#6a9a3a", "#a53b6e", "#e0b02c", "#4bb3b0", "#7b5ea7")
UNDIFFERENTIATED = "#f3e3c3"


def state_colours(k: int) -> np.ndarray:
    """(k + 1, 3) uint8 colours: species 0..k-1, then the undifferentiated state k."""
    names = [SPECIES_COLOURS[j % len(SPECIES_COLOURS)] for j in range(k)] + [UNDIFFERENTIATED]
    cols = [ImageColor.getrgb(c)[:3] for c in names]
    return np.array(cols, np.uint8)


def state_table(k: int) -> np.ndarray:
    """A (256, 3) colour table (for `_render.to_image`) whose entry s is state s's colour."""
    table = colormap_table("gray").copy()
    table[: k + 1] = state_colours(k)
    return table


def cells_image(cells, k: int, scale: int = 1) -> Image.Image:
    """A 2D lattice of states 0..k as an RGB image (one colour per state)."""
    cells = np.asarray(cells)
    if cells.ndim != 2:
        raise ValueError(f"cells_image needs a 2D lattice (got shape {cells.shape})")
    return to_image(cells.astype(np.int64), cmap=state_table(k), vmin=0, vmax=255, scale=scale)


def slice_montage(cells, k: int, n: int = 6, axis: int = 0, scale: int = 2, ncols: int | None = None,
                  title: str | None = None) -> Image.Image:
    """`n` evenly spaced slices of a 3D lattice along `axis`, labelled by their index."""
    cells = np.asarray(cells)
    if cells.ndim != 3:
        raise ValueError(f"slice_montage needs a 3D lattice (got shape {cells.shape})")
    n = max(1, min(int(n), cells.shape[axis]))
    idx = np.linspace(0, cells.shape[axis] - 1, n).round().astype(int)
    images = [cells_image(np.take(cells, i, axis=axis), k, scale) for i in idx]
    ncols = ncols or min(n, 4)
    where = f"slices at axis-{axis} index " + ", ".join(map(str, idx))
    return montage(images, ncols, title=f"{title}; {where}" if title else where)


def species_mesh(cells, j: int, *, step_size: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Surface between species j and every other state (paper 002 Fig. 4b), by marching
    cubes on the padded indicator, so the surface is closed at the lattice boundary.
    Returns (vertices (V, 3) float32 in lattice cells, faces (F, 3) int32)."""
    from skimage.measure import marching_cubes

    cells = np.asarray(cells)
    if cells.ndim != 3:
        raise ValueError(f"species_mesh needs a 3D lattice (got shape {cells.shape})")
    ind = np.pad((cells == j).astype(np.float32), 1)
    if not ind.any():
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
    # "ascent": the indicator rises into the species, so the triangles wind counter-clockwise
    # seen from outside (outward normals, as PLY / OBJ viewers expect)
    verts, faces, _, _ = marching_cubes(ind, level=0.5, step_size=step_size, allow_degenerate=False,
                                        gradient_direction="ascent")
    return (verts - 1.0).astype(np.float32), faces.astype(np.int32)


def write_ply(path, vertices, faces, colour=None) -> Path:
    """A binary little-endian PLY triangle mesh (optional uniform RGB vertex colour)."""
    path = Path(path)
    vertices = np.asarray(vertices, np.float32).reshape(-1, 3)
    faces = np.asarray(faces, np.int32).reshape(-1, 3)
    header = ["ply", "format binary_little_endian 1.0", "comment morphojax cellular automaton",
              f"element vertex {len(vertices)}", "property float x", "property float y", "property float z"]
    vdtype = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if colour is not None:
        header += ["property uchar red", "property uchar green", "property uchar blue"]
        vdtype += [("r", "u1"), ("g", "u1"), ("b", "u1")]
    header += [f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    vrec = np.zeros(len(vertices), dtype=vdtype)
    vrec["x"], vrec["y"], vrec["z"] = vertices.T
    if colour is not None:
        vrec["r"], vrec["g"], vrec["b"] = (int(c) for c in colour)
    frec = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    frec["n"] = 3
    frec["i"] = faces
    with open(path, "wb") as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        fh.write(vrec.tobytes())
        fh.write(frec.tobytes())
    return path


def read_ply(path) -> tuple[np.ndarray, np.ndarray]:
    """Read back a mesh written by `write_ply` (vertices, faces)."""
    data = Path(path).read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    n_v = int(next(h for h in header if h.startswith("element vertex")).split()[-1])
    n_f = int(next(h for h in header if h.startswith("element face")).split()[-1])
    coloured = any(h.startswith("property uchar red") for h in header)
    vdtype = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")] + ([("r", "u1"), ("g", "u1"), ("b", "u1")] if coloured else [])
    v = np.frombuffer(data, dtype=vdtype, count=n_v, offset=end)
    f = np.frombuffer(data, dtype=[("n", "u1"), ("i", "<i4", (3,))], count=n_f, offset=end + v.nbytes)
    return np.stack([v["x"], v["y"], v["z"]], 1), f["i"].copy()


def write_obj(path, vertices, faces) -> Path:
    """A Wavefront OBJ triangle mesh (text; indices are 1-based)."""
    path = Path(path)
    vertices = np.asarray(vertices, np.float32).reshape(-1, 3)
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    with open(path, "w") as fh:
        fh.write("# morphojax cellular automaton\n")
        np.savetxt(fh, vertices, fmt="v %.4f %.4f %.4f")
        np.savetxt(fh, faces + 1, fmt="f %d %d %d")
    return path


def write_species_meshes(cells, k: int, stem, fmt: str = "ply") -> list[Path]:
    """One mesh file per species present: `{stem}_species{j}.{fmt}` (PLY coloured like
    the images). Returns the paths written."""
    if fmt not in ("ply", "obj"):
        raise ValueError(f"unknown mesh format {fmt!r}; allowed: 'ply', 'obj'")
    stem = Path(stem)
    colours = state_colours(k)
    paths = []
    for j in range(k):
        verts, faces = species_mesh(cells, j)
        if len(faces) == 0:
            continue
        path = stem.parent / f"{stem.name}_species{j}.{fmt}"
        if fmt == "ply":
            write_ply(path, verts, faces, colour=colours[j])
        else:
            write_obj(path, verts, faces)
        paths.append(path)
    return paths
