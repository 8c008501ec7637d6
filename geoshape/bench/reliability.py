"""``geoshape bench reliability``: every command against bad output paths, a full disk,
defective meshes, crashing native code and out-of-range options.

Each case runs ``geoshape …`` in its own subprocess (so a crash cannot hide the others) on
small generated inputs, and is judged by what a user sees: the exit status (0, 2 or 130
only), no traceback, no death by a signal, and no partial file left in the output folder
(neither a finished output next to a failed one, nor a temporary). The table goes into the
``reliability`` section of docs/RESULTS.md; the test suite runs the same cases
(``tests/test_reliability.py``), so CI fails on any regression.

Read-only folders and a full disk are real: a read-only and a 32 KiB tmpfs are mounted when
the process may mount (root on Linux); otherwise those rows say "skipped" with the reason.
"""

from __future__ import annotations

import contextlib
import functools
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

HELP = "reliability: every command with bad output paths and a full disk, each in a subprocess"


@dataclass(frozen=True)
class Case:
    """One command line, the exit statuses it may end with, and where it must leave nothing."""

    group: str
    name: str
    argv: tuple[str, ...]  # "{in}" is the inputs folder, "{ro}" a read-only folder, "{full}" a full disk
    expect: frozenset = frozenset({2})
    clean: tuple[str, ...] = ()  # folders that must hold no file afterwards
    needs: str | None = None  # "ro" or "full": skipped where it cannot be mounted


@dataclass
class Outcome:
    case: Case
    status: str  # "ok", "FAIL" or "skipped"
    exit_code: int | None = None
    message: str = ""
    problems: list[str] = field(default_factory=list)


