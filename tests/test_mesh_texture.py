"""Textures from a mesh's UVs (issue 21): OBJ texture coordinates kept through `Mesh.from_file`
with the seams welded, values baked in UV space (a field linear on each face comes out
exactly), and a textured OBJ (+ material + image) that trimesh reads back."""

import re

import numpy as np
import pytest

import morphojax as mj
from mesh_oracle import grid_mesh
from morphojax._mesh_texture import bake_values

# a strip of two unit squares; the texture is cut along the middle edge (x = 1): the right
# square's texture vertices on that edge are (0.6, 0) and (0.6, 1), not (0.5, 0) and (0.5, 1)
SEAMED_OBJ = """\
v 0 0 0
v 1 0 0
v 2 0 0
v 0 1 0
v 1 1 0
v 2 1 0
vt 0 0
vt 0.5 0
vt 1 0
vt 0 1
vt 0.5 1
vt 1 1
vt 0.6 0
vt 0.6 1
f 1/1 2/2 5/5
f 1/1 5/5 4/4
f 2/7 3/3 6/6
f 2/7 6/6 5/8
"""


@pytest.fixture(scope="module")
def plane():
    """A flat 7 x 7 grid (6 x 6 units) with the UVs of its own x, y scaled to [0, 1]."""
    v, f = grid_mesh(7)
    uv = v[:, :2] / 6.0
    return mj.Mesh(v, f, uv=uv, uv_faces=f)


def test_obj_uvs_are_kept_and_seams_welded(tmp_path):
    path = tmp_path / "strip.obj"
    path.write_text(SEAMED_OBJ)
    mesh = mj.Mesh.from_file(path)
    # trimesh splits the two seam vertices (8 vertices); the mesh has the 6 positions
    assert mesh.n_vertices == 6 and mesh.faces.shape == (4, 3)
    assert mesh.uv.shape == (8, 2) and mesh.uv_faces.shape == (4, 3)
    # every corner's texture vertex is the one the file gives it
    corners = {(tuple(np.round(mesh.vertices[v].astype(float), 6)), tuple(np.round(mesh.uv[t].astype(float), 6)))
               for f, tf in zip(mesh.faces, mesh.uv_faces) for v, t in zip(f, tf)}
    assert ((1.0, 0.0, 0.0), (0.5, 0.0)) in corners and ((1.0, 0.0, 0.0), (0.6, 0.0)) in corners
    # diffusion crosses the seam: the same operator as the strip built without texture coordinates
    welded = mj.Mesh(mesh.vertices, mesh.faces)
    field = np.asarray(mesh.vertices[:, 0] ** 2, np.float32)[None]
    np.testing.assert_allclose(np.asarray(mesh.apply(field)), np.asarray(welded.apply(field)), rtol=1e-6)
    spike = np.zeros((1, 6), np.float32)
    spike[0, 0] = 1.0  # (0, 0, 0), left of the seam
    assert np.asarray(mesh.apply(mesh.apply(spike)))[0, 2] != 0.0  # reaches (2, 0, 0) in two steps


def test_baking_reproduces_a_linear_field_exactly(plane):
    values = 0.5 + 2.0 * plane.vertices[:, 0] - 0.25 * plane.vertices[:, 1]
    size = 24
    image, covered = bake_values(plane.uv, plane.uv_faces, plane.faces, values, size)
    assert covered.all()  # the grid covers the whole UV square
    u = (np.arange(size) + 0.5) / size
    v = 1.0 - (np.arange(size) + 0.5) / size  # row 0 is the top of the image, v = 1
    x, y = np.meshgrid(u * 6.0, v * 6.0)
    np.testing.assert_allclose(image, 0.5 + 2.0 * x - 0.25 * y, atol=1e-5)  # float32 UVs


def test_texture_image_colours_and_bleeds(plane):
    half = mj.Mesh(plane.vertices, plane.faces, uv=plane.uv * 0.5, uv_faces=plane.uv_faces)  # the bottom-left quarter
    values = plane.vertices[:, 0]
    img = np.asarray(mj.texture_image(half, values, size=32, cmap="gray", bleed=2))
    assert img.shape == (32, 32, 3)
    assert (img[-1, 0] < 10).all() and (img[-1, 15] > 235).all()  # x = 0 black, x = 6 white on the island
    assert (img[:12, 20:] == 128).all()  # far from the island: the background
    assert (img[-1, 16:18] != 128).all()  # two texels of bleeding past the island's right edge
    assert (img[-1, 18] == 128).all()


def test_textured_obj_is_read_back(tmp_path, plane):
    trimesh = pytest.importorskip("trimesh")
    values = plane.vertices[:, 0]
    out = tmp_path / "plane.obj"
    mj.write_obj(out, plane.vertices, plane.faces, colour=mj.vertex_colours(values), uv=plane.uv,
                 uv_faces=plane.uv_faces, texture=mj.texture_image(plane, values, size=16))
    assert out.with_suffix(".mtl").exists() and (tmp_path / "plane_texture.png").exists()
    loaded = trimesh.load(str(out), force="mesh", process=False)
    assert loaded.visual.material.image.size == (16, 16)
    np.testing.assert_allclose(np.unique(loaded.visual.uv, axis=0), np.unique(plane.uv, axis=0), atol=1e-6)
    back = mj.Mesh.from_file(out)
    assert back.n_vertices == plane.n_vertices and back.uv is not None


def test_bad_texture_inputs_are_refused(plane, tmp_path):
    with pytest.raises(ValueError, match="no texture coordinates"):
        mj.texture_image(mj.Mesh(plane.vertices, plane.faces), plane.vertices[:, 0])
    with pytest.raises(ValueError, match="both uv and uv_faces"):
        mj.Mesh(plane.vertices, plane.faces, uv=plane.uv)
    with pytest.raises(ValueError, match="uv_faces must index"):
        mj.Mesh(plane.vertices, plane.faces, uv=plane.uv[:5], uv_faces=plane.faces)
    with pytest.raises(ValueError, match="one number per vertex"):
        bake_values(plane.uv, plane.uv_faces, plane.faces, np.zeros(3), 8)
    with pytest.raises(ValueError, match="size"):
        mj.texture_image(plane, plane.vertices[:, 0], size=1)
    with pytest.raises(ValueError, match="needs texture coordinates"):
        mj.write_obj(tmp_path / "x.obj", plane.vertices, plane.faces, texture=mj.texture_image(plane, np.zeros(49)))


def test_cli_writes_a_textured_obj(tmp_path):
    from morphojax.cli import main

    src = tmp_path / "strip.obj"
    src.write_text(SEAMED_OBJ)
    out = tmp_path / "out" / "strip.obj"
    assert main(["mesh", str(src), "--steps", "3", "--texture-size", "16", "--out", str(out), "--quiet"]) == 0
    assert out.with_suffix(".mtl").exists() and (out.parent / "strip_texture.png").exists()
    assert "map_Kd strip_texture.png" in out.with_suffix(".mtl").read_text()
    assert re.search(r"^f \d+/\d+ \d+/\d+ \d+/\d+$", out.read_text(), re.M)  # faces name texture vertices
