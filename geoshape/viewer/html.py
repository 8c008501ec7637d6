"""Self-contained HTML viewers: meshes or contours side by side, colours carried through a map.

Each function returns the text of ONE HTML file that opens from disk with no network access:
the shapes are inlined as base64 of little-endian typed arrays (float32 positions, uint16 or
uint32 indices, uint8 colours), decoded by the page's own script; for meshes the three.js r147
UMD build and its ``OrbitControls`` (``vendor/``, MIT) are inlined too. All 3D views share
one camera (dragging any view rotates them all) and clicking a vertex marks it and its image
through the map; 2D contours are drawn as SVG (no WebGL). :func:`write_html` writes a page
atomically.

Each mesh is centred and scaled to unit radius before it is encoded (float32 keeps ~7
digits), so two 5,000-vertex meshes and their map make a file of about 1 MB, of which
0.63 MB is three.js.
"""

from __future__ import annotations

import base64
import functools
import html
import json
import os
import re
from pathlib import Path

import numpy as np

__all__ = [
    "contour_matching_html",
    "correspondence_html",
    "embedding_html",
    "query_html",
    "write_html",
]

#: The vendored scripts inlined into every 3D page, in load order.
VENDOR_SCRIPTS = ("three.min.js", "OrbitControls.js")

#: Most single-coordinate colourings offered by :func:`embedding_html`.
MAX_COORDINATE_COLOURINGS = 16

_MARKER = re.compile(r"/\*@(TITLE|DATA|VENDOR)@\*/")

#: What the page's script draws, and how it names one item (in the line a click writes).
_MESHES = {"kind": "mesh", "unit": "vertex", "units": "vertices"}
_CONTOURS = {"kind": "contour", "unit": "point", "units": "points"}


def _package_text(name: str) -> str:
    from importlib.resources import files

    return files("geoshape.viewer").joinpath(name).read_text(encoding="utf-8")


@functools.lru_cache(maxsize=1)
def _vendor_block() -> str:
    parts = []
    for name in VENDOR_SCRIPTS:
        code = _package_text(f"vendor/{name}")
        if "</script" in code.lower():  # would end the inline <script> early
            raise RuntimeError(f"vendored {name} cannot be inlined: it contains '</script'")
        parts.append(f"<script>/* {name}: three.js r147, MIT licence */\n{code}\n</script>")
    return "\n".join(parts)


def _encode(a, dtype: str) -> dict:
    """``{"dtype", "shape", "b64"}`` of ``a`` as little-endian ``f32``, ``u32``, ``u16`` or ``u8``."""
    np_dtype = {"f32": "<f4", "u32": "<u4", "u16": "<u2", "u8": "u1"}[dtype]
    a = np.ascontiguousarray(a, dtype=np_dtype)
    return {"dtype": dtype, "shape": list(a.shape), "b64": base64.b64encode(a.tobytes()).decode("ascii")}


def _encode_index(a, n: int) -> dict:
    """Indices below ``n``: uint16 when they fit, else uint32."""
    return _encode(a, "u16" if n <= 0xFFFF else "u32")


def _rgb8(colors) -> np.ndarray:
    """(n, 3) uint8 from colours in [0, 1] of shape (n, 3) or (n, 4)."""
    c = np.asarray(colors, dtype=np.float64)[:, :3]
    return np.clip(np.rint(255 * c), 0, 255).astype(np.uint8)


def _unit(V) -> np.ndarray:
    """``V`` centred on its bounding box and scaled to unit radius (the view needs no more)."""
    V = np.asarray(V, dtype=np.float64)
    V = V - (V.min(axis=0) + V.max(axis=0)) / 2
    r = float(np.sqrt((V**2).sum(axis=1).max())) if len(V) else 0.0
    return V / r if r > 0 else V


def _mesh_panel(V, F, label: str, *, name: str, sublabel: str = "", colourings=(), color=None) -> dict:
    from geoshape.io.validate import check_mesh

    V, F = check_mesh(V, F, name=name)
    panel = {"label": label, "sublabel": sublabel, "V": _encode(_unit(V), "f32"),
             "F": _encode_index(F, len(V)), "colors": [_encode(_rgb8(c), "u8") for c in colourings]}
    if color is not None:
        panel["color"] = [int(x) for x in color]
    return panel


def _check_map(p2p, n_source: int, n_target: int, what: str = "p2p_12") -> np.ndarray:
    p2p = np.asarray(p2p)
    if p2p.shape != (n_source,) or p2p.dtype.kind not in "iu":
        raise ValueError(f"{what} must be ({n_source},) integers, got {p2p.shape} {p2p.dtype}")
    if n_source and (p2p.min() < 0 or p2p.max() >= n_target):
        raise ValueError(f"{what} must lie in [0, {n_target - 1}]")
    return p2p


