"""A mesh's per-vertex values baked into a texture image through its UV layout.

A mesh read from an OBJ file with texture coordinates keeps them as OBJ stores them
(`Mesh.uv`: one (u, v) per texture vertex; `Mesh.uv_faces`: the texture vertices of each
face's corners), so a seam's vertex has one position, on which the species diffuse across
the seam, and one texture vertex on each side of it.

`bake_values` rasterises every face in UV space and interpolates its three vertices' values
linearly (barycentric weights at each pixel centre), which reproduces a field that is
linear on each face exactly. `texture_image` maps the values through a colour map as
`vertex_colours` does, and bleeds the colours a few pixels past each island's edge, so a
renderer's filtering does not pick up the background along the seams.
"""

from __future__ import annotations

import numpy as np
from PIL import Image

from ._checks import check_range
from .domains._mesh import check_uv_layout
from ._render_mesh import vertex_colours

BACKGROUND = (128, 128, 128)  # texels no face covers (after bleeding)


def bake_values(uv, uv_faces, faces, values, size: int = 1024):
    """Per-vertex `values` (V,) interpolated over each face in UV space, on a `size` x `size`
    grid of texel centres (row 0 at v = 1, as images are stored; u along the columns).

    Returns (image, covered): the (size, size) values and where a face covers the texel.
    Where faces overlap in UV space, the later face wins."""
    if not isinstance(size, (int, np.integer)) or isinstance(size, bool):
        raise ValueError(f"size must be an integer number of texels (got {size!r})")
    check_range(size, "size", low=2, high=16384)
    uv, uv_faces, faces = check_uv_layout(uv, uv_faces, faces)
    values = np.asarray(values, np.float64).ravel()
    if faces.size and faces.max() >= len(values):
        raise ValueError(f"values needs one number per vertex (got {len(values)} for vertex {faces.max()})")
    # texel (row j, column i) has its centre at x = i, y = j in these coordinates
    x = uv[:, 0] * size - 0.5
    y = (1.0 - uv[:, 1]) * size - 0.5
    image = np.zeros((size, size))
    covered = np.zeros((size, size), bool)
    for t, c in zip(uv_faces, faces):
        xa, ya = x[t], y[t]
        i0, i1 = max(int(np.ceil(xa.min())), 0), min(int(np.floor(xa.max())), size - 1)
        j0, j1 = max(int(np.ceil(ya.min())), 0), min(int(np.floor(ya.max())), size - 1)
        if i0 > i1 or j0 > j1:
            continue
        det = (ya[1] - ya[2]) * (xa[0] - xa[2]) + (xa[2] - xa[1]) * (ya[0] - ya[2])
        if abs(det) < 1e-12:  # a face of no area in UV space covers nothing
            continue
        ii, jj = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1))
        l0 = ((ya[1] - ya[2]) * (ii - xa[2]) + (xa[2] - xa[1]) * (jj - ya[2])) / det
        l1 = ((ya[2] - ya[0]) * (ii - xa[2]) + (xa[0] - xa[2]) * (jj - ya[2])) / det
        l2 = 1.0 - l0 - l1
        inside = (l0 >= -1e-9) & (l1 >= -1e-9) & (l2 >= -1e-9)
        v = values[c]
        image[jj[inside], ii[inside]] = l0[inside] * v[0] + l1[inside] * v[1] + l2[inside] * v[2]
        covered[jj[inside], ii[inside]] = True
    return image, covered


def _bleed(rgb, covered, pixels: int):
    """Fill up to `pixels` rings of uncovered texels around the covered ones with the mean
    colour of their covered neighbours (4-neighbourhood)."""
    rgb, covered = rgb.astype(np.float64), covered.copy()
    for _ in range(pixels):
        total = np.zeros_like(rgb)
        count = np.zeros(covered.shape)
        for axis, shift in ((0, 1), (0, -1), (1, 1), (1, -1)):
            c = np.roll(covered, shift, axis)
            edge = [slice(None)] * 2
            edge[axis] = 0 if shift == 1 else -1  # no wrapping around the image
            c[tuple(edge)] = False
            total += np.where(c[..., None], np.roll(rgb, shift, axis), 0.0)
            count += c
        grow = ~covered & (count > 0)
        if not grow.any():
            break
        rgb[grow] = total[grow] / count[grow][:, None]
        covered |= grow
    return rgb, covered


def texture_image(mesh, values, size: int = 1024, cmap="inferno", vmin=None, vmax=None, bleed: int = 4) -> Image.Image:
    """The RGB texture of per-vertex `values` on a `mesh` with UVs (`Mesh.from_file` of an
    OBJ with texture coordinates): the values baked over each face (`bake_values`) through
    the colour map `cmap` on the range [vmin, vmax] (default the vertex values' own, as in
    `vertex_colours`), bled `bleed` texels past the islands' edges; grey elsewhere."""
    if getattr(mesh, "uv", None) is None:
        raise ValueError("texture_image: this mesh has no texture coordinates (read an OBJ with UVs, "
                         "or pass uv= and uv_faces= to Mesh)")
    check_range(bleed, "bleed", low=0, high=64)
    values = np.asarray(values, np.float64).ravel()
    lo = np.nanmin(values) if vmin is None else float(vmin)
    hi = np.nanmax(values) if vmax is None else float(vmax)
    image, covered = bake_values(mesh.uv, mesh.uv_faces, mesh.faces, values, size)
    rgb = vertex_colours(image.ravel(), cmap=cmap, vmin=lo, vmax=hi).reshape(size, size, 3)
    rgb, covered = _bleed(rgb, covered, int(bleed))
    rgb[~covered] = BACKGROUND
    return Image.fromarray(np.clip(np.round(rgb), 0, 255).astype(np.uint8))
