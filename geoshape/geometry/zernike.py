"""Zernike radial polynomials, the one home of their formula (2D region moments of contours,
silhouette features of the light-field descriptor)."""

from __future__ import annotations

from math import factorial

import numpy as np

__all__ = ["zernike_indices", "zernike_radial"]


def zernike_indices(order: int, first: int = 0) -> list[tuple[int, int]]:
    """The ``(n, m)`` of the Zernike polynomials with ``first ≤ n ≤ order``, ``0 ≤ m ≤ n``,
    ``n − m`` even, in the usual order.

    >>> zernike_indices(3)
    [(0, 0), (1, 1), (2, 0), (2, 2), (3, 1), (3, 3)]
    """
    return [(n, m) for n in range(first, order + 1) for m in range(n % 2, n + 1, 2)]


def zernike_radial(rho: np.ndarray, n: int, m: int) -> np.ndarray:
    """The radial polynomial ``R_nm(ρ)`` (``n − m`` even, ``0 ≤ m ≤ n``) at radii ``rho``; O(n · len(rho)).

    >>> zernike_radial(np.array([0.0, 0.5, 1.0]), 2, 0).tolist()  # 2ρ² − 1
    [-1.0, -0.5, 1.0]
    """
    R = np.zeros_like(rho, dtype=np.float64)
    for s in range((n - m) // 2 + 1):
        coef = ((-1) ** s * factorial(n - s)
                / (factorial(s) * factorial((n + m) // 2 - s) * factorial((n - m) // 2 - s)))
        R += coef * rho ** (n - 2 * s)
    return R
