"""Descriptor functional maps with an orientation term (geoshape.correspondence.fmaps.descriptor_fmap)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from geoshape.correspondence.fmaps.descriptor_fmap import (
    _commutator_normal_matrix,
    descriptor_functional_map,
    descriptor_operators,
    orientation_operators,
    wave_kernel_signature,
)
from geoshape.correspondence.fmaps.zoomout import p2p_from_functional_map
from geoshape.correspondence.orientation import orientation_score
from geoshape.errors import InvalidOptionError
from geoshape.spectral.laplacian import laplacian_basis


@functools.cache
def biped():
    from geoshape_datasets_gen.articulated3d import generate_figure

    fig = generate_figure("biped", poses=1, seed=3, target_vertices=900, resolution=64)
    V, F = fig.poses[0], fig.F
    return V, F, laplacian_basis(V, F, 40)


def test_normal_matrix_equals_the_explicit_kronecker_form(rng):
    k = 4
    X, Y = rng.standard_normal((3, k, k)), rng.standard_normal((3, k, k))
    eye = np.eye(k)
    # residual vec(C X - Y C) = (Xᵀ ⊗ I - I ⊗ Y) vec(C), column-major vec
    explicit = sum((np.kron(x.T, eye) - np.kron(eye, y)).T @ (np.kron(x.T, eye) - np.kron(eye, y))
                   for x, y in zip(X, Y, strict=True))
    assert np.allclose(_commutator_normal_matrix(X, Y), explicit)
    C = rng.standard_normal((k, k))
    residual = sum(np.sum((C @ x - y @ C) ** 2) for x, y in zip(X, Y, strict=True))
    v = C.reshape(-1, order="F")
    assert v @ _commutator_normal_matrix(X, Y) @ v == pytest.approx(residual)


def test_wave_kernel_signatures_are_positive_and_unit_norm():
    _, _, basis = biped()
    wks = wave_kernel_signature(basis, 20)
    assert wks.shape == (len(basis.mass), 20)
    assert (wks >= 0).all()
    assert np.allclose(basis.mass @ wks**2, 1.0)


def test_orientation_operators_change_sign_under_reflection():
    V, F, basis = biped()
    D = wave_kernel_signature(basis, 12)
    O = orientation_operators(V, F, basis, D, 10)
    assert np.abs(O).max() > 0
    mirrored = laplacian_basis(V * [-1, 1, 1], F[:, ::-1], 40)
    assert np.allclose(mirrored.evals, basis.evals)
    O_mirror = orientation_operators(V * [-1, 1, 1], F[:, ::-1], mirrored,
                                     wave_kernel_signature(mirrored, 12), 10)
    # same eigenvectors up to sign: compare magnitudes entry by entry, and the sign of a
    # basis-independent quantity, the trace of O_d applied through both bases' overlap
    S = np.sign(np.einsum("ni,ni->i", basis.evecs[:, :10] * basis.mass[:, None], mirrored.evecs[:, :10]))
    assert np.allclose(O_mirror, -(S[:, None] * O * S[None, :]), atol=1e-4 * np.abs(O).max())


def test_a_mesh_matched_to_itself_gives_the_identity_functional_map():
    V, F, basis = biped()
    ops = descriptor_operators(V, F, basis, k=20)
    C = descriptor_functional_map(ops, ops)
    assert np.allclose(C, np.eye(20), atol=1e-6)


def test_the_orientation_term_chooses_between_a_map_and_its_mirror():
    """A left-right symmetric figure matched to itself: "preserving" gives the identity,
    "reversing" gives the left-right symmetry (orientation-reversing)."""
    V, F, basis = biped()
    ops = descriptor_operators(V, F, basis, k=20)
    direct = p2p_from_functional_map(basis, basis, descriptor_functional_map(ops, ops))
    mirror = p2p_from_functional_map(basis, basis,
                                     descriptor_functional_map(ops, ops, orientation="reversing"))
    assert orientation_score(V, F, V, F, direct) > 0.9
    assert orientation_score(V, F, V, F, mirror) < -0.3
    reflected = V * [-1, 1, 1]  # where each vertex's mirror image should land
    assert np.median(np.linalg.norm(V[mirror] - reflected, axis=1)) < 0.1 * np.ptp(V, axis=0).max()


def test_bad_options_are_reported():
    V, F, basis = biped()
    ops = descriptor_operators(V, F, basis, k=10)
    with pytest.raises(InvalidOptionError, match="orientation"):
        descriptor_functional_map(ops, ops, orientation="sideways")
    with pytest.raises(InvalidOptionError, match="differ in size"):
        descriptor_functional_map(ops, descriptor_operators(V, F, basis, k=12))
    with pytest.raises(InvalidOptionError, match="eigenpairs"):
        descriptor_operators(V, F, basis, k=41)


def test_a_sphere_has_free_directions_but_still_gets_a_map():
    """Constant descriptors and degenerate eigenspaces leave the energy flat along many
    directions; the ridge keeps the solve definite instead of failing."""
    from conftest import icosphere

    V, F = icosphere(1)
    basis = laplacian_basis(V, F, 41)
    ops = descriptor_operators(V, F, basis, k=30)
    C = descriptor_functional_map(ops, ops)
    assert np.isfinite(C).all()
    assert C[0, 0] == pytest.approx(1.0, abs=1e-3)  # constants map to constants
