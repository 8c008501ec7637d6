"""Spherical harmonics descriptor (SHD) of a mesh, after Kazhdan, Funkhouser & Rusinkiewicz 2003.

The surface is described by how its area is distributed over concentric spheres around its
centroid. On each sphere (shell) the area forms a function of direction; its spherical
harmonic expansion is taken and, for every frequency ``l``, only the energy
``‖f_l‖ = sqrt(Σ_m |c_lm|^2)`` is kept. Energies do not change when the function is rotated,
so the descriptor is rotation invariant without pose normalisation.

Simplifications against the paper (documented, deliberate): instead of voxelising the
surface and sampling each shell on a grid, the surface is represented by ``n_points``
area-weighted random samples (seeded) and the shell functions are the resulting sums of
point masses, spread linearly over the two nearest shells. The coefficients of a sum of
point masses are exact sums of ``conj(Y_lm)`` at the points, so the only approximation is
the sampling. Shapes are centred at the area centroid and scaled to unit RMS radius
(translation and scale invariance).

Shapes: ``n_shells x (l_max + 1)`` energies, flattened; compare with L2 (the paper's metric).
"""

from __future__ import annotations

import numpy as np

from geoshape.errors import InvalidOptionError
from geoshape.geometry.mesh import face_areas
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

__all__ = ["surface_samples", "normalize_surface", "shd_descriptor", "SHD_SHELLS", "SHD_LMAX"]

SHD_SHELLS = 16
SHD_LMAX = 16
SHD_POINTS = 6000
#: outer shell radius, in units of the RMS radius
SHD_RADIUS = 2.5


@mesh_input
def surface_samples(V, F, n_points: int, seed: int = 0) -> np.ndarray:
    """Area-weighted uniform random points on the triangles of a mesh.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    n_points : int
    seed : int

    Returns
    -------
    P : (n_points, 3) float64
        Points on the surface; the vertices themselves (uniform over vertices) for a mesh
        without faces or of zero area.

    Notes
    -----
    Time O(m + n_points log m).
    """
    # Not trimesh.sample.sample_surface: that draws the same kind of points but consumes the
    # generator in another order (faces from an unnormalised cumulative sum, then interleaved
    # (u, v) pairs), so one seed gives other points (0.27 apart on a unit icosphere) and other
    # SHD values, and the numbers in docs/RESULTS.md depend on these exact samples.
    rng = np.random.default_rng(seed)
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    if len(F):
        area = face_areas(V, F)
        total = area.sum()
    else:
        total = 0.0
    if not total > 0:
        return V[rng.integers(len(V), size=n_points)]
    cdf = np.cumsum(area) / total
    tri = np.minimum(np.searchsorted(cdf, rng.random(n_points)), len(F) - 1)
    u, v = rng.random(n_points), rng.random(n_points)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    T = V[F[tri]]  # (n_points, 3, 3)
    return T[:, 0] + u[:, None] * (T[:, 1] - T[:, 0]) + v[:, None] * (T[:, 2] - T[:, 0])


def normalize_surface(P: np.ndarray) -> np.ndarray:
    """Centre surface samples at their mean and scale them to unit RMS radius.

    Returns
    -------
    Q : (N, 3) float64
    """
    Q = P - P.mean(axis=0)
    rms = float(np.sqrt((Q * Q).sum(axis=1).mean()))
    if not rms > 0:
        raise InvalidOptionError("the shape has zero extent; no descriptor can be computed")
    return Q / rms


@mesh_input
def shd_descriptor(V, F, *, n_shells: int = SHD_SHELLS, l_max: int = SHD_LMAX,
                   n_points: int = SHD_POINTS, radius: float = SHD_RADIUS,
                   seed: int = 0) -> np.ndarray:
    """Rotation-invariant spherical harmonics energies of a mesh's surface.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    n_shells : int
        Concentric shells between 0 and ``radius`` (RMS radii); farther points count in
        the outermost shell.
    l_max : int
        Highest frequency kept.
    n_points : int
        Surface samples.
    radius : float
        Outer shell radius, in RMS radii.
    seed : int
        Seed of the surface sampling.

    Returns
    -------
    shd : (n_shells * (l_max + 1),) float64
        Energy of frequency ``l`` on shell ``s`` at index ``s * (l_max + 1) + l``.

    Examples
    --------
    >>> import trimesh
    >>> m = trimesh.creation.box()
    >>> shd_descriptor(m.vertices, m.faces, n_shells=4, l_max=3).shape
    (16,)

    Notes
    -----
    Time O(n_points · l_max^2) (the harmonics at every sample), memory the same.
    """
    from scipy.special import sph_harm_y

    V, F = check_mesh(V, F, allow_no_faces=True)
    if n_shells < 1 or l_max < 0 or n_points < 1 or not radius > 0:
        raise InvalidOptionError(
            f"shd needs n_shells >= 1, l_max >= 0, n_points >= 1, radius > 0; got "
            f"{n_shells}, {l_max}, {n_points}, {radius}"
        )
    P = normalize_surface(surface_samples(V, F, n_points, seed))
    r = np.linalg.norm(P, axis=1)
    theta = np.arccos(np.clip(P[:, 2] / np.maximum(r, 1e-300), -1.0, 1.0))
    phi = np.arctan2(P[:, 1], P[:, 0])
    # Linear spreading of each point over the two nearest shell radii.
    x = np.clip(r / (radius / n_shells) - 0.5, 0.0, n_shells - 1.0)
    lo = np.floor(x).astype(np.int64)
    hi = np.minimum(lo + 1, n_shells - 1)
    w_hi = x - lo
    W = np.zeros((n_shells, len(P)))
    idx = np.arange(len(P))
    np.add.at(W, (lo, idx), 1.0 - w_hi)
    np.add.at(W, (hi, idx), w_hi)
    W /= len(P)
    out = np.zeros((n_shells, l_max + 1))
    for ell in range(l_max + 1):
        m = np.arange(ell + 1)
        Y = sph_harm_y(ell, m[:, None], theta[None, :], phi[None, :])  # (l+1, N)
        C = W @ np.conj(Y).T  # (n_shells, l+1): coefficients for m >= 0
        power = np.abs(C[:, 0]) ** 2 + 2.0 * (np.abs(C[:, 1:]) ** 2).sum(axis=1)
        out[:, ell] = np.sqrt(power)
    return out.ravel()
