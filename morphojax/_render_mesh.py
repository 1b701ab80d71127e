"""Pictures of values on a triangle mesh: per-vertex colours and a small software renderer.

`vertex_colours` maps one value per vertex through the library's colour maps (the same
tables as the lattice pictures). `mesh_image` draws the surface headless with Pillow: an
orthographic view from the direction `view` = (azimuth, elevation) in degrees, each
triangle filled with the mean colour of its corners times a Lambert shading factor, in
the painter's order (farthest first); triangles facing away are skipped, which is exact
for a closed surface wound outward and a fair picture of an open one.
"""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw

from ._colours import colormap_table


def vertex_colours(values, cmap="inferno", vmin=None, vmax=None) -> np.ndarray:
    """(V, 3) uint8 colours of per-vertex `values` through the colour map `cmap` (a name,
    a Gradient or a table), the range [vmin, vmax] defaulting to the values' own."""
    x = np.asarray(values, np.float64).ravel()
    lo = np.nanmin(x) if vmin is None else float(vmin)
    hi = np.nanmax(x) if vmax is None else float(vmax)
    t = (x - lo) / (hi - lo) if hi > lo else np.zeros_like(x)
    table = colormap_table(cmap)
    idx = np.clip(np.nan_to_num(t) * (len(table) - 1), 0, len(table) - 1).round().astype(int)
    return table[idx].astype(np.uint8)


def _rotation(view) -> np.ndarray:
    """Rows: the screen's right, up and towards-the-viewer axes for (azimuth, elevation)."""
    az, el = np.radians(float(view[0])), np.radians(float(view[1]))
    towards = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    right = np.array([-np.sin(az), np.cos(az), 0.0])
    up = np.cross(towards, right)
    return np.stack([right, up, towards])


def mesh_image(mesh, values, cmap="inferno", view=(30.0, 20.0), size: int = 512, vmin=None, vmax=None,
               background=(255, 255, 255), light=(0.4, 0.3, 1.0), ambient: float = 0.35) -> Image.Image:
    """A `size` x `size` RGB picture of per-vertex `values` on `mesh` (a `Mesh`, or a
    (vertices, faces) pair), seen from `view` = (azimuth, elevation) in degrees (z up).

    `light` is the light's direction in the view's frame (right, up, towards the viewer);
    a triangle's brightness is ambient + (1 - ambient) max(0, n . light).
    """
    if isinstance(mesh, tuple):
        vertices, faces = mesh
    else:
        vertices, faces = mesh.vertices, mesh.faces
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    values = np.asarray(values)
    if values.shape != (len(v),):
        raise ValueError(f"mesh_image.values needs one value per vertex, shape ({len(v)},) (got {values.shape})")
    colours = vertex_colours(values, cmap, vmin, vmax).astype(np.float64)
    p = (v - v.mean(0)) @ _rotation(view).T  # (right, up, towards)
    tri = p[f]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    facing = normal[:, 2] > 0
    lamp = np.asarray(light, float) / np.linalg.norm(light)
    shade = ambient + (1.0 - ambient) * np.clip(normal @ lamp, 0.0, 1.0)
    rgb = np.clip(colours[f].mean(1) * shade[:, None], 0, 255).astype(np.uint8)
    extent = np.abs(p[:, :2]).max() * 1.05 or 1.0
    half = size / 2.0
    xy = np.stack([half + tri[..., 0] / extent * half, half - tri[..., 1] / extent * half], -1)
    img = Image.new("RGB", (int(size), int(size)), tuple(int(c) for c in background))
    draw = ImageDraw.Draw(img)
    for k in np.flatnonzero(facing)[np.argsort(tri[facing, :, 2].mean(1))]:  # far to near
        colour = tuple(int(c) for c in rgb[k])
        draw.polygon([tuple(q) for q in xy[k]], fill=colour, outline=colour)
    return img