def _page(data: dict, *, three: bool) -> str:
    """The HTML text: the template with the title, the data and (for 3D) the scripts inlined."""
    data = {"title": "geoshape", "subtitle": "", "legend": "", "up": "z", **data}
    if data["up"] not in ("y", "z"):
        raise ValueError(f"up must be 'y' or 'z', got {data['up']!r}")
    # "<" escaped: the JSON sits inside a <script> element and must not close it
    blob = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")
    parts = {"TITLE": html.escape(data["title"]), "DATA": blob, "VENDOR": _vendor_block() if three else ""}
    return _MARKER.sub(lambda m: parts[m.group(1)], _package_text("template.html"))


def correspondence_html(V1, F1, V2, F2, p2p_12, *, names=("source", "target"), title: str | None = None,
                        subtitle: str = "", up: str = "z") -> str:
    """Page of a 3-D map: source (coloured through the map) and target side by side.

    Parameters
    ----------
    V1 : (n1, 3) float
    F1 : (m1, 3) int
        Source mesh.
    V2 : (n2, 3) float
    F2 : (m2, 3) int
        Target mesh.
    p2p_12 : (n1,) int
        Target vertex of each source vertex.
    names : (str, str)
        Labels of the two views.
    title, subtitle : str
        Page heading and a line under it (method, cost…).
    up : {"z", "y"}
        Axis shown vertical at first (a button switches).

    Returns
    -------
    str
        The HTML text (write it with :func:`write_html`).
    """
    from geoshape.plot.correspondence import transferred_colors

    p2p = _check_map(p2p_12, len(V1), len(V2))
    src, tgt = transferred_colors(np.asarray(V2, dtype=np.float64), p2p)
    panels = [_mesh_panel(V1, F1, names[0], name="source mesh", sublabel="coloured through the map",
                          colourings=[src]),
              _mesh_panel(V2, F2, names[1], name="target mesh", sublabel="coloured by position",
                          colourings=[tgt])]
    legend = ("Target coloured by position in its bounding box (x red, y green, z blue); each source "
              "vertex takes the colour of its image, so parts that correspond look alike.")
    return _page({**_MESHES, "title": title or f"{names[0]} \u2192 {names[1]}",
                  "subtitle": subtitle, "legend": legend, "up": up, "colorings": ["through the map"],
                  "panels": panels, "maps": [{"src": 0, "dst": 1, "p2p": _encode_index(p2p, len(V2))}]},
                 three=True)


def embedding_html(V, F, coords, *, name: str = "mesh", title: str | None = None, subtitle: str = "",
                   up: str = "z") -> str:
    """Page of a spectral embedding: the mesh and the embedded mesh, coloured by the coordinates.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
        The mesh.
    coords : (n, k) float
        Embedding coordinates (``geoshape embed``'s ``OUT.npy``). The second view is the
        embedded mesh (coordinates 1–3 as positions, zeros when ``k < 3``); clicking a
        vertex marks it on both.
    name, title, subtitle, up
        As in :func:`correspondence_html`.

    Returns
    -------
    str

    Colourings (a menu): coordinates 1–3 as RGB, then each of the first
    :data:`MAX_COORDINATE_COLOURINGS` coordinates through a diverging colour map.
    """
    from geoshape.plot.colormap import position_colors, scalar_colors
    from geoshape.spectral.embedded_mesh import embedding_vertices

    coords = np.asarray(coords, dtype=np.float64)
    if coords.ndim != 2 or coords.shape[0] != len(V) or coords.shape[1] < 1:
        raise ValueError(f"coords must be ({len(V)}, k) with k >= 1, got {coords.shape}")
    if not np.isfinite(coords).all():
        raise ValueError("coords must be finite")
    k = coords.shape[1]
    E = embedding_vertices(coords)
    names = [f"coordinates 1\u2013{min(k, 3)} as RGB"]
    colourings = [position_colors(E)]
    for j in range(min(k, MAX_COORDINATE_COLOURINGS)):
        names.append(f"coordinate {j + 1}")
        colourings.append(scalar_colors(coords[:, j], "coolwarm"))
    panels = [_mesh_panel(V, F, name, name="mesh", colourings=colourings),
              _mesh_panel(E, F, "embedding", name="embedded mesh",
                          sublabel="coordinates 1\u20133 as x, y, z")]
    panels[1]["colors"] = []
    panels[1]["colors_from"] = 0  # the same colours, stored once
    legend = (f"{k} embedding coordinates. Red/green/blue: coordinates 1/2/3 scaled to their range; "
              "single coordinates: blue negative, red positive.")
    return _page({**_MESHES, "title": title or f"spectral embedding of {name}",
                  "subtitle": subtitle, "legend": legend, "up": up, "colorings": names, "panels": panels,
                  "maps": [{"src": 0, "dst": 1, "p2p": None}]}, three=True)


