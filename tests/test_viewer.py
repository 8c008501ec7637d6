"""The offline HTML viewer (geoshape.viewer): self-contained pages, compact, rendered by a real
browser (headless Chromium), and the --html option of correspond, embed, match2d, index query."""

from __future__ import annotations

import base64
import functools
import json
import re
import shutil
import subprocess

import numpy as np
import pytest
from conftest import grid_mesh, icosphere

from geoshape.__main__ import main
from geoshape.viewer import (
    contour_matching_html,
    correspondence_html,
    embedding_html,
    query_html,
    write_html,
)

#: Flags that give headless Chromium a working WebGL on a machine without a GPU: ANGLE on
#: SwiftShader, a CPU renderer (explicitly allowed, newer releases no longer fall back to it
#: on their own), and a virtual-time budget so the page has loaded and drawn before the shot.
CHROMIUM_FLAGS = ("--headless", "--disable-gpu", "--no-sandbox", "--use-angle=swiftshader",
                  "--enable-unsafe-swiftshader", "--hide-scrollbars", "--mute-audio",
                  "--virtual-time-budget=5000")


#: Text found only in the vendored three.min.js (r147) and OrbitControls.js.
THREE_INLINE, ORBIT_INLINE = 'const e="147"', "THREE.OrbitControls = OrbitControls"


def _data(page: str) -> dict:
    """The JSON data block of a page."""
    m = re.search(r'<script id="geoshape-data" type="application/json">(.*?)</script>', page, re.S)
    assert m, "no data block"
    return json.loads(m.group(1))


def _array(a: dict) -> np.ndarray:
    dtype = {"f32": "<f4", "u32": "<u4", "u16": "<u2", "u8": "u1"}[a["dtype"]]
    return np.frombuffer(base64.b64decode(a["b64"]), dtype=dtype).reshape(a["shape"])


def _assert_offline(page: str) -> None:
    """Nothing to fetch: no external script, style, image or import."""
    assert not re.search(r"<script[^>]*\bsrc\s*=", page, re.I), "a <script src=…>"
    assert not re.search(r"<link\b", page, re.I), "a <link> element"
    assert not re.search(r"""\b(?:src|href)\s*=\s*["']?(?:https?:)?//""", page, re.I), "a URL attribute"
    assert not re.search(r"""url\(\s*["']?(?:https?:)?//""", page, re.I), "a CSS url()"
    assert not re.search(r"@import", page), "a CSS @import"
    assert page.count("<html") == 1 and page.rstrip().endswith("</html>")


def _pair(n_sub: int = 2):
    V, F = icosphere(n_sub)
    return V, F, V * [1.3, 1.0, 0.7], F


def test_a_correspondence_page_is_self_contained_and_round_trips_its_data():
    V1, F1, V2, F2 = _pair()
    p2p = np.arange(len(V1))[::-1].copy()
    page = correspondence_html(V1, F1, V2, F2, p2p, names=("left", "</script><b>right"))
    _assert_offline(page)
    assert THREE_INLINE in page and ORBIT_INLINE in page  # three.js r147 and its controls, inline
    data = _data(page)
    assert [p["label"] for p in data["panels"]] == ["left", "</script><b>right"]  # escaped, intact
    assert page.count("</script>") == 4  # data, three.js, OrbitControls, the page's own script
    src, tgt = data["panels"]
    assert _array(src["V"]).shape == (len(V1), 3) and src["F"]["dtype"] == "u16"
    assert np.array_equal(_array(src["F"]), F1)
    np.testing.assert_allclose(np.linalg.norm(_array(tgt["V"]), axis=1).max(), 1.0, rtol=1e-6)
    assert np.array_equal(_array(data["maps"][0]["p2p"]), p2p)
    # corresponding points have the same colour: source colour i == target colour p2p[i]
    assert np.array_equal(_array(src["colors"][0]), _array(tgt["colors"][0])[p2p])


def test_two_5k_vertex_meshes_make_a_page_under_5_mb():
    V1, F1 = grid_mesh(71, 71)  # 5041 vertices, 9800 faces
    V1[:, 2] = np.sin(3 * V1[:, 0]) * np.cos(2 * V1[:, 1])
    V2 = V1 * [1.2, 0.9, 1.5]
    p2p = np.random.default_rng(0).integers(0, len(V2), len(V1))
    page = correspondence_html(V1, F1, V2, F1, p2p)
    size = len(page.encode("utf-8"))
    assert size < 5_000_000, f"{size / 1e6:.2f} MB"
    data_size = len(re.search(r'application/json">(.*?)</script>', page, re.S).group(1))
    assert data_size < 600_000, f"data block {data_size / 1e6:.2f} MB: not a compact encoding"


