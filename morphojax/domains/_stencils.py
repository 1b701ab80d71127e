"""The square lattice's arithmetic: 3x3 stencils, ghost-cell boundaries, active regions.

Fields have shape (..., rows, cols). A boundary is expressed by one ring of ghost cells
around the active region:

- "wrap": toroidal, the ghost row above row 0 is the last active row, and so on;
- "no-flux": the ghost cell equals the edge cell next to it (scipy.ndimage mode="reflect"),
  so nothing crosses the border and total mass is conserved by pure diffusion.

The operator is then a fixed-size stencil over the padded array, which XLA fuses with
the reaction into one loop. The active region may be smaller than the array (a growing
lattice at fixed capacity); ghost cells are then placed right after the active rows and
columns, so nothing leaks in from unused capacity.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import jax.scipy.fft
import numpy as np

from .._checks import check_choice

BOUNDARIES = ("wrap", "no-flux")
STENCILS = ("nine-point", "five-point", "moore", "three-point", "seven-point", "nineteen-point")
# the number of spatial axes each stencil acts on, and the default stencil of each
STENCIL_NDIM = {"nine-point": 2, "five-point": 2, "moore": 2, "three-point": 1, "seven-point": 3,
                "nineteen-point": 3}
DEFAULT_STENCIL = {1: "three-point", 2: "nine-point", 3: "nineteen-point"}

# Largest |eigenvalue| of each stencil over all lattice sizes, in cells^-2. The symbol of a
# 3x3 stencil at wave numbers (k, l) is bilinear in (cos k, cos l), so its extremes lie at
# the corners (cos k, cos l) = (+-1, +-1):
#   nine-point [[1,4,1],[4,-20,4],[1,4,1]]/6: (8 (cos k + cos l) + 4 cos k cos l - 20) / 6,
#     -16/3 at the checkerboard (-1, -1);
#   five-point [[0,1,0],[1,-4,1],[0,1,0]]: 2 cos k + 2 cos l - 4, -8 at the checkerboard;
#   moore [[1,1,1],[1,-8,1],[1,1,1]]: 2 cos k + 2 cos l + 4 cos k cos l - 8, -12 at the
#     stripes (-1, +1) (the checkerboard gives only -8).
# Each is attained on a wrapped lattice with an even number of rows or columns and bounds
# every other lattice and boundary (no-flux drops links, which lowers the quadratic form).
#   three-point [1, -2, 1]: 2 cos k - 2, -4 at k = pi;
#   seven-point (the 3D five-point): 2 (cos k + cos l + cos m) - 6, -12 at (pi, pi, pi);
#   nineteen-point, the isotropic 3D stencil (faces 2/6, edges 1/6, centre -24/6):
#     (4 (cos k + cos l + cos m) + 4 (cos k cos l + cos k cos m + cos l cos m) - 24) / 6,
#     -16/3 where two phases are pi and one is 0 (the corner (pi, pi, pi) gives only -4).
SPECTRAL_RADIUS = {"nine-point": 16.0 / 3.0, "five-point": 8.0, "moore": 12.0, "three-point": 4.0,
                   "seven-point": 12.0, "nineteen-point": 16.0 / 3.0}
_STENCIL_ALIASES = {"9": "nine-point", "9-point": "nine-point", "nine": "nine-point",
                    "5": "five-point", "5-point": "five-point", "five": "five-point",
                    "8": "moore", "8-neighbour": "moore", "8-neighbor": "moore", "eight": "moore",
                    "3": "three-point", "3-point": "three-point", "7": "seven-point", "7-point": "seven-point",
                    "19": "nineteen-point", "19-point": "nineteen-point"}
_BOUNDARY_ALIASES = {"periodic": "wrap", "toroidal": "wrap", "noflux": "no-flux", "neumann": "no-flux",
                     "reflect": "no-flux"}


def normalise_stencil(stencil) -> str:
    key = _STENCIL_ALIASES.get(str(stencil).lower(), str(stencil).lower())
    check_choice(key, "stencil", STENCILS)
    return key


def normalise_boundary(boundary) -> str:
    key = _BOUNDARY_ALIASES.get(str(boundary).lower(), str(boundary).lower())
    check_choice(key, "boundary", BOUNDARIES)
    return key


def stencil_weights(stencil: str = "nine-point"):
    """The 3x3 stencil as a NumPy-compatible nested list (cells^-2)."""
    stencil = normalise_stencil(stencil)
    if stencil == "nine-point":
        return [[1 / 6, 4 / 6, 1 / 6], [4 / 6, -20 / 6, 4 / 6], [1 / 6, 4 / 6, 1 / 6]]
    if stencil == "moore":
        return [[1.0, 1.0, 1.0], [1.0, -8.0, 1.0], [1.0, 1.0, 1.0]]
    return [[0.0, 1.0, 0.0], [1.0, -4.0, 1.0], [0.0, 1.0, 0.0]]


def pad(x, boundary: str, lanes: bool = False):
    """Add one ring of ghost cells to the rows and columns of `x`: its last two axes, or with
    `lanes` the two before its last (a sweep's members in the last axis, see `_lanes`). The
    whole array is the lattice; `repad` writes the ghost cells of an active region inside a
    larger array."""
    widths = [(0, 0)] * (x.ndim - 2 - lanes) + [(1, 1), (1, 1)] + [(0, 0)] * lanes
    return jnp.pad(x, widths, mode="wrap" if boundary == "wrap" else "edge")


def repad(p, x, size, boundary: str):
    """Write the interior `x` (..., rows, cols) into the padded array `p` (..., rows + 2,
    cols + 2) in place, with the ghost cells of the active region `size` (may be traced).

    The ghost rows and columns are cut from `x` and written as four lines, so that XLA
    updates `p`'s buffer in place: one copy of the interior plus four lines per step, no
    padded copy of the whole array. The ghost rows are written from column 1 on; their end
    cells (the corners) come with the ghost columns, written last. Every line is computed
    from `x` alone, so XLA fuses it into its own write (a line that fed another line would
    be a separate small op, which XLA:CPU splits across threads at a cost far above its
    work; see benchmarks/results/bench_growth.md).
    Cells beyond the active region are left as they are (the ghost lines after the last
    active row and column lie there); the stepper zeroes them with its mask.
    """
    ds, dus = jax.lax.dynamic_slice_in_dim, jax.lax.dynamic_update_slice_in_dim
    ax_r, ax_c = x.ndim - 2, x.ndim - 1
    # the default integer, as the constant indices below (int64 with x64, whatever size holds)
    h, w = jnp.asarray(size[0], int), jnp.asarray(size[1], int)
    wrap = boundary == "wrap"
    top, bottom = (h - 1, 0) if wrap else (0, h - 1)  # interior rows the ghost rows copy
    left, right = (w - 1, 0) if wrap else (0, w - 1)
    i = jnp.arange(x.shape[-2] + 2)[:, None]
    lead = (0,) * (x.ndim - 2)

    def cell(r, c):  # (..., 1, 1)
        return ds(ds(x, r, 1, axis=ax_r), c, 1, axis=ax_c)

    def padded_col(c):  # (..., rows + 2, 1): column c with the corners of the ghost rows
        v = ds(x, c, 1, axis=ax_c)
        vp = jnp.concatenate([cell(top, c), v, jnp.zeros_like(cell(0, c))], axis=ax_r)
        return jnp.where(i == h + 1, cell(bottom, c), vp)

    p = jax.lax.dynamic_update_slice(p, x, lead + (1, 1))
    p = jax.lax.dynamic_update_slice(p, ds(x, top, 1, axis=ax_r), lead + (0, 1))
    p = jax.lax.dynamic_update_slice(p, ds(x, bottom, 1, axis=ax_r), lead + (h + 1, 1))
    p = dus(p, padded_col(left), 0, axis=ax_c)
    return dus(p, padded_col(right), w + 1, axis=ax_c)


def laplacian_padded(p, stencil: str = "nine-point", lanes: bool = False):
    """The stencil applied to the interior of a ghost-padded array `p` (..., rows + 2,
    cols + 2), or with `lanes` (..., rows + 2, cols + 2, members): a Laplacian in cells^-2
    for "nine-point" and "five-point"; for "moore" the thesis's equal-weight sum over the
    eight neighbours, sum_j (u_j - u), which approximates 3 x the Laplacian (edges give
    lap u, the diagonals 2 lap u)."""
    tail = (slice(None),) * lanes

    def shifted(dr, dc):  # the interior moved by (dr, dc) cells
        rows, cols = p.shape[-2 - lanes], p.shape[-1 - lanes]
        return p[(Ellipsis, slice(1 + dr, rows - 1 + dr), slice(1 + dc, cols - 1 + dc)) + tail]

    c = shifted(0, 0)
    edges = shifted(-1, 0) + shifted(1, 0) + shifted(0, -1) + shifted(0, 1)
    if stencil == "five-point":
        return edges - 4.0 * c
    corners = shifted(-1, -1) + shifted(-1, 1) + shifted(1, -1) + shifted(1, 1)
    if stencil == "moore":
        return edges + corners - 8.0 * c
    return (4.0 * edges + corners - 20.0 * c) * (1.0 / 6.0)


def active_mask(shape, size):
    """Boolean (rows, cols) mask of the active region `size` inside an array of `shape`."""
    rows = jnp.arange(shape[0])[:, None] < size[0]
    cols = jnp.arange(shape[1])[None, :] < size[1]
    return rows & cols


# ---- the stencils' eigenvalues: what the exponential and implicit solvers step on -----------
def symbol(stencil: str, *cosines):
    """The stencil's eigenvalue (cells^-2) for the wave whose phases along the axes have
    these cosines (broadcast, one per axis): the formulas of `SPECTRAL_RADIUS` above."""
    if stencil == "three-point":
        (c,) = cosines
        return 2.0 * c - 2.0
    if stencil in ("seven-point", "nineteen-point"):
        a, b, c = cosines
        if stencil == "seven-point":
            return 2.0 * (a + b + c) - 6.0
        return (4.0 * (a + b + c) + 4.0 * (a * b + a * c + b * c) - 24.0) / 6.0
    cos_r, cos_c = cosines
    if stencil == "five-point":
        return 2.0 * cos_r + 2.0 * cos_c - 4.0
    if stencil == "moore":
        return 2.0 * cos_r + 2.0 * cos_c + 4.0 * cos_r * cos_c - 8.0
    return (8.0 * (cos_r + cos_c) + 4.0 * cos_r * cos_c - 20.0) / 6.0


def eigenvalues(stencil: str, boundary: str, shape, full: bool = False) -> np.ndarray:
    """The stencil's eigenvalues (float64, cells^-2) on a lattice of `shape` (one length per
    axis), laid out as the coefficients of `forward_transform` (with `full` and "wrap", of
    the complex FFT: every k on every axis).

    "wrap": the waves exp(2 pi i sum_a k_a x_a / N_a) diagonalise every stencil on the
    torus, with phases t = 2 pi k / N; the real FFT keeps k <= N / 2 on the last axis.
    "no-flux" (ghost cell = edge cell): the cosines cos(pi k (x + 1/2) / N), the DCT-II
    basis, are even about both half-cell borders of every axis, so the ghost cells the
    stencil reads are exactly the values the reflection gives; phases t = pi k / N. Both
    are exact, not approximations of the continuum Laplacian: the stencil stays the model."""
    shape = tuple(int(n) for n in shape)
    phases = []
    for axis, n in enumerate(shape):
        if boundary == "wrap":
            t = 2.0 * np.pi * (np.fft.rfftfreq(n) if axis == len(shape) - 1 and not full else np.fft.fftfreq(n))
        else:
            t = np.pi * np.arange(n) / n
        phases.append(np.cos(t).reshape([-1 if a == axis else 1 for a in range(len(shape))]))
    return symbol(stencil, *phases)


def forward_transform(x, boundary: str, ndim: int = 2):
    """Coefficients of `x` (..., *spatial) in the eigenbasis of `eigenvalues` (its last
    `ndim` axes): the real FFT for "wrap", the orthonormal DCT-II for "no-flux"."""
    axes = tuple(range(-ndim, 0))
    if boundary == "wrap":
        return jnp.fft.rfftn(x, axes=axes)
    return jax.scipy.fft.dctn(x, type=2, axes=axes, norm="ortho")


def inverse_transform(coefficients, boundary: str, shape):
    """The fields (..., *shape) of `forward_transform`'s coefficients (real)."""
    axes = tuple(range(-len(shape), 0))
    if boundary == "wrap":
        return jnp.fft.irfftn(coefficients, s=tuple(shape), axes=axes)
    return jax.scipy.fft.idctn(coefficients, type=2, axes=axes, norm="ortho")


