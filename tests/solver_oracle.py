"""NumPy oracle for the exponential and IMEX solvers: the stencil as a dense matrix, its
eigenvectors by `numpy.linalg.eigh`, and the schemes written from their papers' formulas
in that basis (no FFT, no DCT, no contour integrals). Float64 throughout."""

import math

import numpy as np

from oracle import laplacian


def stencil_matrix(shape, boundary, stencil):
    """The stencil on a (rows, cols) lattice as an (n, n) matrix (acting on raveled fields)."""
    n = shape[0] * shape[1]
    columns = [laplacian(np.eye(n)[j].reshape(shape), boundary, stencil).ravel() for j in range(n)]
    return np.stack(columns, axis=1)


def eigenbasis(shape, boundary, stencil):
    s = stencil_matrix(shape, boundary, stencil)
    assert np.allclose(s, s.T), "the stencil matrix is symmetric"
    return np.linalg.eigh(s)


def phi(z, k):
    """phi_k(z) in float64: the defining formula, or its Taylor series sum z^j / (j + k)! near 0."""
    z = np.asarray(z, float)
    series = sum(z**j / math.factorial(j + k) for j in range(25))
    with np.errstate(all="ignore"):
        if k == 0:
            direct = np.exp(z)
        else:
            direct = (np.exp(z) - sum(z**j / math.factorial(j) for j in range(k))) / z**k
    return np.where(np.abs(z) < 0.5, series, direct)


class Stepper:
    """One step of a scheme for dx_i/dt = D_i S x_i + N(x)_i, x of shape (species, rows, cols).
    With `lower`, the reaction is evaluated on stages clamped to it (as morphojax does)."""

    def __init__(self, shape, boundary, stencil, rates, reaction, lower=None):
        self.w, self.v = eigenbasis(shape, boundary, stencil)
        self.shape, self.rates = shape, np.asarray(rates, float)
        self.reaction = reaction if lower is None else (lambda y: reaction(np.maximum(y, lower)))

    def _to(self, x):  # fields -> eigen-coefficients per species
        return np.stack([self.v.T @ xi.ravel() for xi in x])

    def _back(self, c):
        return np.stack([(self.v @ ci).reshape(self.shape) for ci in c])

    def _z(self, dt):
        return dt * self.rates[:, None] * self.w[None, :]

    def etdrk(self, x, dt, order):
        z, n = self._z(dt), lambda y: self._to(self.reaction(y))
        v = self._to(x)
        if order == 1:  # x_{n+1} = e^z x + dt phi_1(z) N(x)
            return self._back(phi(z, 0) * v + dt * phi(z, 1) * n(x))
        if order == 2:  # Cox and Matthews (2002) eq. (22)
            a = phi(z, 0) * v + dt * phi(z, 1) * n(x)
            return self._back(a + dt * phi(z, 2) * (n(self._back(a)) - n(x)))
        # Cox and Matthews (2002) ETDRK4, eqs. (26)-(29)
        e2, q = phi(z / 2, 0), dt / 2 * phi(z / 2, 1)
        nv = n(x)
        a = e2 * v + q * nv
        na = n(self._back(a))
        b = e2 * v + q * na
        nb = n(self._back(b))
        c = e2 * a + q * (2 * nb - nv)
        nc = n(self._back(c))
        p1, p2, p3 = phi(z, 1), phi(z, 2), phi(z, 3)
        f1, f2, f3 = p1 - 3 * p2 + 4 * p3, p2 - 2 * p3, 4 * p3 - p2
        return self._back(phi(z, 0) * v + dt * (f1 * nv + 2 * f2 * (na + nb) + f3 * nc))

    def imex(self, x, dt, order):
        z, n = self._z(dt), lambda y: self._to(self.reaction(y))
        v = self._to(x)
        if order == 1:  # (1 - dt L) x_{n+1} = x + dt N(x)
            return self._back((v + dt * n(x)) / (1 - z))
        g = 1 - 2**-0.5  # Ascher, Ruuth and Spiteri (1997), the (2,2,2) tableaux
        d = 1 - 1 / (2 * g)
        u1 = (v + dt * g * n(x)) / (1 - g * z)
        n1 = n(self._back(u1))
        u2 = (v + (1 - g) * z * u1 + dt * (d * n(x) + (1 - d) * n1)) / (1 - g * z)
        return self._back(u2)