def test_other_pages_and_bad_input():
    V, F = icosphere(1)
    coords = np.column_stack([V[:, 0], V[:, 1] ** 2, V[:, 2], V[:, 0] * V[:, 1]])
    emb = _data(embedding_html(V, F, coords, name="ball"))
    assert emb["colorings"][:2] == ["coordinates 1\u20133 as RGB", "coordinate 1"]
    assert len(emb["panels"][0]["colors"]) == 1 + 4 and emb["panels"][1]["colors_from"] == 0
    np.testing.assert_allclose(np.linalg.norm(_array(emb["panels"][1]["V"]), axis=1).max(), 1.0, rtol=1e-6)
    q = _data(query_html((V, F), [(V, F), (2 * V, F)], query_name="ball", names=["a", "b"], scores=[0, 0.5]))
    assert [p["label"] for p in q["panels"]] == ["query: ball", "#1 a", "#2 b"] and q["maps"] == []
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    P = np.column_stack([np.cos(t), np.sin(t)])
    page = contour_matching_html(P, 2 * P, np.roll(np.arange(40), 3), names=("p", "q"))
    _assert_offline(page)
    assert THREE_INLINE not in page and len(page) < 60_000  # 2D needs no WebGL library
    with pytest.raises(ValueError, match="p2p_12"):
        correspondence_html(V, F, V, F, np.full(len(V), len(V)))
    with pytest.raises(ValueError, match="coords"):
        embedding_html(V, F, coords[:-1])
    with pytest.raises(ValueError, match="up"):
        correspondence_html(V, F, V, F, np.arange(len(V)), up="x")


# ---- a real browser ---------------------------------------------------------------------

def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("no Chromium/Chrome binary on PATH (apt-get install chromium): cannot render the viewer")


def _chromium_run(tmp_path, url: str, *args: str) -> subprocess.CompletedProcess:
    cmd = [_chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}",
           "--window-size=1200,600", *args, url]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def _coloured_fraction(rgb: np.ndarray) -> float:
    """Share of saturated pixels: the meshes are coloured, background, frames and text grey."""
    rgb = rgb.astype(int)
    return float(((rgb.max(axis=2) - rgb.min(axis=2)) > 40).mean())


def test_headless_chromium_draws_both_meshes(tmp_path):
    from PIL import Image

    V1, F1, V2, F2 = _pair(3)
    page = write_html(tmp_path / "view.html", correspondence_html(V1, F1, V2, F2, np.arange(len(V1))))
    shot = tmp_path / "shot.png"
    r = _chromium_run(tmp_path, page.resolve().as_uri(), f"--screenshot={shot}")
    assert r.returncode == 0 and shot.is_file(), r.stderr[-2000:]
    img = np.asarray(Image.open(shot).convert("RGB"))
    assert img.shape[:2] == (600, 1200)
    body = img[150:]  # below the page's header
    left, right = _coloured_fraction(body[:, :600]), _coloured_fraction(body[:, 600:])
    assert left > 0.05 and right > 0.05, f"coloured pixels: left {left:.3f}, right {right:.3f}"


def test_a_click_marks_the_image_through_the_map(tmp_path):
    V1, F1, V2, F2 = _pair(2)
    p2p = np.arange(len(V1))[::-1].copy()
    page = write_html(tmp_path / "view.html",
                      correspondence_html(V1, F1, V2, F2, p2p, names=("left", "right")))
    # "#mark=K,I" runs the click handler on item I of view K when the page opens
    r = _chromium_run(tmp_path, page.resolve().as_uri() + "#mark=0,7", "--dump-dom")
    assert r.returncode == 0, r.stderr[-2000:]
    assert 'data-ready="1"' in r.stdout
    assert f"left vertex 7 \u2192 right vertex {p2p[7]}" in r.stdout
    t = np.linspace(0, 2 * np.pi, 30, endpoint=False)
    P = np.column_stack([np.cos(t), np.sin(2 * t) / 2 + np.sin(t)])
    shift = np.roll(np.arange(30), 4)  # point i of a matches point i - 4 of b
    page2 = write_html(tmp_path / "c.html", contour_matching_html(P, P, shift, names=("a", "b")))
    r = _chromium_run(tmp_path, page2.resolve().as_uri() + "#mark=1,4", "--dump-dom")
    assert "b point 4 \u2190 a points 8 (1 map here)" in r.stdout, r.stdout[-3000:]
    assert r.stdout.count("<circle") == 60


