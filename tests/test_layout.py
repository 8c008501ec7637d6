"""The house rules of docs/architecture.md: imports flow one way, packages install under
specific names, and every module says in its first docstring line what it holds."""

from __future__ import annotations

import ast
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import tomllib

ROOT = Path(__file__).resolve().parents[1]

#: Rank of each part of the library: a module may import only from lower ranks or its own
#: package. Shared helpers (rank 0) may use each other, and so may the layers on top (TOP);
#: parts of one rank in between (2D contour vs 3D correspondence) stay independent.
TOP = 8
RANK = {
    "__init__": 0, "errors": 0, "_options": 0, "distances": 0, "parallel": 0,
    "io": 1,
    "geometry": 2,
    "spectral": 3, "metrics": 3,
    "contour": 4, "correspondence": 4,
    "retrieval": 5,
    "plot": 6,
    "viewer": 7,  # HTML pages, with the colours of plot
    "cli": TOP, "bench": TOP, "__main__": TOP,
}
TOP_LAYERS = {"geoshape_plugins": TOP, "geoshape_datasets_gen": TOP}


def _part(module: str) -> str | None:
    """The library part of a dotted module name (``geoshape.io.mesh_io`` → ``io``)."""
    head, _, rest = module.partition(".")
    if head in TOP_LAYERS:
        return head
    if head != "geoshape":
        return None
    return rest.split(".")[0] if rest else "__init__"


def _imports(path: Path) -> list[tuple[int, str]]:
    """Every absolute import of a file, also those inside functions (line, module)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.lineno, node.module))
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
    return out


def _library_files():
    return sorted((ROOT / "geoshape").rglob("*.py"))


def test_every_library_part_has_a_rank():
    parts = {p.relative_to(ROOT / "geoshape").with_suffix("").parts[0] for p in _library_files()}
    assert parts <= set(RANK), f"parts without a rank in this test: {sorted(parts - set(RANK))}"


def test_imports_flow_one_way():
    wrong = []
    for path in _library_files():
        own = path.relative_to(ROOT / "geoshape").with_suffix("").parts[0]
        for line, module in _imports(path):
            target = _part(module)
            if target is None or target == own:
                continue
            rank = RANK.get(target, TOP_LAYERS.get(target))
            if rank is None or rank > RANK[own] or (rank == RANK[own] and rank not in (0, TOP)):
                wrong.append(f"{path.relative_to(ROOT)}:{line} ({own}) imports {module} ({target})")
    assert not wrong, "imports against the layering of docs/architecture.md:\n" + "\n".join(wrong)


def test_plugins_and_generators_do_not_import_the_command_line():
    wrong = []
    for folder in ("plugins", "datasets_gen"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            for line, module in _imports(path):
                if _part(module) in ("cli", "bench", "__main__"):
                    wrong.append(f"{path.relative_to(ROOT)}:{line} imports {module}")
    assert not wrong, "\n".join(wrong)


def test_every_module_starts_with_a_docstring():
    missing = []
    for folder in ("geoshape", "plugins", "datasets_gen"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
            if not doc or len(doc.splitlines()[0].split()) < 3:
                missing.append(str(path.relative_to(ROOT)))
    assert not missing, f"modules without a first docstring line saying what they hold: {missing}"


def test_pyproject_lists_every_package_under_its_installed_name():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    listed = set(config["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "geoshape").rglob("__init__.py")}
    found |= set(config["package-dir"])
    assert listed == found, f"missing: {sorted(found - listed)}, stale: {sorted(listed - found)}"
    assert config["package-dir"] == {"geoshape_plugins": "plugins", "geoshape_datasets_gen": "datasets_gen"}


@pytest.mark.slow
def test_wheel_installs_specific_names_only(tmp_path):
    """The wheel holds geoshape, geoshape_plugins and geoshape_datasets_gen (with py.typed),
    and no generic top-level ``plugins`` or ``datasets_gen``."""
    result = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(ROOT)],
        capture_output=True, text=True, timeout=600,
    )
    if result.returncode != 0 and "No matching distribution" in result.stderr:
        pytest.skip("cannot build a wheel here: the build backend cannot be installed")
    assert result.returncode == 0, result.stderr[-2000:]
    (wheel,) = tmp_path.glob("geoshape-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith((".dist-info", ".data"))}
    assert tops == {"geoshape", "geoshape_plugins", "geoshape_datasets_gen"}
    assert "geoshape/py.typed" in names
    assert "geoshape/correspondence/fmaps/zoomout.py" in names
    assert "geoshape_plugins/meshset.py" in names
    # the viewer's package data: its page and the three.js files it inlines
    assert {"geoshape/viewer/template.html", "geoshape/viewer/vendor/three.min.js",
            "geoshape/viewer/vendor/OrbitControls.js", "geoshape/viewer/vendor/LICENSE"} <= set(names)
    # the plugins' recorded PyMeshLab table (display names, XML names, fresh defaults)
    assert "geoshape_plugins/data/pymeshlab_filters.json" in names
