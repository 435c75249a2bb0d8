"""Import layers and circles (import-linter contracts in pyproject.toml).

The contracts: in ``zwcore`` the planners sit over the MRR and the arcs, those
over the grid, the grid over the errors; ``zwcore`` never imports the service or
the web stack; the service's app over its routers over the request plumbing over
its parts; private modules stay inside their capability; no import circles
between sibling modules, deferred imports included.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT = [sys.executable, "-c", "import sys; from importlinter.cli import lint_imports_command;"
        " sys.exit(lint_imports_command())", "--no-cache"]


def _lint(tree: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*LINT, "--config", str(tree / "pyproject.toml")], cwd=tree,
                          env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"},
                          capture_output=True, text=True, timeout=120)


def test_the_contracts_hold() -> None:
    run = _lint(ROOT)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "0 broken" in run.stdout


@pytest.fixture
def copy(tmp_path: Path) -> Path:
    for name in ("zwcore", "service"):
        shutil.copytree(ROOT / name, tmp_path / name,
                        ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    return tmp_path


@pytest.mark.parametrize(("module", "planted", "contract"), [
    ("zwcore/grid/zmap.py", "import zwcore.scanline.planner", "zwcore layers"),
    ("zwcore/mrr/wavelets.py", "import service.settings", "knows nothing of the service"),
    ("zwcore/contour/planner.py", "from zwcore.scanline import _passes", "private modules"),
    ("service/problems.py", "from service.deps import get_pool", "service layers"),
    ("zwcore/arcs/_geometry.py", "import zwcore.arcs.gcode", "no import circles"),
])
def test_a_planted_import_breaks_its_contract(copy: Path, module: str, planted: str,
                                              contract: str) -> None:
    path = copy / module
    text = path.read_text()
    # Planted after the module's docstring and __future__ import, inside a function
    # where it would hide a circle at import time.
    path.write_text(text + f"\n\ndef _planted() -> None:\n    {planted}  # noqa\n")
    run = _lint(copy)
    assert run.returncode != 0, run.stdout
    broken = [line for line in run.stdout.splitlines() if line.endswith("BROKEN")]
    assert any(contract in line for line in broken), run.stdout