def _inputs(folder: Path) -> None:
    """Two silhouettes, a labelled folder of four, two small meshes, a labelled mesh folder,
    an index of them and an .mlx script: everything the cases read, in about a second."""
    import numpy as np
    import trimesh
    from PIL import Image, ImageDraw

    from geoshape.io.mesh_io import save_mesh

    sil = folder / "sil"
    sil.mkdir()
    rows = []
    for i, (w, h) in enumerate([(40, 40), (44, 38), (60, 20), (58, 24)]):
        img = Image.new("L", (96, 96), 0)
        ImageDraw.Draw(img).ellipse([48 - w // 2, 48 - h // 2, 48 + w // 2, 48 + h // 2], fill=255)
        img.save(sil / f"s{i}.png")
        rows.append(f"s{i}.png,{'round' if i < 2 else 'long'}")
    (sil / "labels.csv").write_text("file,label\n" + "\n".join(rows) + "\n")
    meshes = folder / "meshes"
    meshes.mkdir()
    rng = np.random.default_rng(0)
    rows = []
    for i in range(4):
        m = trimesh.creation.icosphere(subdivisions=2)
        V = m.vertices * ([1.0, 1.0, 1.0] if i < 2 else [2.0, 0.6, 0.6]) + rng.normal(
            0, 0.005, m.vertices.shape
        )
        save_mesh(meshes / f"m{i}.off", V, m.faces)
        rows.append(f"m{i}.off,{'sphere' if i < 2 else 'cigar'}")
    (meshes / "labels.csv").write_text("file,label\n" + "\n".join(rows) + "\n")
    (folder / "negative.mlx").write_text(  # PyMeshLab dies with SIGBUS on this one
        '<!DOCTYPE FilterScript>\n<FilterScript>\n <filter name="meshing_decimation_quadric_edge_collapse">\n'
        '  <Param type="RichInt" name="targetfacenum" value="-5"/>\n </filter>\n</FilterScript>\n'
    )
    (folder / "exact_geodesics.mlx").write_text(
        '<!DOCTYPE FilterScript>\n<FilterScript>\n <filter id="geodesic_distance_from_selection">\n'
        '  <Param type="RichString" name="sources" value="0"/>\n'
        '  <Param type="RichEnum" name="method" value="exact"/>\n </filter>\n</FilterScript>\n'
    )
    pairs = folder / "pairs"
    for sub in ("a", "b"):
        (pairs / sub).mkdir(parents=True)
        for name, i in (("x", 0), ("y", 1)):
            (pairs / sub / f"{name}.off").write_bytes((meshes / f"m{i}.off").read_bytes())
    (pairs / "colliding.csv").write_text("source,target\na/x.off,a/y.off\nb/x.off,b/y.off\n")
    (pairs / "one_column.csv").write_text("source,target\na/x.off\n")
    unlabelled = folder / "sil_unlabelled"
    unlabelled.mkdir()
    for i in (0, 1):
        (unlabelled / f"s{i}.png").write_bytes((sil / f"s{i}.png").read_bytes())
    (unlabelled / "labels.csv").write_text("file,label\ns0.png,round\ns1.png\n")
    bad = folder / "defects"
    bad.mkdir()
    m = trimesh.creation.icosphere(subdivisions=2)
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    save_mesh(bad / "duplicate_faces.off", V, np.vstack([F, F[:5]]))
    save_mesh(bad / "repeated_vertex.off", V, np.vstack([F[1:], [[F[0, 0], F[0, 0], F[0, 1]]]]))
    save_mesh(
        bad / "nonmanifold_edge.off",
        np.vstack([V, [[3.0, 3.0, 3.0]]]),
        np.vstack([F, [[F[0, 0], F[0, 1], len(V)]]]),
    )
    save_mesh(
        bad / "zero_area_face.off",
        np.vstack([V, V[F[0, 0]], V[F[0, 0]]]),
        np.vstack([F, [[len(V), len(V) + 1, F[0, 0]]]]),
    )
    coincident = V.copy()
    coincident[1] = coincident[0]
    save_mesh(bad / "coincident_vertices.off", coincident, F)
    (folder / "script.mlx").write_text(
        "<!DOCTYPE FilterScript>\n<FilterScript>\n"
        ' <filter name="Compute normals for point sets"/>\n</FilterScript>\n'
    )
    _geoshape(
        "index", "add", str(folder / "index.db"), str(meshes), "--descriptor", "d2", "--backend", "serial"
    )


def _geoshape(*argv: str, timeout: float = 300.0) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONFAULTHANDLER"}
    env["MPLBACKEND"] = "Agg"
    return subprocess.run(
        [sys.executable, "-m", "geoshape", *argv],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        stdin=subprocess.DEVNULL,
    )


def cases() -> list[Case]:
    """Every case class of the reliability issue, each one command line."""
    sil, meshes = "{in}/sil", "{in}/meshes"
    a, b = f"{sil}/s0.png", f"{sil}/s1.png"
    m0, m1 = f"{meshes}/m0.off", f"{meshes}/m1.off"
    out = []
    writers = [  # (command, argv before the output option, output option, a good name for it)
        ("match2d", ("match2d", a, b), "--out", "pairs.csv"),
        ("match2d", ("match2d", a, b), "--plot", "fig.png"),
        ("retrieval2d", ("retrieval2d", sil, "--backend", "serial"), "--matrix", "D.npy"),
        ("embed", ("embed", m0), "-o", "emb.ply"),
        ("correspond", ("correspond", m0, m1, "--method", "rigid-icp"), "-o", "map.txt"),
        (
            "retrieval3d",
            ("retrieval3d", meshes, "--descriptor", "d2", "--backend", "serial"),
            "--matrix",
            "D.npy",
        ),
        (
            "index query",
            ("index", "query", "{in}/index.db", m0, "--descriptor", "d2"),
            "--plot-strip",
            "s.png",
        ),
        ("run", ("run", "-i", m0, "-s", "{in}/script.mlx"), "-o", "out.ply"),
        ("gen spikes", ("gen", "spikes", m0, "--count", "3", "--height", "0.1"), "--out", "spiky.off"),
    ]
    # retrieval2d/retrieval3d need --matrix even when another output is the one under test
    for command, argv, option, good in writers:
        extra = ()
        if option != "--matrix" and command in ("retrieval2d", "retrieval3d"):
            extra = ("--matrix", "{out}/D.npy")
        out += [
            Case(
                "missing folder",
                f"{command} {option}",
                (*argv, *extra, option, f"{{out}}/no/such/{good}"),
                clean=("{out}",),
            ),
            Case(
                "parent is a file",
                f"{command} {option}",
                (*argv, *extra, option, f"{{in}}/script.mlx/{good}"),
                clean=("{out}",),
            ),
            Case(
                "path is a folder", f"{command} {option}", (*argv, *extra, option, "{out}"), clean=("{out}",)
            ),
            Case(
                "read-only folder",
                f"{command} {option}",
                (*argv, *extra, option, f"{{ro}}/{good}"),
                clean=("{out}", "{ro}"),
                needs="ro",
            ),
        ]
    for command, argv in [
        ("match2d", ("match2d", a, b)),
        ("retrieval2d", ("retrieval2d", sil, "--matrix", "{out}/D.npy")),
    ]:
        out.append(
            Case(
                "unknown picture extension",
                f"{command} --plot p.xyz",
                (*argv, "--plot", "{out}/p.xyz"),
                clean=("{out}",),
            )
        )
    out += [
        Case(
            "second output fails",
            "match2d --out ok, --plot read-only",
            ("match2d", a, b, "--out", "{out}/pairs.csv", "--plot", "{ro}/fig.png"),
            clean=("{out}",),
            needs="ro",
        ),
        Case(
            "second output fails",
            "retrieval3d --matrix ok, --plot-pr into a file",
            (
                "retrieval3d",
                meshes,
                "--descriptor",
                "d2",
                "--backend",
                "serial",
                "--matrix",
                "{out}/D.npy",
                "--plot-pr",
                "{in}/script.mlx/pr.png",
            ),
            clean=("{out}",),
        ),
        Case(
            "two outputs, one file",
            "match2d --out X --plot X",
            ("match2d", a, b, "--out", "{out}/x.png", "--plot", "{out}/x.png"),
            clean=("{out}",),
        ),
        Case(
            "full disk",
            "retrieval2d --matrix + --plot on a full disk",
            ("retrieval2d", sil, "--backend", "serial", "--matrix", "{full}/D.npy", "--plot", "{full}/m.png"),
            clean=("{full}",),
            needs="full",
        ),
        Case(
            "full disk",
            "match2d --plot on a full disk",
            ("match2d", a, b, "--plot", "{full}/fig.png"),
            clean=("{full}",),
            needs="full",
        ),
        Case(
            "good outputs",
            "match2d --out and --plot",
            ("match2d", a, b, "--out", "{out}/p.csv", "--plot", "{out}/p.png"),
            expect=frozenset({0}),
        ),
    ]
    return out + _input_cases(sil, meshes, a, b, m0, m1)


def _input_cases(sil: str, meshes: str, a: str, b: str, m0: str, m1: str) -> list[Case]:
    """Defective meshes, native crashes, out-of-range options, wrong inputs, batches, full disks.

    Each row: (group, name, argv, folders that must stay clean, mount needed, expected exits).
    """
    defects, out, ro, full = "{in}/defects", ("{out}",), "{ro}", "{full}"
    emb = ("embed", m0, "-o", "{out}/e.ply")
    batch = ("correspond-batch", "{in}/pairs", "--pairs")
    ok = frozenset({0})
    rows = [
        *[("mesh defect → exact geodesics", f"embed {name}.off --geodesics exact",
           ("embed", f"{defects}/{name}.off", "-o", "{out}/e.ply", "--geodesics", "exact"), out, None, None)
          for name in ("duplicate_faces", "repeated_vertex", "nonmanifold_edge", "zero_area_face")],
        ("mesh defect, handled", "correspond zero_area_face.off m1.off",
         ("correspond", f"{defects}/zero_area_face.off", m1, "-o", "{out}/map.txt"), (), None, ok),
        ("mesh defect, handled", "embed coincident_vertices.off --geodesics heat",
         ("embed", f"{defects}/coincident_vertices.off", "-o", "{out}/e.ply", "--geodesics", "heat"),
         (), None, ok),
        ("native crash", "run: PyMeshLab decimation to -5 faces (SIGBUS inside PyMeshLab)",
         ("run", "-i", m0, "-s", "{in}/negative.mlx", "-o", "{out}/out.ply"), out, None, None),
        ("native crash avoided", "run: exact-geodesic filter on a mesh with duplicate faces",
         ("run", "-i", f"{defects}/duplicate_faces.off", "-s", "{in}/exact_geodesics.mlx",
          "-o", "{out}/o.ply"),
         out, None, None),
        ("option out of range", "embed --seed -1", (*emb, "--seed", "-1"), out, None, None),
        ("option out of range", "embed --sigma 1e-300", (*emb, "--sigma", "1e-300"), out, None, None),
        ("option out of range", "embed --dims 200 on a 162-vertex mesh", (*emb, "--dims", "200"), out,
         None, None),
        ("option out of range", "match2d --n-points 100000", ("match2d", a, b, "--n-points", "100000"),
         (), None, None),
        ("option out of range", "retrieval2d --n-jobs 0",
         ("retrieval2d", sil, "--matrix", "{out}/D.npy", "--n-jobs", "0"), out, None, None),
        ("option out of range", "retrieval3d --rerank-k 0",
         ("retrieval3d", meshes, "--descriptor", "d2", "--matrix", "{out}/D.npy", "--rerank-k", "0"),
         out, None, None),
        ("option out of range", "index query --rerank-k -1",
         ("index", "query", "{in}/index.db", m0, "--rerank-k", "-1"), (), None, None),
        ("wrong kind of input", "correspond DIR m1.off", ("correspond", meshes, m1, "-o", "{out}/map.txt"),
         out, None, None),
        ("wrong kind of input", "index add into a file that is not an index",
         ("index", "add", "{in}/script.mlx", meshes, "--descriptor", "d2"), (), None, None),
        ("labels", "retrieval2d: a labels.csv row without a label",
         ("retrieval2d", "{in}/sil_unlabelled", "--matrix", "{out}/D.npy"), out, None, None),
        ("batch", "correspond-batch: two pairs would write one map",
         (*batch, "colliding.csv", "--out-dir", "{out}/maps"), out, None, None),
        ("batch", "correspond-batch: a one-column row in pairs.csv",
         (*batch, "one_column.csv", "--out-dir", "{out}/maps"), out, None, None),
        ("batch", "correspond-batch --out-dir is a file",
         (*batch, "colliding.csv", "--out-dir", "{in}/script.mlx"), (), None, None),
        ("batch", "correspond-batch --out-dir in a read-only folder",
         (*batch, "colliding.csv", "--out-dir", f"{ro}/maps"), (ro,), "ro", None),
        ("gen", "gen decimate --out in a read-only folder",
         ("gen", "decimate", m0, "--ratios", "0.5", "--out", f"{ro}/ladder"), (ro,), "ro", None),
        ("gen", "run --save-script into a read-only folder",
         ("run", "-i", m0, "-s", "{in}/script.mlx", "-o", "{out}/o.ply", "--save-script", f"{ro}/used.mlx"),
         ("{out}", ro), "ro", None),
        ("full disk", "embed on a full disk", ("embed", m0, "-o", f"{full}/e.ply"), (full,), "full", None),
        ("full disk", "index add into a database on a full disk",
         ("index", "add", f"{full}/idx.db", meshes, "--descriptor", "d2", "--backend", "serial"),
         (full,), "full", None),
    ]
    done_or_refused = frozenset({0, 2})  # a defect is repaired, tolerated or refused: never a crash
    defect_names = ("duplicate_faces", "repeated_vertex", "nonmanifold_edge", "zero_area_face",
                    "coincident_vertices")
    for name in defect_names:
        mesh = f"{defects}/{name}.off"
        for command, argv in (
            ("info", ("info", mesh)),
            ("embed", ("embed", mesh, "-o", "{out}/e.ply")),
            ("correspond", ("correspond", mesh, m1, "-o", "{out}/map.txt")),
            ("gen spikes", ("gen", "spikes", mesh, "--count", "3", "--height", "0.1",
                            "--out", "{out}/s.off")),
            ("gen stretch", ("gen", "stretch", mesh, "--scale", "1.5,1,1", "--out", "{out}/s.off")),
            ("gen decimate", ("gen", "decimate", mesh, "--ratios", "0.5", "--out", "{out}/d")),
            ("run", ("run", "-i", mesh, "-s", "{in}/script.mlx", "-o", "{out}/o.ply")),
        ):
            rows.append(("mesh defect × every mesh command", f"{command} {name}.off", argv, (), None,
                         done_or_refused))
    return [Case(group, name, argv, expect=expect or frozenset({2}), clean=clean, needs=needs)
            for group, name, argv, clean, needs, expect in rows]


@contextlib.contextmanager
def _mounted(folder: Path, options: str):
    """Mount a tmpfs at ``folder`` (yield True), or yield False where mounting is not allowed."""
    folder.mkdir(parents=True, exist_ok=True)
    if sys.platform != "linux" or os.geteuid() != 0:
        yield False
        return
    done = (
        subprocess.run(
            ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)], capture_output=True
        ).returncode
        == 0
    )
    try:
        yield done
    finally:
        if done:
            subprocess.run(["umount", "-l", str(folder)], capture_output=True)