# ---- 1D and 3D lattices: the stencil as offsets and weights ----------------------------------
_OFFSETS_3D = [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)]
STENCIL_WEIGHTS_ND = {
    "three-point": {(-1,): 1.0, (1,): 1.0, (0,): -2.0},
    "seven-point": {**{o: 1.0 for o in _OFFSETS_3D if sum(map(abs, o)) == 1}, (0, 0, 0): -6.0},
    "nineteen-point": {**{o: 2.0 / 6.0 for o in _OFFSETS_3D if sum(map(abs, o)) == 1},
                       **{o: 1.0 / 6.0 for o in _OFFSETS_3D if sum(map(abs, o)) == 2}, (0, 0, 0): -4.0},
}


def pad_nd(x, boundary: str, ndim: int):
    """One ring of ghost cells on the last `ndim` axes of `x` (the whole array is the lattice)."""
    widths = [(0, 0)] * (x.ndim - ndim) + [(1, 1)] * ndim
    return jnp.pad(x, widths, mode="wrap" if boundary == "wrap" else "edge")


def laplacian_padded_nd(p, stencil: str):
    """A 1D or 3D stencil (`STENCIL_WEIGHTS_ND`) on the interior of a ghost-padded array."""
    weights = STENCIL_WEIGHTS_ND[stencil]
    ndim = STENCIL_NDIM[stencil]
    lead = p.ndim - ndim

    def shifted(offset):
        return p[(Ellipsis,) + tuple(slice(1 + o, p.shape[lead + a] - 1 + o) for a, o in enumerate(offset))]

    centre = weights[(0,) * ndim] * shifted((0,) * ndim)
    return centre + sum(w * shifted(o) for o, w in weights.items() if any(o))
