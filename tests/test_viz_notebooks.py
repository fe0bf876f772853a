"""Every committed notebook carries its figures (a code host renders them unrun)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))
#: Calls that draw a figure in a cell's own code (not inside a function definition).
DRAWS = ("plt.subplots(", "plot_plan(", "plot_gantt(", "plot_instance(", "plot_runtime_table(",
         "plot_layers(", "plot_distance(", "plot_cactus(", "Figure(")  # fmt: skip


def _images(cell: dict) -> int:
    return sum("image/png" in out.get("data", {}) for out in cell.get("outputs", []))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_outputs_include_its_figures(path: Path) -> None:
    cells = [c for c in json.loads(path.read_text())["cells"] if c["cell_type"] == "code"]
    drawing = []
    for i, c in enumerate(cells):
        src = "".join(c["source"])
        top = "\n".join(ln for ln in src.splitlines() if not ln.startswith((" ", "\t", "def ")))
        if any(d in top for d in DRAWS) or any(d in src for d in DRAWS if "fig" in top):
            drawing.append(i)
    assert drawing, f"{path.name}: no cell draws a figure (is DRAWS out of date?)"
    missing = [i for i in drawing if _images(cells[i]) == 0]
    assert not missing, f"{path.name}: code cells {missing} draw figures but hold no image output"
