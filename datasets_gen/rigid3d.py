"""Procedural rigid objects as unions of simple closed parts (trimesh primitives and sweeps).

Each class builder draws its proportions and optional details from a seeded generator and
returns the object as a list of closed, outward-oriented parts that overlap where they join
(a chair's legs enter its seat, a cup's handle enters its wall). Frame: ``+y`` is up, the
object is roughly 1-2 units large; callers normalise scale and pose.

Parts are surfaces of revolution (:func:`revolve`, trimesh's ``revolve`` with ``y`` as the
axis), tubes swept along a polyline (:func:`tube`), prisms over a 2-D outline with an
optional bore (:func:`prism`), boxes, cylinders and spheres. :func:`build_rigid` gives the
parts and the radius of the thinnest feature, so a caller can fuse them
(:func:`geoshape_datasets_gen.union3d.fuse_parts`) or keep them as separate components.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from geoshape._options import check_choice
from geoshape.geometry.mesh import signed_volume

__all__ = ["RIGID_CLASSES", "Parts", "build_rigid", "revolve", "tube", "prism", "box", "cylinder", "sphere"]

RIGID_CLASSES = ("cup", "vase", "bottle", "chair", "table", "spring", "gear", "bearing", "airplane",
                 "glasses")

# rotation taking trimesh's revolution axis (z) to +y
_Z_TO_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


class Parts(NamedTuple):
    """A rigid object as overlapping closed parts.

    Attributes
    ----------
    parts : list of (V (n_i, 3) float64, F (m_i, 3) int64)
        Closed, outward-oriented surfaces.
    min_feature : float
        Radius (half thickness) of the thinnest feature, in the object's units.
    """

    parts: list
    min_feature: float


# --------------------------------------------------------------------------- primitives


def _outward(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    return V, (F if signed_volume(V, F) >= 0 else F[:, ::-1].copy())


def _transform(V: np.ndarray, R=None, t=(0.0, 0.0, 0.0)) -> np.ndarray:
    return (V if R is None else V @ np.asarray(R).T) + np.asarray(t, dtype=np.float64)


def rotation(axis, angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` radians about ``axis`` (right-handed)."""
    a = np.asarray(axis, dtype=np.float64)
    x, y, z = a / np.linalg.norm(a)
    c, s = math.cos(angle), math.sin(angle)
    C = 1.0 - c
    return np.array([[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
                     [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
                     [z * x * C - y * s, z * y * C + x * s, c + z * z * C]])


def revolve(profile, *, sections: int = 64, R=None, t=(0.0, 0.0, 0.0)):
    """Surface of revolution of a ``(K, 2)`` profile of ``(radius, height)`` points about ``+y``.

    A profile that starts and ends on the axis (radius 0) gives a closed solid; a closed
    polygon off the axis (first point repeated last) gives a ring. ``R``, ``t`` place it.

    Returns
    -------
    (V (n, 3) float64, F (m, 3) int64), closed and outward oriented.
    """
    import trimesh

    m = trimesh.creation.revolve(np.asarray(profile, dtype=np.float64), sections=int(sections))
    return _outward(_transform(np.asarray(m.vertices) @ _Z_TO_Y.T, R, t), m.faces)


def box(extents, *, R=None, t=(0.0, 0.0, 0.0)):
    """Axis-aligned box of ``extents`` (3,) centred at the origin, then rotated by ``R`` and
    moved by ``t``. Returns ``(V (8, 3), F (12, 3))``."""
    import trimesh

    m = trimesh.creation.box(extents=np.asarray(extents, dtype=np.float64))
    return _outward(_transform(np.asarray(m.vertices), R, t), m.faces)


def cylinder(p0, p1, radius: float, *, sections: int = 32):
    """Closed cylinder of ``radius`` from point ``p0`` to ``p1`` (each (3,))."""
    import trimesh

    m = trimesh.creation.cylinder(radius=float(radius), segment=np.array([p0, p1], dtype=np.float64),
                                  sections=int(sections))
    return _outward(m.vertices, m.faces)


def sphere(center, radius: float, *, subdivisions: int = 3):
    """Icosphere of ``radius`` at ``center`` (3,)."""
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=int(subdivisions), radius=float(radius))
    return _outward(np.asarray(m.vertices) + np.asarray(center, dtype=np.float64), m.faces)


def tube(path, radius, *, closed: bool = False, sections: int = 16):
    """Tube of circular section swept along a polyline.

    Parameters
    ----------
    path : (K, 3) array_like
        Centre line (K >= 2), sampled finely enough for the bends.
    radius : float or (K,) array_like
        Tube radius, constant or per path point (tapered tubes).
    closed : bool
        The path is a loop (no caps; the last point joins the first).
    sections : int
        Points around the section.

    Returns
    -------
    (V (K * sections [+ 2], 3) float64, F (m, 3) int64)
        Closed, outward oriented (open paths get flat caps).

    Notes
    -----
    The section frame is parallel-transported along the path (no twist on planar paths).
    """
    P = np.asarray(path, dtype=np.float64)
    K, S = len(P), int(sections)
    r = np.broadcast_to(np.asarray(radius, dtype=np.float64), (K,))
    if closed:
        T = np.roll(P, -1, axis=0) - np.roll(P, 1, axis=0)
    else:
        T = np.gradient(P, axis=0)
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    N = np.empty_like(P)
    ref = np.eye(3)[np.argmin(np.abs(T[0]))]
    n = np.cross(T[0], ref)
    for k in range(K):
        n = n - (n @ T[k]) * T[k]
        n /= np.linalg.norm(n)
        N[k] = n
    B = np.cross(T, N)
    ang = 2 * np.pi * np.arange(S) / S
    ring = P[:, None] + r[:, None, None] * (np.cos(ang)[None, :, None] * N[:, None]
                                            + np.sin(ang)[None, :, None] * B[:, None])
    V = ring.reshape(-1, 3)
    idx = np.arange(K * S).reshape(K, S)
    rows = K if closed else K - 1
    a = idx[:rows]
    b = idx[(np.arange(rows) + 1) % K]
    a1, b1 = np.roll(a, -1, axis=1), np.roll(b, -1, axis=1)
    F = np.concatenate([np.stack([a, b, b1], -1).reshape(-1, 3), np.stack([a, b1, a1], -1).reshape(-1, 3)])
    if not closed:
        c0, c1 = K * S, K * S + 1
        V = np.concatenate([V, P[[0, -1]]])
        first, last = idx[0], idx[-1]
        F = np.concatenate([F,
                            np.column_stack([np.full(S, c0), first, np.roll(first, -1)]),
                            np.column_stack([np.full(S, c1), np.roll(last, -1), last])])
    return _outward(V, F)


def prism(outline, y0: float, y1: float, *, inner=None, R=None, t=(0.0, 0.0, 0.0)):
    """Prism over a closed 2-D outline in the ``x-z`` plane, from height ``y0`` to ``y1``.

    Parameters
    ----------
    outline : (K, 2) array_like
        ``(x, z)`` points of a loop that is star-shaped about its mean point (not repeated).
    y0, y1 : float
        Bottom and top heights.
    inner : (K, 2) array_like, optional
        A bore: an inner loop with the same point count, inside ``outline`` (gives a ring).
    R, t
        Rotation and translation applied after building.

    Returns
    -------
    (V (n, 3) float64, F (m, 3) int64), closed and outward oriented.
    """
    O = np.asarray(outline, dtype=np.float64)
    K = len(O)
    inner_pts = O.mean(axis=0)[None] if inner is None else np.asarray(inner, dtype=np.float64)
    L = len(inner_pts)

    def lift(Q, y):
        return np.column_stack([Q[:, 0], np.full(len(Q), y), Q[:, 1]])

    V = np.concatenate([lift(O, y0), lift(O, y1), lift(inner_pts, y0), lift(inner_pts, y1)])
    ob, ot, ib, it = 0, K, 2 * K, 2 * K + L
    k = np.arange(K)
    k1 = (k + 1) % K
    # outer wall, then top and bottom (fan to the centre or strip to the bore)
    F = [np.column_stack([ob + k, ot + k1, ot + k]), np.column_stack([ob + k, ob + k1, ot + k1])]
    if inner is None:
        F += [np.column_stack([ot + k, ot + k1, np.full(K, it)]),
              np.column_stack([ob + k1, ob + k, np.full(K, ib)])]
    else:
        F += [np.column_stack([ot + k, ot + k1, it + k1]), np.column_stack([ot + k, it + k1, it + k]),
              np.column_stack([ob + k1, ob + k, ib + k]), np.column_stack([ob + k1, ib + k, ib + k1]),
              np.column_stack([ib + k, it + k, it + k1]), np.column_stack([ib + k, it + k1, ib + k1])]
    return _outward(_transform(V, R, t), np.concatenate(F))


def _arc(center, u, v, a, b, t0: float, t1: float, n: int) -> np.ndarray:
    """(n, 3) points ``center + a cos(t) u + b sin(t) v`` for t in [t0, t1]."""
    t = np.linspace(t0, t1, n)
    return (np.asarray(center, dtype=np.float64)[None] + a * np.cos(t)[:, None] * np.asarray(u)
            + b * np.sin(t)[:, None] * np.asarray(v))


def _superellipse(a: float, b: float, p: float, n: int) -> np.ndarray:
    """(n, 2) points of ``|x/a|^p + |y/b|^p = 1`` (p = 2 ellipse, larger = squarer)."""
    t = 2 * np.pi * np.arange(n) / n
    c, s = np.cos(t), np.sin(t)
    return np.column_stack([a * np.sign(c) * np.abs(c) ** (2 / p), b * np.sign(s) * np.abs(s) ** (2 / p)])


_X, _Y, _Z = np.eye(3)


# --------------------------------------------------------------------------- classes


def _cup(rng: np.random.Generator) -> Parts:
    H = rng.uniform(0.6, 1.1)
    Rt = rng.uniform(0.3, 0.5)
    Rb = Rt * rng.uniform(0.55, 1.0)
    bulge = rng.uniform(-0.04, 0.08)
    wall, base = rng.uniform(0.045, 0.075), rng.uniform(0.05, 0.1)

    def ro(y):
        return Rb + (Rt - Rb) * y / H + bulge * np.sin(np.pi * y / H)

    ys = np.linspace(0, H, 24)
    yi = np.linspace(H, base, 20)
    fillet = min(0.03, 0.3 * Rb)
    profile = np.concatenate([[[0, 0], [Rb - fillet, 0]], np.column_stack([ro(ys), ys])[1:],
                              np.column_stack([ro(yi) - wall, yi]), [[0, base]]])
    profile[len(ys) + 1, 1] += fillet  # round the bottom edge a little
    parts = [revolve(profile)]
    # handle: a C-shaped (or squarish) tube following the side, its ends buried in the wall
    yc = H * rng.uniform(0.45, 0.58)
    B = min(yc - 0.12 * H, H - yc - 0.1 * H) * rng.uniform(0.7, 1.0)
    A = rng.uniform(0.12, 0.28)
    p = rng.uniform(2.0, 4.0)
    t = np.linspace(-np.pi / 2, np.pi / 2, 40)
    y = yc + B * np.sign(np.sin(t)) * np.abs(np.sin(t)) ** (2 / p)
    x = ro(y) - wall / 2 + A * np.abs(np.cos(t)) ** (2 / p)
    handle_r = rng.uniform(0.03, 0.05)
    parts.append(tube(np.column_stack([x, y, np.zeros_like(x)]), handle_r))
    if rng.random() < 0.25:  # saucer
        Rs = Rb * rng.uniform(1.5, 2.0)
        parts.append(revolve([[0, -0.035], [Rs * 0.9, -0.03], [Rs, 0.02], [Rs * 0.97, 0.03],
                              [Rs * 0.6, 0.0], [0, 0.005]]))
    return Parts(parts, min(wall / 2, handle_r))


def _vase(rng: np.random.Generator) -> Parts:
    from scipy.interpolate import PchipInterpolator

    H = rng.uniform(1.0, 1.8)
    n = int(rng.integers(4, 7))
    yk = np.linspace(0, H, n)
    rk = rng.uniform(0.14, 0.45, n)
    rk[0] = rng.uniform(0.14, 0.3)
    rk[-1] = rng.uniform(0.1, 0.28) * rng.choice([1.0, 1.3])
    r = PchipInterpolator(yk, rk)
    wall = rng.uniform(0.04, 0.065)
    depth = H * rng.uniform(0.15, 0.5)
    ys = np.linspace(0, H, 48)
    yi = np.linspace(H, H - depth, 16)
    profile = np.concatenate([[[0, 0]], np.column_stack([r(ys), ys]),
                              np.column_stack([np.maximum(r(yi) - wall, 0.03), yi]), [[0, H - depth]]])
    parts = [revolve(profile)]
    if rng.random() < 0.3:  # amphora handles from the neck to the shoulder
        y0, y1 = H * rng.uniform(0.55, 0.7), H * rng.uniform(0.8, 0.92)
        hr = rng.uniform(0.025, 0.04)
        for s in (1.0, -1.0):
            t = np.linspace(-np.pi / 2, np.pi / 2, 30)
            y = (y0 + y1) / 2 + (y1 - y0) / 2 * np.sin(t)
            x = s * (r(y) - wall / 2 + rng.uniform(0.1, 0.18) * np.cos(t))
            parts.append(tube(np.column_stack([x, y, np.zeros_like(x)]), hr))
    return Parts(parts, wall / 2)


def _bottle(rng: np.random.Generator) -> Parts:
    R = rng.uniform(0.16, 0.3)
    Hb = rng.uniform(0.5, 1.0)
    Hs = rng.uniform(0.08, 0.35)
    Rn = R * rng.uniform(0.25, 0.45)
    Hn = rng.uniform(0.15, 0.45)
    waist = rng.uniform(-0.05, 0.12)
    yb = np.linspace(0.02, Hb, 16)
    body = R * (1 - waist * np.sin(np.pi * yb / Hb))
    u = np.linspace(0, 1, 16)[1:]
    shoulder = Rn + (R - Rn) * (0.5 + 0.5 * np.cos(np.pi * u))
    top = Hb + Hs + Hn
    lip = Rn * rng.uniform(1.1, 1.25)
    prof = [[0, 0], [R * 0.9, 0], *np.column_stack([body, yb]), *np.column_stack([shoulder, Hb + Hs * u]),
            [Rn, top - 0.04], [lip, top - 0.035], [lip, top - 0.01], [Rn * 0.95, top]]
    if rng.random() < 0.5:  # open mouth
        prof += [[Rn * 0.7, top], [Rn * 0.7, top - 0.1], [0, top - 0.1]]
    else:
        prof += [[0, top]]
    parts = [revolve(prof)]
    if rng.random() < 0.35:  # cap
        hc = rng.uniform(0.05, 0.12)
        parts.append(cylinder((0, top - 0.03, 0), (0, top + hc, 0), lip * 1.05, sections=48))
    return Parts(parts, Rn * 0.3)


def _leg(rng_square: bool, p0, p1, s: float):
    """A chair/table leg from ``p0`` to ``p1``: square section of side ``2 s`` or round of radius ``s``."""
    if not rng_square:
        return cylinder(p0, p1, s)
    p0, p1 = np.asarray(p0, dtype=np.float64), np.asarray(p1, dtype=np.float64)
    d = p1 - p0
    L = float(np.linalg.norm(d))
    axis = np.cross(_Y, d / L)
    ang = math.asin(min(1.0, float(np.linalg.norm(axis))))
    Rm = rotation(axis, ang) if ang > 1e-9 else np.eye(3)
    return box((2 * s, L, 2 * s), R=Rm, t=(p0 + p1) / 2)


def _chair(rng: np.random.Generator) -> Parts:
    w, d, th = rng.uniform(0.8, 1.1), rng.uniform(0.75, 1.05), rng.uniform(0.05, 0.12)
    hs = rng.uniform(0.75, 1.0)
    parts = [box((w, th, d), t=(0, hs, 0))]
    s = rng.uniform(0.035, 0.07)
    square = rng.random() < 0.5
    thin = min(th / 2, s)
    if rng.random() < 0.2:  # swivel chair: column, five-star base, casters
        parts.append(cylinder((0, 0.12, 0), (0, hs, 0), rng.uniform(0.04, 0.07)))
        arm_len = rng.uniform(0.35, 0.5)
        for k in range(5):
            a = 2 * np.pi * k / 5
            dvec = np.array([math.cos(a), 0.0, math.sin(a)])
            parts.append(_leg(True, (0, 0.12, 0), dvec * arm_len + (0, 0.06, 0), 0.035))
            parts.append(sphere(dvec * arm_len + (0, 0.04, 0), 0.045, subdivisions=2))
    else:
        splay = rng.uniform(0.0, 0.08)
        inset = rng.uniform(0.02, 0.08)
        corners = [(sx * (w / 2 - inset - s), sz * (d / 2 - inset - s)) for sx in (1, -1) for sz in (1, -1)]
        for cx, cz in corners:
            top = (cx, hs, cz)
            foot = (cx * (1 + splay), 0.0, cz * (1 + splay))
            parts.append(_leg(square, top, foot, s))
        if rng.random() < 0.4:  # stretchers between the legs
            yst = hs * rng.uniform(0.2, 0.4)
            for (ax, az), (bx, bz) in ((corners[0], corners[1]), (corners[2], corners[3]),
                                       (corners[0], corners[2])):
                f = 1 + splay * (1 - yst / hs)
                parts.append(cylinder((ax * f, yst, az * f), (bx * f, yst, bz * f), s * 0.6))
            thin = min(thin, s * 0.6)
    # back: a panel, two posts with rails, or two posts with slats; tilted back
    hb = rng.uniform(0.55, 0.95)
    tilt = rng.uniform(0.0, 0.25)
    Rt = rotation(_X, -tilt)
    base = np.array([0.0, hs + th / 2, -d / 2 + 0.04])
    style = rng.integers(3)
    bt = rng.uniform(0.04, 0.08)
    if style == 0:
        parts.append(box((w * rng.uniform(0.85, 1.0), hb, bt), R=Rt, t=base + Rt @ (0, hb / 2, 0)))
    else:
        post = rng.uniform(0.03, 0.05)
        for sx in (1, -1):
            parts.append(box((2 * post, hb + th, 2 * post), R=Rt,
                             t=base + Rt @ (sx * (w / 2 - post), hb / 2 - th / 2, 0)))
        if style == 1:
            for y in np.linspace(0.35, 0.92, int(rng.integers(2, 5))) * hb:
                parts.append(box((w - 2 * post, rng.uniform(0.05, 0.1), bt * 0.7), R=Rt,
                                 t=base + Rt @ (0, y, 0)))
        else:
            nsl = int(rng.integers(3, 7))
            parts.append(box((w - 2 * post, 0.08, bt * 0.7), R=Rt, t=base + Rt @ (0, hb - 0.04, 0)))
            for x in np.linspace(-1, 1, nsl + 2)[1:-1] * (w / 2 - post):
                parts.append(box((0.04, hb, bt * 0.5), R=Rt, t=base + Rt @ (x, hb / 2, 0)))
        thin = min(thin, bt * 0.25)
    if rng.random() < 0.3:  # arm rests on posts
        ha = rng.uniform(0.2, 0.3)
        for sx in (1, -1):
            x = sx * (w / 2 - 0.03)
            parts.append(box((0.06, 0.04, d * 0.85), t=(x, hs + ha, -0.05)))
            parts.append(cylinder((x, hs, d * 0.3), (x, hs + ha, d * 0.3), 0.025))
        thin = min(thin, 0.02)
    return Parts(parts, thin)


def _table(rng: np.random.Generator) -> Parts:
    ht = rng.uniform(0.65, 0.9)
    th = rng.uniform(0.04, 0.1)
    round_top = rng.random() < 0.35
    if round_top:
        rad = rng.uniform(0.5, 0.85)
        parts = [cylinder((0, ht - th, 0), (0, ht, 0), rad, sections=64)]
        w = d = 2 * rad * 0.7
    else:
        w, d = rng.uniform(1.1, 2.0), rng.uniform(0.6, 1.1)
        parts = [box((w, th, d), t=(0, ht - th / 2, 0))]
    thin = th / 2
    if rng.random() < (0.6 if round_top else 0.2):  # pedestal
        col = rng.uniform(0.05, 0.12)
        ys = np.linspace(0.05, ht - th, 12)
        wave = col * (1 + rng.uniform(0, 0.6) * np.sin(np.pi * ys / ht) ** 2)
        parts.append(revolve(np.concatenate([[[0, 0.04]], np.column_stack([wave, ys]), [[0, ht - th / 2]]])))
        if rng.random() < 0.5:
            rb = rng.uniform(0.3, 0.5)
            parts.append(revolve([[0, 0], [rb, 0], [rb * 0.95, 0.03], [col * 1.5, 0.07], [0, 0.08]]))
        else:
            nf = int(rng.integers(3, 5))
            for k in range(nf):
                a = 2 * np.pi * k / nf
                parts.append(_leg(True, (0, 0.05, 0), (math.cos(a) * 0.4, 0.03, math.sin(a) * 0.4), 0.035))
        thin = min(thin, 0.03)
    else:
        s = rng.uniform(0.03, 0.07)
        square = rng.random() < 0.5
        inset = rng.uniform(0.03, 0.12)
        taper = rng.random() < 0.3
        for sx in (1, -1):
            for sz in (1, -1):
                cx, cz = sx * (w / 2 - inset - s), sz * (d / 2 - inset - s)
                if taper and not square:
                    ys = np.linspace(0, ht - th / 2, 8)
                    parts.append(tube(np.column_stack([np.full(8, cx), ys, np.full(8, cz)]),
                                      s * np.linspace(0.55, 1.0, 8), sections=24))
                else:
                    parts.append(_leg(square, (cx, ht - th / 2, cz), (cx, 0, cz), s))
        thin = min(thin, s * (0.55 if taper else 1.0))
        if rng.random() < 0.4:  # apron
            ah = rng.uniform(0.06, 0.12)
            for sz in (1, -1):
                parts.append(box((w - 2 * inset - 2 * s, ah, 0.03),
                                 t=(0, ht - th - ah / 2 + 0.01, sz * (d / 2 - inset - s))))
            thin = min(thin, 0.015)
        if rng.random() < 0.2:  # lower shelf
            parts.append(box((w - 2 * inset, 0.03, d - 2 * inset), t=(0, ht * 0.25, 0)))
            thin = min(thin, 0.015)
    return Parts(parts, thin)


def _spring(rng: np.random.Generator) -> Parts:
    R = rng.uniform(0.2, 0.35)
    rw = rng.uniform(0.025, 0.05)
    turns = rng.uniform(4.0, 10.0)
    pitch = rng.uniform(3.0, 6.0) * rw
    ends = rng.choice(["closed", "hooks", "plain"])
    K = int(turns * 48)
    t = np.linspace(0, turns, K)
    if ends == "closed":  # last 3/4 turn at each end squeezed to touch the next coil
        e = 0.75
        dpitch = np.where(t < e, 2.05 * rw, np.where(t > turns - e, 2.05 * rw, pitch))
        y = np.concatenate([[0], np.cumsum(dpitch[1:] * np.diff(t))])
    else:
        y = pitch * t
    a = 2 * np.pi * t
    path = np.column_stack([R * np.cos(a), y, R * np.sin(a)])
    parts = [tube(path, rw, sections=12)]
    if ends == "hooks":  # half loops over each end, spanning the coil's diameter
        for end, up in ((path[-1], 1.0), (path[0], -1.0)):
            dvec = np.array([end[0], 0.0, end[2]]) / R
            c = np.array([0.0, end[1], 0.0])
            loop = _arc(c, dvec, up * _Y, R, R * rng.uniform(0.8, 1.2), 0.0, np.pi, 40)
            parts.append(tube(loop, rw, sections=12))
    return Parts(parts, rw)


def _gear_outline(rng, n_teeth: int, R: float, depth: float, samples_per_tooth: int = 16) -> np.ndarray:
    K = n_teeth * samples_per_tooth
    th = 2 * np.pi * np.arange(K) / K
    phase = (th * n_teeth / (2 * np.pi)) % 1.0
    duty = rng.uniform(0.35, 0.5)
    # trapezoidal teeth: rise, flat top, fall
    top = np.clip((duty - np.abs(phase - 0.5)) / 0.12 + 0.5, 0.0, 1.0)
    r = R - depth + depth * top
    return np.column_stack([r * np.cos(th), r * np.sin(th)])


def _gear(rng: np.random.Generator) -> Parts:
    n = int(rng.integers(10, 29))
    R = rng.uniform(0.4, 0.6)
    depth = rng.uniform(0.05, 0.11)
    th = rng.uniform(0.08, 0.3)
    bore = rng.uniform(0.06, 0.16)
    K = n * 16
    ang = 2 * np.pi * np.arange(K) / K
    circ = np.column_stack([np.cos(ang), np.sin(ang)])
    parts = [prism(_gear_outline(rng, n, R, depth), -th / 2, th / 2, inner=bore * circ)]
    thin = min(th / 2, depth / 2)
    if rng.random() < 0.5:  # hub boss
        hb = rng.uniform(bore + 0.05, max(bore + 0.06, 0.75 * (R - depth)))
        hh = rng.uniform(0.08, 0.25)
        parts.append(prism(hb * circ, th / 2 - 0.01, th / 2 + hh, inner=1.03 * bore * circ))
    if rng.random() < 0.3:  # compound gear: a smaller gear on the same shaft
        n2 = int(rng.integers(8, max(9, n // 2 + 1)))
        R2 = R * rng.uniform(0.45, 0.65)
        K2 = n2 * 16
        a2 = 2 * np.pi * np.arange(K2) / K2
        c2 = np.column_stack([np.cos(a2), np.sin(a2)])
        th2 = rng.uniform(0.08, 0.2)
        parts.append(prism(_gear_outline(rng, n2, R2, depth * 0.8), -th / 2 - th2, -th / 2 + 0.01,
                           inner=1.03 * bore * c2))
    return Parts(parts, thin)


def _bearing(rng: np.random.Generator) -> Parts:
    ri_in = rng.uniform(0.1, 0.25)
    ring_w = rng.uniform(0.06, 0.12)
    gap = rng.uniform(0.08, 0.18)
    ro_in = ri_in + ring_w + gap
    ro_out = ro_in + ring_w * rng.uniform(0.8, 1.3)
    hw = rng.uniform(0.06, 0.14) + gap / 2  # half width (along the axis)
    groove = gap * 0.25

    def ring(r0, r1, groove_side):
        n = 9
        yy = np.linspace(-hw * 0.5, hw * 0.5, n)
        bump = groove * np.cos(np.linspace(-np.pi / 2, np.pi / 2, n))
        if groove_side > 0:  # groove on the outer face of the inner ring
            side = np.column_stack([r1 - bump, yy])
            prof = [[r0, -hw], [r1, -hw], *side, [r1, hw], [r0, hw], [r0, -hw]]
        else:
            side = np.column_stack([r0 + bump, yy])[::-1]
            prof = [[r0, -hw], [r1, -hw], [r1, hw], [r0, hw], *side, [r0, -hw]]
        return revolve(prof, sections=72)

    parts = [ring(ri_in, ri_in + ring_w, 1), ring(ro_in, ro_out, -1)]
    rm = ri_in + ring_w + gap / 2
    rb = gap / 2 + groove * 1.15  # balls sink into both grooves, past their bottoms
    nb = int(np.floor(2 * np.pi * rm / (2 * rb * rng.uniform(1.1, 1.6))))
    a0 = rng.uniform(0, 2 * np.pi)
    for k in range(nb):
        a = a0 + 2 * np.pi * k / nb
        parts.append(sphere((rm * math.cos(a), 0.0, rm * math.sin(a)), rb))
    if rng.random() < 0.3:  # shields covering the balls on one or both sides
        for s in ((1.0, -1.0) if rng.random() < 0.5 else (1.0,)):
            y = s * (hw - 0.022)
            parts.append(revolve([[ri_in + ring_w - 0.01, y - 0.02], [ro_in + 0.01, y - 0.02],
                                  [ro_in + 0.01, y + 0.02], [ri_in + ring_w - 0.01, y + 0.02],
                                  [ri_in + ring_w - 0.01, y - 0.02]], sections=72))
    return Parts(parts, min(0.02, ring_w / 2))


def _wing(span: float, root: float, tip: float, sweep: float, thick: float, side: float,
          x0: float, y0: float, dihedral: float, vertical: bool = False):
    """A tapered swept wing panel (a trapezoid prism) from the root at z=0 outwards."""
    outline = np.array([[x0, 0.0], [x0 - sweep, side * span], [x0 - sweep - tip, side * span],
                        [x0 - root, 0.0]])
    if side < 0:
        outline = outline[::-1]
    V, F = prism(outline, -thick / 2, thick / 2)
    if vertical:  # fin: the span goes up (+y) instead of sideways (+z)
        V = V @ rotation(_X, -np.pi / 2 * side).T
    else:
        V = V @ rotation(_X, -side * dihedral).T
    return _outward(V + np.array([0.0, y0, 0.0]), F)


def _airplane(rng: np.random.Generator) -> Parts:
    L = rng.uniform(1.6, 2.2)
    Rf = L * rng.uniform(0.04, 0.065)
    nose, tail = L * rng.uniform(0.1, 0.2), L * rng.uniform(0.25, 0.35)
    xs = np.linspace(0, L, 40)
    r = np.full_like(xs, Rf)
    r = np.where(xs < nose, Rf * np.sqrt(np.clip(np.sin(np.pi / 2 * xs / nose), 0, 1)), r)
    r = np.where(xs > L - tail, Rf * (0.25 + 0.75 * (L - xs) / tail), r)
    prof = np.concatenate([[[0, 0]], np.column_stack([r[1:], xs[1:]]), [[0, L]]])
    # the fuselage is revolved about +y, then laid along -x (nose at x = L/2)
    parts = [revolve(prof, sections=48, R=rotation(_Z, np.pi / 2), t=(L / 2, 0.0, 0.0))]
    span = L * rng.uniform(0.4, 0.6)
    root = L * rng.uniform(0.14, 0.25)
    tipc = root * rng.uniform(0.25, 0.7)
    sweep = span * rng.uniform(0.0, 0.6)
    thick = rng.uniform(0.025, 0.045)
    xw = L * rng.uniform(0.05, 0.18)
    yw = rng.uniform(-0.5, 0.5) * Rf
    dih = rng.uniform(0.0, 0.1)
    for s in (1.0, -1.0):
        parts.append(_wing(span, root, tipc, sweep, thick, s, xw, yw, dih))
    # tail plane and fin
    hs = span * rng.uniform(0.3, 0.45)
    hr = root * rng.uniform(0.4, 0.6)
    xt = -L / 2 + tail * 0.55
    for s in (1.0, -1.0):
        parts.append(_wing(hs, hr, hr * 0.5, hs * 0.4, thick * 0.7, s, xt, Rf * 0.2, 0.0))
    fh = span * rng.uniform(0.25, 0.4)
    parts.append(_wing(fh, hr * 1.2, hr * 0.5, fh * 0.7, thick * 0.7, 1.0, xt + 0.02, Rf * 0.3, 0.0,
                       vertical=True))
    engines = int(rng.choice([0, 2, 4]))
    if engines:
        re = Rf * rng.uniform(0.35, 0.55)
        le = root * rng.uniform(0.5, 0.8)
        zs = span * (np.array([0.35]) if engines == 2 else np.array([0.3, 0.6]))
        for z in zs:
            for s in (1.0, -1.0):
                x = xw - sweep * z / span + le * 0.3
                yy = yw - re * 0.9
                parts.append(tube(np.array([[x, yy, s * z], [x - le, yy, s * z]]), re, sections=24))
                parts.append(box((le * 0.5, re * 1.2, 0.02), t=(x - le / 2, yy + re * 0.7, s * z)))
    return Parts(parts, min(thick / 2, 0.01 if engines else 1.0))


def _glasses(rng: np.random.Generator) -> Parts:
    a, b = rng.uniform(0.2, 0.3), rng.uniform(0.14, 0.22)
    p = rng.uniform(2.0, 4.5)
    wire = rng.uniform(0.02, 0.03)
    bridge = rng.uniform(0.1, 0.2)
    cx = a + bridge / 2
    outline = _superellipse(a, b, p, 96)
    parts = []
    lenses = rng.random() < 0.6
    for s in (1.0, -1.0):
        rim = np.column_stack([s * cx + outline[:, 0], outline[:, 1], np.zeros(len(outline))])
        parts.append(tube(rim, wire, closed=True, sections=10))
        if lenses:  # a thin slab filling the rim (the outline lies in x-y, thickness along z)
            lens = prism(outline * 0.97, -0.008, 0.008, R=rotation(_X, np.pi / 2), t=(s * cx, 0.0, 0.0))
            parts.append(lens)
    # bridge: an arc over the nose between the two rims
    yb = b * rng.uniform(0.2, 0.6)
    xin = bridge / 2 + a * 0.1
    arch = _arc((0, yb, 0), _X, _Y, xin, rng.uniform(0.03, 0.08), 0, np.pi, 20)
    parts.append(tube(arch, wire, sections=10))
    # temples: from the outer hinge back along -z, the tip bent down, folded inwards by some angle
    length = rng.uniform(0.8, 1.1)
    bend = rng.uniform(0.2, 0.6)
    fold = rng.uniform(0.0, 1.4)
    for s in (1.0, -1.0):
        hinge = np.array([s * (cx + a * 0.98), b * 0.35, 0.0])
        u = np.linspace(0, 1, 24)
        straight = np.minimum(u, 0.75) * length
        drop = np.maximum(u - 0.75, 0) * length
        path = np.column_stack([np.zeros_like(u), -drop * math.sin(bend),
                                -(straight + drop * math.cos(bend))])
        fold_s = fold * rng.uniform(0.8, 1.0)
        path = path @ rotation(_Y, s * fold_s).T + hinge + (0, 0, -0.03)
        parts.append(tube(np.concatenate([[hinge], path]), wire, sections=10))
        parts.append(box((0.05, 0.06, 0.06), t=hinge + (0, 0, -0.02)))
    return Parts(parts, wire)


_BUILDERS = {
    "cup": _cup,
    "vase": _vase,
    "bottle": _bottle,
    "chair": _chair,
    "table": _table,
    "spring": _spring,
    "gear": _gear,
    "bearing": _bearing,
    "airplane": _airplane,
    "glasses": _glasses,
}


def build_rigid(cls: str, rng: np.random.Generator) -> Parts:
    """Draw one object of a rigid class.

    Parameters
    ----------
    cls : str
        One of :data:`RIGID_CLASSES`.
    rng : numpy.random.Generator
        Source of the proportions and options (the same state gives the same object).

    Returns
    -------
    Parts

    Examples
    --------
    >>> parts = build_rigid("cup", np.random.default_rng(0))
    >>> len(parts.parts) >= 2 and parts.min_feature > 0
    True
    """
    check_choice("rigid class", cls, RIGID_CLASSES)
    return _BUILDERS[cls](rng)