def _fill(folder: Path) -> None:
    """Fill a small tmpfs until no block is left."""
    with contextlib.suppress(OSError), open(folder / "filler", "wb") as fh:
        while True:
            fh.write(b"\0" * 4096)
            fh.flush()


def run_cases(selected: list[Case] | None = None, *, progress=None) -> list[Outcome]:
    """Run ``selected`` cases (default all) and judge each; see the module docstring."""
    selected = cases() if selected is None else selected
    results = []
    with tempfile.TemporaryDirectory(prefix="geoshape-reliability-") as tmp:
        root = Path(tmp)
        (root / "in").mkdir()
        _inputs(root / "in")
        with _mounted(root / "ro", "ro,size=64k") as ro, _mounted(root / "full", "size=32k") as full:
            for case in selected:
                if progress:
                    progress(case)
                if (case.needs == "ro" and not ro) or (case.needs == "full" and not full):
                    results.append(
                        Outcome(case, "skipped", message=f"cannot mount a {case.needs} tmpfs here")
                    )
                    continue
                out = root / "out"
                out.mkdir()
                if full:
                    for f in (root / "full").iterdir():
                        f.unlink()
                    _fill(root / "full")
                places = {
                    "{in}": str(root / "in"),
                    "{out}": str(out),
                    "{ro}": str(root / "ro"),
                    "{full}": str(root / "full"),
                }
                fill_in = functools.partial(_fill_in, places=places)
                done = _geoshape(*[fill_in(x) for x in case.argv])
                outcome = _judge(case, done, [Path(fill_in(c)) for c in case.clean])
                outcome.message = outcome.message.replace(str(root), "…")
                results.append(outcome)
                for f in sorted(out.rglob("*"), reverse=True):
                    f.unlink() if f.is_file() else f.rmdir()
                out.rmdir()
    return results


