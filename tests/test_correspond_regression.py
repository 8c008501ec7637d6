"""Seeded regression of ``correspond`` (default method) on a small stored pair.

``tests/data/correspond_quadruped500_input.npz`` holds ``V1``, ``V2``, ``F``: the two poses of
``generate_figure("quadruped", poses=2, seed=1, target_vertices=500, resolution=48)``
(500 vertices). The input is stored, not regenerated, because the generator's output moves
in the last bits between library versions (a fresh install on 2026-12-01 changed its bytes,
not the map). ``tests/data/correspond_quadruped500_p2p.npy`` holds the map ``p2p_12`` that
``correspond(V1, F, V2, F)`` returned (90.8 % of the vertices mapped exactly to themselves
when recorded). The pipeline is deterministic, so the test requires equality: any change
of the map is a change of behaviour to look at. It runs the whole default pipeline (~3 s),
so it is in the slow tier (``-m slow``, and the default run).

To regenerate the map after an intended change, run::

    GEOSHAPE_REGEN=1 python -m pytest tests/test_correspond_regression.py

then review the difference and commit the new file.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"
INPUT = DATA / "correspond_quadruped500_input.npz"
REFERENCE = DATA / "correspond_quadruped500_p2p.npy"


def regression_pair():
    with np.load(INPUT) as z:
        return z["V1"], z["V2"], z["F"]


def regenerate() -> np.ndarray:
    """Recompute the reference map and write it to :data:`REFERENCE`."""
    from geoshape.correspondence.mesh_matching import correspond

    V1, V2, F = regression_pair()
    p2p = correspond(V1, F, V2, F).p2p_12.astype(np.int64)
    np.save(REFERENCE, p2p)
    return p2p


@pytest.mark.slow
def test_default_correspond_reproduces_the_recorded_map():
    from geoshape.correspondence.mesh_matching import correspond

    V1, V2, F = regression_pair()
    if os.environ.get("GEOSHAPE_REGEN") == "1":
        regenerate()
    expected = np.load(REFERENCE)
    p2p = correspond(V1, F, V2, F).p2p_12
    assert p2p.shape == expected.shape == (500,)
    differ = np.flatnonzero(p2p != expected)
    assert differ.size == 0, (
        f"{differ.size} of {len(p2p)} vertices map elsewhere than recorded (first: {differ[:10].tolist()}); "
        "if intended, regenerate with GEOSHAPE_REGEN=1 (see the module docstring)"
    )
