"""The notebooks: generated from notebooks/_build.py, and every code cell runs.

Each notebook's code cells are executed in order in one fresh namespace with
matplotlib's Agg backend and ``notebooks/`` as the working directory (as Jupyter runs
them); any exception fails the test. The notebooks contain their own assertions
(optima agree, ECBS within its bound, replay distance >= guaranteed distance, ...).
"""

from __future__ import annotations

import base64
import importlib.util
import json
import time
from pathlib import Path

import pytest

NOTEBOOK_DIR = Path(__file__).resolve().parent.parent / "notebooks"


def _load_build():  # noqa: ANN202
    spec = importlib.util.spec_from_file_location("_nb_build", NOTEBOOK_DIR / "_build.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


build = _load_build()
NAMES = list(build.NOTEBOOKS)


def _run(name: str, sources: list[str] | None = None) -> float:
    if sources is None:
        sources = build.code_cells(NOTEBOOK_DIR / f"{name}.ipynb")
    t0 = time.perf_counter()
    build.run_cells(sources, cwd=NOTEBOOK_DIR, label=name, capture=False)
    return time.perf_counter() - t0


@pytest.mark.parametrize("name", NAMES)
def test_notebook_file_matches_build_script(name: str) -> None:
    path = NOTEBOOK_DIR / f"{name}.ipynb"
    assert path.exists(), f"run python notebooks/_build.py --execute ({path.name} missing)"
    assert path.stat().st_size < build.MAX_BYTES
    nb = json.loads(path.read_text(encoding="utf-8"))
    assert nb["nbformat"] == 4 and nb["nbformat_minor"] >= 4
    assert build.cell_sources(path) == list(build.NOTEBOOKS[name]), (
        f"{path.name} is stale: run python notebooks/_build.py --execute"
    )
    ids = [c["id"] for c in nb["cells"]]
    assert len(set(ids)) == len(ids)
    for cell in nb["cells"]:
        if cell["cell_type"] != "code":
            continue
        for out in cell["outputs"]:
            assert out["output_type"] in ("stream", "display_data", "execute_result")
            png = out.get("data", {}).get("image/png")
            if png is not None:
                assert base64.b64decode(png)[:8] == b"\x89PNG\r\n\x1a\n"


def test_check_mode_reports_stale_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(build, "HERE", tmp_path)
    assert build.main(["--check", "--only", "mapf_post"]) == 1  # no file there yet
    build.write_notebook("mapf_post")
    assert build.main(["--check", "--only", "mapf_post"]) == 0
    nb = json.loads((tmp_path / "mapf_post.ipynb").read_text())
    nb["cells"][-1]["source"] = ["print('edited by hand')\n"]
    (tmp_path / "mapf_post.ipynb").write_text(json.dumps(nb))
    assert build.main(["--check", "--only", "mapf_post"]) == 1


def test_run_cells_stores_text_figures_and_fails_loudly() -> None:
    outs = build.run_cells(
        [
            "import matplotlib.pyplot as plt\nx = 6 * 7\nprint('x =', x)",
            "fig, ax = plt.subplots()\nax.plot([0, 1], [1, 0])\nx + 1",
        ],
        label="t",
    )
    assert outs[0] == [{"output_type": "stream", "name": "stdout", "text": ["x = 42\n"]}]
    kinds = [o["output_type"] for o in outs[1]]
    assert kinds == ["execute_result", "display_data"]
    assert outs[1][0]["data"]["text/plain"] == ["43"]
    with pytest.raises(build.CellError, match=r"t, code cell 2 raised ZeroDivisionError") as err:
        build.run_cells(["y = 1", "print('before')\n1 / 0"], label="t")
    assert "before" in str(err.value) and "1 / 0" in str(err.value)  # output and source line


def test_allow_errors_stores_the_error_and_goes_on() -> None:
    outs = build.run_cells(
        ["print('a')\nassert 1 == 2, 'mismatch'", "print('b')"], label="t", allow_errors=True
    )
    assert [o["output_type"] for o in outs[0]] == ["stream", "error"]
    assert outs[0][1]["ename"] == "AssertionError" and outs[0][1]["evalue"] == "mismatch"
    assert outs[1] == [{"output_type": "stream", "name": "stdout", "text": ["b\n"]}]


@pytest.mark.parametrize("name", NAMES)
def test_notebook_runs(name: str) -> None:
    # Each takes 2-15 s on an idle 2-core machine (up to ~45 s for solver_comparison
    # when six other jobs share it), so none is marked slow.
    _run(name)
