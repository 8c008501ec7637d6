"""3-D shape context: the thesis' "trivial 3-D extension" of Belongie et al. (baseline).

For every vertex, a histogram of ``n_ref`` reference points (farthest-point samples) in
log-polar bins around it: ``n_r`` log-spaced radii (normalised by the mean pairwise
distance) × ``n_azimuth`` × ``n_elevation`` angles, in the frame of the shape's
principal axes (the thesis aligned shapes by hand; principal axes play that role here,
with the sign ambiguity resolved by third moments). Histograms are L1-normalised and
compared with the Hellinger distance (Euclidean on square roots, a close cousin of χ²
that admits fast nearest-neighbour search). Not invariant to bending — that is the
point of the comparison. Time O(n n_ref) for descriptors, O(n1 n2 b) for matching with
b bins.
"""

from __future__ import annotations

import numpy as np

from geoshape.geometry.knn import nearest
from geoshape.geometry.sampling import euclidean_farthest_point_sampling


def principal_frame(X: np.ndarray) -> np.ndarray:
    """Centre and rotate ``X (n, 3)`` into its principal axes, signs fixed by skewness."""
    Xc = X - X.mean(0)
    _, _, Vt = np.linalg.svd(Xc, full_matrices=False)
    Y = Xc @ Vt.T
    skew = np.sign((Y**3).sum(0))
    skew[skew == 0] = 1.0
    Y = Y * skew
    if np.linalg.det(Vt.T * skew) < 0:  # keep a proper rotation: flip the weakest axis
        Y[:, 2] = -Y[:, 2]
    return Y


def shape_context_3d(X: np.ndarray, *, n_ref: int = 300, n_r: int = 5, n_azimuth: int = 12,
                     n_elevation: int = 6, seed: int = 0) -> np.ndarray:
    """(n, n_r · n_azimuth · n_elevation) L1-normalised histograms for the points ``X``."""
    Y = principal_frame(np.asarray(X, dtype=np.float64))
    ref = Y[euclidean_farthest_point_sampling(Y, n_ref, seed)]
    D = Y[:, None, :] - ref[None, :, :]  # (n, r, 3)
    r = np.linalg.norm(D, axis=2)
    mean_r = r.mean()
    edges = np.logspace(np.log10(0.125), np.log10(2.0), n_r + 1) * mean_r
    rbin = np.clip(np.searchsorted(edges, r) - 1, -1, n_r - 1)
    azimuth = np.arctan2(D[..., 1], D[..., 0]) + np.pi
    az = np.floor(azimuth / (2 * np.pi) * n_azimuth).astype(int) % n_azimuth
    el = np.clip(np.floor(np.arccos(np.clip(D[..., 2] / np.maximum(r, 1e-300), -1, 1)) / np.pi * n_elevation),
                 0, n_elevation - 1).astype(int)
    valid = (rbin >= 0) & (r > 0)
    bins = (rbin * n_azimuth + az) * n_elevation + el
    n_bins = n_r * n_azimuth * n_elevation
    H = np.zeros((len(Y), n_bins))
    rows = np.repeat(np.arange(len(Y)), r.shape[1]).reshape(r.shape)
    np.add.at(H, (rows[valid], bins[valid]), 1.0)
    return H / np.maximum(H.sum(1, keepdims=True), 1.0)


def match_shape_context_3d(X1, X2, **options) -> tuple[np.ndarray, float]:
    """Nearest-descriptor map from point set 1 to point set 2 and its total Hellinger cost."""
    H1 = np.sqrt(shape_context_3d(X1, **options))
    H2 = np.sqrt(shape_context_3d(X2, **options))
    d, p2p = nearest(H2, H1)
    return p2p, float(d.sum())
