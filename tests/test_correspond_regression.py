"""Seeded regression of ``correspond`` (default method) on a small generated pair.

``tests/data/correspond_quadruped500_p2p.npy`` holds the map ``p2p_12`` that
``correspond(V1, F, V2, F)`` returned for the two poses of
``generate_figure("quadruped", poses=2, seed=1, target_vertices=500, resolution=48)``
(500 vertices; 90.8 % of the vertices mapped exactly to themselves when recorded). The
pipeline is deterministic (same answer in two separate processes when recorded), so the
test requires equality: any change of the map is a change of behaviour to look at. It runs
the whole default pipeline (~3 s), so it is in the slow tier (``-m slow``, and the default run).

To regenerate after an intended change, run::

    GEOSHAPE_REGEN=1 python -m pytest tests/test_correspond_regression.py

which rewrites the array (and fails with a reminder to update ``INPUT_SHA256`` if the
generated input itself changed), then review the difference and commit the new file.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np
import pytest

REFERENCE = Path(__file__).parent / "data" / "correspond_quadruped500_p2p.npy"
#: first 16 hex digits of the SHA-256 of V1, V2 (float64) and F (int64) bytes when recorded
INPUT_SHA256 = "a05de4a656050da4"


def regression_pair():
    from geoshape_datasets_gen.articulated3d import generate_figure

    fig = generate_figure("quadruped", poses=2, seed=1, target_vertices=500, resolution=48)
    V1, V2 = (np.ascontiguousarray(p, dtype=np.float64) for p in fig.poses)
    F = np.ascontiguousarray(fig.F, dtype=np.int64)
    digest = hashlib.sha256(V1.tobytes() + V2.tobytes() + F.tobytes()).hexdigest()[:16]
    return V1, V2, F, digest


def regenerate() -> np.ndarray:
    """Recompute the reference map and write it to :data:`REFERENCE`."""
    from geoshape.correspondence.mesh_matching import correspond

    V1, V2, F, _ = regression_pair()
    p2p = correspond(V1, F, V2, F).p2p_12.astype(np.int64)
    REFERENCE.parent.mkdir(parents=True, exist_ok=True)
    np.save(REFERENCE, p2p)
    return p2p


@pytest.mark.slow
def test_default_correspond_reproduces_the_recorded_map():
    from geoshape.correspondence.mesh_matching import correspond

    V1, V2, F, digest = regression_pair()
    if os.environ.get("GEOSHAPE_REGEN") == "1":
        regenerate()
    assert digest == INPUT_SHA256, (
        f"the generated input pair changed (sha {digest}), not correspond: check datasets_gen, "
        "then set INPUT_SHA256 and regenerate with GEOSHAPE_REGEN=1"
    )
    expected = np.load(REFERENCE)
    p2p = correspond(V1, F, V2, F).p2p_12
    assert p2p.shape == expected.shape == (500,)
    differ = np.flatnonzero(p2p != expected)
    assert differ.size == 0, (
        f"{differ.size} of {len(p2p)} vertices map elsewhere than recorded (first: {differ[:10].tolist()}); "
        "if intended, regenerate with GEOSHAPE_REGEN=1 (see the module docstring)"
    )