def query_html(query, results, *, query_name: str = "query", names=None, scores=None,
               title: str | None = None, subtitle: str = "", up: str = "z") -> str:
    """Page of a retrieval query: the query mesh and its results, side by side, one camera.

    Parameters
    ----------
    query : (V (n, 3), F (m, 3))
    results : sequence of (V, F)
        Best first.
    query_name : str
    names : sequence of str, optional
        Label of each result (default ``result 1`` …).
    scores : sequence of float, optional
        Distance of each result to the query, shown under its name.
    title, subtitle, up
        As in :func:`correspondence_html`.

    Returns
    -------
    str
    """
    results = list(results)
    names = list(names) if names is not None else [f"result {i + 1}" for i in range(len(results))]
    if len(names) != len(results) or (scores is not None and len(scores) != len(results)):
        raise ValueError("names and scores need one entry per result")
    panels = [_mesh_panel(*query, f"query: {query_name}", name=f"query {query_name}", color=(235, 160, 90))]
    for i, ((V, F), nm) in enumerate(zip(results, names, strict=True)):
        sub = f"distance {float(scores[i]):.4g}" if scores is not None else ""
        panels.append(_mesh_panel(V, F, f"#{i + 1} {nm}", name=str(nm), sublabel=sub, color=(143, 179, 217)))
    return _page({**_MESHES, "title": title or f"{len(results)} results for {query_name}",
                  "subtitle": subtitle, "up": up, "colorings": ["uniform"], "panels": panels, "maps": []},
                 three=True)


def contour_matching_html(P, Q, p2p_12, *, names=("A", "B"), title: str | None = None,
                          subtitle: str = "") -> str:
    """Page of a 2-D matching: both contours (SVG), matched points coloured alike.

    Parameters
    ----------
    P : (N, 2) float
    Q : (M, 2) float
        Closed contours, ``(x, y)`` with y up (as :func:`geoshape.geometry.contour.contour_from_image`).
    p2p_12 : (N,) int
        Point of ``Q`` matched to each point of ``P``.
    names, title, subtitle
        As in :func:`correspondence_html`.

    Returns
    -------
    str

    ``Q`` is coloured by arc position (hue around the contour), each point of ``P`` by the
    colour of its match; clicking a point marks it and its match.
    """
    from matplotlib.colors import hsv_to_rgb

    P = np.asarray(P, dtype=np.float64)
    Q = np.asarray(Q, dtype=np.float64)
    for X, nm in ((P, "P"), (Q, "Q")):
        if X.ndim != 2 or X.shape[1] != 2 or len(X) < 3 or not np.isfinite(X).all():
            raise ValueError(f"{nm} must be a finite (N, 2) array with N >= 3, got {X.shape}")
    p2p = _check_map(p2p_12, len(P), len(Q))
    hue = np.arange(len(Q)) / len(Q)
    tgt = hsv_to_rgb(np.column_stack([hue, np.full_like(hue, 0.85), np.full_like(hue, 0.9)]))
    panels = []
    for X, nm, colours, sub in ((P, names[0], tgt[p2p], "coloured through the matching"),
                                (Q, names[1], tgt, "coloured by position along the contour")):
        X = X - (X.min(axis=0) + X.max(axis=0)) / 2
        X = X / max(float(np.abs(X).max()), 1e-300)
        panels.append({"label": nm, "sublabel": sub, "V": _encode(X, "f32"),
                       "colors": [_encode(_rgb8(colours), "u8")]})
    legend = (f"{names[1]} coloured by position along its contour; each point of {names[0]} takes the "
              "colour of its match.")
    return _page({**_CONTOURS, "title": title or f"{names[0]} \u2194 {names[1]}",
                  "subtitle": subtitle, "legend": legend, "colorings": ["through the matching"],
                  "panels": panels, "maps": [{"src": 0, "dst": 1, "p2p": _encode_index(p2p, len(Q))}]},
                 three=False)


def write_html(path: str | os.PathLike, text: str) -> Path:
    """Write a page atomically (UTF-8) and return its path."""
    from geoshape.io.atomic import write_text_atomic

    write_text_atomic(path, text)
    return Path(path)