class _Browser:
    """Headless Chromium driven over the DevTools protocol on a pipe (no extra package):
    JSON messages ending in NUL, written to the browser's fd 3 and read from its fd 4."""

    def __init__(self, url: str, profile):
        import fcntl
        import os

        to_chrome, from_us = os.pipe()
        to_us, from_chrome = os.pipe()

        def fds_3_and_4():  # move through high numbers first: the pipe ends may be 3 or 4
            a = fcntl.fcntl(to_chrome, fcntl.F_DUPFD, 10)
            b = fcntl.fcntl(from_chrome, fcntl.F_DUPFD, 10)
            os.dup2(a, 3)
            os.dup2(b, 4)

        cmd = [_chromium(), *(f for f in CHROMIUM_FLAGS if not f.startswith("--virtual-time")),
               f"--user-data-dir={profile}", "--window-size=1200,600", "--remote-debugging-pipe", url]
        self.proc = subprocess.Popen(cmd, pass_fds=(3, 4), preexec_fn=fds_3_and_4,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(to_chrome)
        os.close(from_chrome)
        self.w, self.r = os.fdopen(from_us, "wb", buffering=0), os.fdopen(to_us, "rb", buffering=0)
        self.buf, self.last, self.session = b"", 0, None

    def send(self, method: str, **params):
        self.last += 1
        msg = {"id": self.last, "method": method, "params": params}
        if self.session and not method.startswith(("Target.", "Browser.")):
            msg["sessionId"] = self.session
        self.w.write(json.dumps(msg).encode() + b"\0")
        while True:
            while b"\0" not in self.buf:
                chunk = self.r.read(1 << 16)
                assert chunk, "Chromium closed the DevTools pipe"
                self.buf += chunk
            raw, self.buf = self.buf.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self.last:
                assert "error" not in reply, reply["error"]
                return reply["result"]

    def open_page(self, timeout: float = 60.0):
        import time

        end = time.monotonic() + timeout

        def pages():
            targets = self.send("Target.getTargets")["targetInfos"]
            return [t["targetId"] for t in targets if t["type"] == "page"]

        while not pages():
            assert time.monotonic() < end, "no page"
            time.sleep(0.05)
        self.session = self.send("Target.attachToTarget", targetId=pages()[0], flatten=True)["sessionId"]
        while self.js("document.body.dataset.ready") != "1":
            assert time.monotonic() < end, "the page never drew"
            time.sleep(0.05)

    def js(self, expression: str):
        return self.send("Runtime.evaluate", expression=expression, returnByValue=True,
                         awaitPromise=True)["result"].get("value")

    def drawn(self) -> None:
        """Wait two animation frames: a render requested before has run."""
        self.js("new Promise((ok) => requestAnimationFrame(() => requestAnimationFrame(ok)))")

    def screenshot(self) -> np.ndarray:
        import io

        from PIL import Image

        png = base64.b64decode(self.send("Page.captureScreenshot", format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)

    def drag(self, x0: int, x1: int, y: int) -> None:
        mouse = functools.partial(self.send, "Input.dispatchMouseEvent", y=y, button="left", clickCount=1)
        mouse(type="mousePressed", x=x0, buttons=1)
        for x in np.linspace(x0, x1, 8)[1:]:
            mouse(type="mouseMoved", x=float(x), buttons=1)
        mouse(type="mouseReleased", x=x1, buttons=0)

    def close(self) -> None:
        try:
            self.send("Browser.close")
            self.proc.wait(timeout=30)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait()
            self.w.close()
            self.r.close()


def test_dragging_one_view_turns_both_and_a_click_marks_the_image(tmp_path):
    V1, F1, V2, F2 = _pair(3)
    p2p = np.arange(len(V1))[::-1].copy()
    page = write_html(tmp_path / "view.html",
                      correspondence_html(V1, F1, V2, F2, p2p, names=("left", "right")))
    browser = _Browser(page.resolve().as_uri(), tmp_path / "profile")
    try:
        browser.open_page()
        browser.drag(300, 300, 360)  # a click (no motion) on the left mesh picks a vertex
        browser.drawn()
        status = browser.js("document.getElementById('status').textContent")
        m = re.fullmatch(r"left vertex (\d+) \u2192 right vertex (\d+)", status or "")
        assert m and p2p[int(m.group(1))] == int(m.group(2)), status
        assert browser.js("document.querySelectorAll('#panels .panel').length") == 2
        for x0, x1 in ((200, 420), (1000, 780)):  # drag in the left view, then in the right one
            before = browser.screenshot()[150:]
            browser.drag(x0, x1, 380)
            browser.drawn()
            changed = np.abs(browser.screenshot()[150:] - before).sum(axis=2) > 30
            left, right = changed[:, :600].mean(), changed[:, 600:].mean()
            assert left > 0.02 and right > 0.02, f"drag {x0}->{x1}: changed {left:.3f} | {right:.3f}"
    finally:
        browser.close()


# ---- the command line -------------------------------------------------------------------

@pytest.fixture
def meshes(tmp_path):
    from geoshape.io.mesh_io import save_mesh

    V, F = icosphere(2)
    save_mesh(tmp_path / "a.off", V, F)
    save_mesh(tmp_path / "b.off", V * [1.3, 1.0, 0.8], F)
    return tmp_path / "a.off", tmp_path / "b.off"


def _page_ok(path, *, three: bool = True) -> dict:
    page = path.read_text(encoding="utf-8")
    _assert_offline(page)
    assert (THREE_INLINE in page) == three and (ORBIT_INLINE in page) == three
    return _data(page)


def test_cli_correspond_and_embed_write_a_viewer(meshes, tmp_path):
    a, b = meshes
    view = tmp_path / "v.html"
    assert main(["correspond", str(a), str(b), "-o", str(tmp_path / "m.txt"), "--method", "rigid-icp",
                 "--html", str(view)]) == 0
    data = _page_ok(view)
    assert [p["label"] for p in data["panels"]] == ["a", "b"] and "rigid-icp" in data["subtitle"]
    p2p = np.loadtxt(tmp_path / "m.txt", dtype=int)
    assert np.array_equal(_array(data["maps"][0]["p2p"]), p2p)
    assert main(["embed", str(a), "-o", str(tmp_path / "e.ply"), "--dims", "4",
                 "--html", str(tmp_path / "e.htm")]) == 0
    data = _page_ok(tmp_path / "e.htm")
    assert len(data["panels"][0]["colors"]) == 1 + 4
    coords = np.load(tmp_path / "e.npy")
    assert coords.shape == (len(_array(data["panels"][0]["V"])), 4)


def test_cli_match2d_writes_a_viewer(tmp_path, capsys):
    from geoshape_datasets_gen.silhouettes2d import generate_silhouettes

    generate_silhouettes(tmp_path, per_class=2, classes=("star",), seed=0)
    view = tmp_path / "m.html"
    assert main(["match2d", str(tmp_path / "star_0.png"), str(tmp_path / "star_1.png"), "--n-points", "60",
                 "--html", str(view)]) == 0
    assert f"viewer: {view}" in capsys.readouterr().out
    data = _page_ok(view, three=False)
    assert data["kind"] == "contour" and [p["label"] for p in data["panels"]] == ["star_0.png", "star_1.png"]
    assert _array(data["panels"][0]["V"]).shape == (60, 2)


def test_cli_index_query_writes_a_viewer(meshes, tmp_path):
    a, b = meshes
    db = tmp_path / "idx.db"
    assert main(["index", "add", str(db), str(a), str(b), "--descriptor", "d2", "--backend", "serial"]) == 0
    view = tmp_path / "q.html"
    assert main(["index", "query", str(db), str(a), "--descriptor", "d2", "--top", "2",
                 "--html", str(view)]) == 0
    data = _page_ok(view)
    labels = [p["label"] for p in data["panels"]]
    assert labels[0] == "query: a" and sorted(labels[1:]) == ["#1 a", "#2 b"]
    assert data["panels"][1]["sublabel"].startswith("distance ")


@pytest.mark.parametrize("argv", [
    ["correspond", "A.off", "B.off", "-o", "m.txt"],
    ["embed", "A.off", "-o", "e.ply"],
    ["match2d", "A.png", "B.png"],
    ["index", "query", "db.sqlite", "A.off"],
])
def test_a_bad_html_path_fails_first_in_one_line(argv, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the inputs do not exist either: the output is checked first
    assert main([*argv, "--html", str(tmp_path / "no" / "v.html")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--html" in err[0] and "does not exist" in err[0], err
    assert main([*argv, "--html", str(tmp_path / "v.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unsupported extension '.png'" in err[0] and ".html, .htm" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # nothing written