def _fill_in(text: str, places: dict[str, str]) -> str:
    for key, value in places.items():
        text = text.replace(key, value)
    return text


def _judge(case: Case, done: subprocess.CompletedProcess, clean: list[Path]) -> Outcome:
    problems = []
    code = done.returncode
    if code < 0:
        problems.append(f"killed by signal {-code}")
    elif code not in case.expect:
        problems.append(f"exit {code}, expected {'/'.join(map(str, sorted(case.expect)))}")
    if "Traceback" in done.stderr or "Fatal Python error" in done.stderr:
        problems.append("traceback")
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    if code == 2 and len(lines) != 1:
        problems.append(f"{len(lines)} lines on stderr, expected one")
    for folder in clean:
        left = (
            [p.name for p in folder.rglob("*") if p.is_file() and p.name != "filler"]
            if folder.is_dir()
            else []
        )
        if left:
            problems.append(f"left {', '.join(sorted(left))}")
    message = lines[-1] if lines else ""
    return Outcome(case, "FAIL" if problems else "ok", code, message, problems)


def markdown(results: list[Outcome]) -> str:
    from geoshape.bench.results import markdown_table

    rows = [
        [
            o.case.group,
            f"`{o.case.name}`",
            "/".join(map(str, sorted(o.case.expect))),
            "—" if o.exit_code is None else o.exit_code,
            o.status + (": " + "; ".join(o.problems) if o.problems else ""),
            o.message.replace("|", "\\|")[:140],
        ]
        for o in results
    ]
    counts = {s: sum(o.status == s for o in results) for s in ("ok", "FAIL", "skipped")}
    return (
        "## Reliability: bad output paths, a full disk, defective meshes, native crashes, bad options\n\n"
        "Command: `geoshape bench reliability`. Each row is one `geoshape` command line run in its own "
        "subprocess on small generated inputs; it passes when it exits with the expected status, prints "
        "no traceback (one line on stderr for exit 2), is not killed by a signal, and leaves no file in "
        "the output folders it was given. Read-only folders and the full disk are real tmpfs mounts "
        "(32 KiB, filled before each case). "
        f"Result: {counts['ok']} ok, {counts['FAIL']} failed, {counts['skipped']} skipped.\n\n"
        + markdown_table(
            ["case", "command", "expected exit", "exit", "verdict", "message (last stderr line)"], rows
        )
    )


def add_arguments(parser) -> None:
    parser.add_argument("--no-write", action="store_true", help="print only; do not write docs/RESULTS.md")


def run(args) -> int:
    from geoshape.bench.results import update_results_section

    results = run_cases(progress=lambda c: print(f"[{c.group}] {c.name}", file=sys.stderr))
    text = markdown(results)
    print(text)
    if not args.no_write:
        update_results_section("reliability", text)
    return 1 if any(o.status == "FAIL" for o in results) else 0
