"""An independent NumPy oracle of linear stability: the lattice operator as a dense matrix
built from the stencils' printed weights, the reactions written out from their equations,
Jacobians by central differences and growth rates by `numpy.linalg.eigvals`, all in
float64. It shares no code with morphojax (`_stability`, `_steady`, `_stencils`).
"""

from __future__ import annotations

import itertools

import numpy as np

# the 3x3 stencils as their docstrings print them (cells^-2)
WEIGHTS = {
    "nine-point": np.array([[1, 4, 1], [4, -20, 4], [1, 4, 1]], float) / 6.0,
    "five-point": np.array([[0, 1, 0], [1, -4, 1], [0, 1, 0]], float),
    "moore": np.array([[1, 1, 1], [1, -8, 1], [1, 1, 1]], float),
}


def stencil_matrix(stencil: str, boundary: str, shape) -> np.ndarray:
    """The operator on a (rows, cols) lattice as a dense (cells, cells) matrix: "wrap" takes
    neighbours modulo the shape, "no-flux" reads a ghost cell equal to the edge cell next
    to it (the neighbour's index clamped into the lattice)."""
    rows, cols = shape
    w = WEIGHTS[stencil]
    m = np.zeros((rows * cols, rows * cols))
    for r, c in itertools.product(range(rows), range(cols)):
        for dr, dc in itertools.product((-1, 0, 1), repeat=2):
            if boundary == "wrap":
                rr, cc = (r + dr) % rows, (c + dc) % cols
            else:
                rr, cc = min(max(r + dr, 0), rows - 1), min(max(c + dc, 0), cols - 1)
            m[r * cols + c, rr * cols + cc] += w[dr + 1, dc + 1]
    return m


def wave(shape, boundary, kr, kc) -> np.ndarray:
    """The mode (kr, kc): cos(2 pi (kr r / rows + kc c / cols)) on a torus, the product of
    cos(pi k (x + 1/2) / n) along each axis with no-flux walls."""
    r, c = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    if boundary == "wrap":
        return np.cos(2 * np.pi * (kr * r / shape[0] + kc * c / shape[1]))
    return np.cos(np.pi * kr * (r + 0.5) / shape[0]) * np.cos(np.pi * kc * (c + 0.5) / shape[1])


def period(shape, boundary, kr, kc) -> float:
    """The wave's wavelength in cells: 1 / |its frequency in cycles per cell|."""
    scale = 1.0 if boundary == "wrap" else 0.5
    fr = scale * (min(kr, shape[0] - kr) if boundary == "wrap" else kr) / shape[0]
    fc = scale * (min(kc, shape[1] - kc) if boundary == "wrap" else kc) / shape[1]
    f = np.hypot(fr, fc)
    return np.inf if f == 0 else 1.0 / f


# ---- the reactions, from their equations ----------------------------------------------------
def turing(x, ratio, scale):
    a, b = x
    return np.array([16.0 - a * b, a * b - b - 12.0])


def fitzhugh_nagumo(x, a, b, epsilon, du, dv):
    u, v = x
    return np.array([(a - u) * (u - 1.0) * u - v, epsilon * (b * u - v)])


def gierer_meinhardt(x, rho, mu, nu, du, dv):
    u, v = x
    return np.array([rho * (u * u / v - mu * u), rho * (u * u - nu * v)])


def schnakenberg(x, a, b, du, dv):
    u, v = x
    return np.array([a - u + u * u * v, b - u * u * v])


def brusselator(x, a, b, du, dv):
    u, v = x
    return np.array([a - (b + 1.0) * u + u * u * v, b * u - u * u * v])


def thomas(x, a, b, alpha, rho, K, du, dv):
    u, v = x
    r = rho * u * v / (1.0 + u + K * u * u)
    return np.array([a - u - r, alpha * (b - v) - r])


def thomas_states(a, b, alpha, rho, K):
    """Every positive homogeneous state of Thomas's model: the real roots u in
    [max(0, a - alpha b), a] of (a - u)(1 + u + K u^2) alpha = rho u (alpha b - a + u)."""
    # expand both sides as polynomials in u (highest power first)
    left = np.polymul([-1.0, a], [K, 1.0, 1.0]) * alpha
    right = np.polymul([rho, 0.0], [1.0, alpha * b - a])
    roots = np.roots(np.polysub(left, right))
    lo = max(0.0, a - alpha * b)
    us = sorted(float(r.real) for r in roots if abs(r.imag) < 1e-9 and lo - 1e-9 <= r.real <= a + 1e-9)
    return [(u, b - (a - u) / alpha) for u in us]


def jacobian(f, x, h=1e-6) -> np.ndarray:
    """Central differences of f at x, column j from x +- h (1 + |x_j|) e_j."""
    x = np.asarray(x, float)
    cols = []
    for j in range(len(x)):
        step = h * (1.0 + abs(x[j]))
        e = np.zeros_like(x)
        e[j] = step
        cols.append((f(x + e) - f(x - e)) / (2 * step))
    return np.stack(cols, axis=1)


def growth_rate(jac, diffusion, mu) -> float:
    """The largest real part of the eigenvalues of jac + mu diag(diffusion)."""
    return float(np.max(np.linalg.eigvals(jac + mu * np.diag(diffusion)).real))
