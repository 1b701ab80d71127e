"""Meshes of 3D cellular-automaton lattices, and the PLY / OBJ writers of every mesh.

Per species, a closed surface mesh from scikit-image's marching cubes (`species_mesh`),
written as PLY (coloured like the pictures) or OBJ by the small writers here
(`write_ply`, `write_obj`, `write_species_meshes`). Coordinates are in lattice cells.
The writers also take one colour per vertex: reaction-diffusion on a `Mesh` writes its
values through them (`mj.vertex_colours`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._pictures import state_colours


def species_mesh(cells, j: int, *, step_size: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Surface between species j and every other state (Dur 2023 Fig. 4b), by marching
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


def _vertex_colours(colour, n: int):
    """None, or an (n, 3) uint8 array from one RGB triple or one triple per vertex."""
    if colour is None:
        return None
    c = np.asarray(colour)
    if c.shape == (3,):
        c = np.broadcast_to(c, (n, 3))
    if c.shape != (n, 3):
        raise ValueError(f"colour must be one RGB triple or one per vertex, shape ({n}, 3) (got {c.shape})")
    if np.issubdtype(c.dtype, np.floating) and c.size and c.max() <= 1.0:
        c = np.round(c * 255.0)  # colours in [0, 1]
    if c.size and (c.min() < 0 or c.max() > 255):
        raise ValueError("colour values must lie in [0, 255] (or [0, 1] as floats)")
    return c.astype(np.uint8)


def _written_by() -> str:
    """The version line every mesh file carries (morphojax's version and the file format number)."""
    from .._files import FORMAT_VERSION
    from .._version import __version__

    return f"written by morphojax {__version__}, format {FORMAT_VERSION}"


def write_ply(path, vertices, faces, colour=None, comment: str = "morphojax") -> Path:
    """A binary little-endian PLY triangle mesh with optional vertex colours: `colour` is
    one RGB triple for every vertex or an (V, 3) array, one per vertex (uint8, or floats
    in [0, 1]; `mj.vertex_colours` maps values through a colour map)."""
    path = Path(path)
    vertices = np.asarray(vertices, np.float32).reshape(-1, 3)
    faces = np.asarray(faces, np.int32).reshape(-1, 3)
    colours = _vertex_colours(colour, len(vertices))
    header = ["ply", "format binary_little_endian 1.0", f"comment {comment}", f"comment {_written_by()}",
              f"element vertex {len(vertices)}", "property float x", "property float y", "property float z"]
    vdtype = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if colours is not None:
        header += ["property uchar red", "property uchar green", "property uchar blue"]
        vdtype += [("r", "u1"), ("g", "u1"), ("b", "u1")]
    header += [f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    vrec = np.zeros(len(vertices), dtype=vdtype)
    vrec["x"], vrec["y"], vrec["z"] = vertices.T
    if colours is not None:
        vrec["r"], vrec["g"], vrec["b"] = colours.T
    frec = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    frec["n"] = 3
    frec["i"] = faces
    from .._files import write_atomically

    def write(tmp):
        with open(tmp, "wb") as fh:
            fh.write(("\n".join(header) + "\n").encode("ascii"))
            fh.write(vrec.tobytes())
            fh.write(frec.tobytes())

    return write_atomically(path, write)


def read_ply(path, colours: bool = False):
    """Read back a mesh written by `write_ply`: (vertices, faces), and with `colours=True`
    also the (V, 3) uint8 vertex colours (None when the file has none)."""
    data = Path(path).read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    n_v = int(next(h for h in header if h.startswith("element vertex")).split()[-1])
    n_f = int(next(h for h in header if h.startswith("element face")).split()[-1])
    coloured = any(h.startswith("property uchar red") for h in header)
    vdtype = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")] + ([("r", "u1"), ("g", "u1"), ("b", "u1")] if coloured else [])
    v = np.frombuffer(data, dtype=vdtype, count=n_v, offset=end)
    f = np.frombuffer(data, dtype=[("n", "u1"), ("i", "<i4", (3,))], count=n_f, offset=end + v.nbytes)
    out = np.stack([v["x"], v["y"], v["z"]], 1), f["i"].copy()
    if not colours:
        return out
    return out + ((np.stack([v["r"], v["g"], v["b"]], 1) if coloured else None),)


def write_obj(path, vertices, faces, colour=None, comment: str = "morphojax", *, uv=None, uv_faces=None,
              texture=None) -> Path:
    """A Wavefront OBJ triangle mesh (text; indices are 1-based). With `colour` (as for
    `write_ply`) each vertex line carries its colour as `v x y z r g b` with r, g, b in
    [0, 1], the vertex-colour extension that MeshLab, Blender and trimesh read.

    With texture coordinates (`uv` (T, 2) and `uv_faces` (F, 3), as `Mesh` holds them) the
    faces name their texture vertices (`f v/vt`); with a `texture` image as well (e.g.
    `mj.texture_image(mesh, values)`), it is written beside as `{stem}_texture.png` with a material
    `{stem}.mtl` that maps it (`map_Kd`). Every file is written atomically."""
    from .._files import write_atomically

    path = Path(path)
    vertices = np.asarray(vertices, np.float32).reshape(-1, 3)
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    colours = _vertex_colours(colour, len(vertices))
    if (uv is None) != (uv_faces is None):
        raise ValueError("write_obj: give both uv and uv_faces (texture coordinates), or neither")
    if texture is not None and uv is None:
        raise ValueError("write_obj: a texture needs texture coordinates (uv= and uv_faces=)")
    if uv is not None:
        from ..domains._mesh import check_uv_layout

        uv, uv_faces, _ = check_uv_layout(uv, uv_faces, faces)
    material = path.with_suffix(".mtl")
    if texture is not None:
        image = path.with_name(f"{path.stem}_texture.png")
        write_atomically(image, lambda tmp: texture.save(tmp, format="PNG"))

        def write_material(tmp):
            with open(tmp, "w") as fh:
                fh.write(f"# {comment}\nnewmtl morphojax\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nmap_Kd {image.name}\n")

        write_atomically(material, write_material)

    def write(tmp):
        with open(tmp, "w") as fh:
            fh.write(f"# {comment}\n# {_written_by()}\n")
            if texture is not None:
                fh.write(f"mtllib {material.name}\nusemtl morphojax\n")
            if colours is None:
                np.savetxt(fh, vertices, fmt="v %.4f %.4f %.4f")
            else:
                np.savetxt(fh, np.hstack([vertices, colours / 255.0]), fmt="v %.4f %.4f %.4f %.4f %.4f %.4f")
            if uv is None:
                np.savetxt(fh, faces + 1, fmt="f %d %d %d")
            else:
                np.savetxt(fh, uv, fmt="vt %.6f %.6f")
                corners = np.stack([faces + 1, uv_faces + 1], axis=-1).reshape(-1, 6)
                np.savetxt(fh, corners, fmt="f %d/%d %d/%d %d/%d")

    return write_atomically(path, write)


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
            write_ply(path, verts, faces, colour=colours[j], comment="morphojax cellular automaton")
        else:
            write_obj(path, verts, faces, comment="morphojax cellular automaton")
        paths.append(path)
    return paths
