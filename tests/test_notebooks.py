"""The notebooks: paired jupytext files, executed by nbclient in a real Jupyter kernel.

Each notebook is kept twice: ``notebooks/NAME.py`` (jupytext percent format, the file to
review and edit) and ``notebooks/NAME.ipynb`` (the same cells with their outputs, for a
code host to render). The tests check that each pair holds the same cells and execute
every ``.py`` in an IPython kernel started from this test's own Python (a kernelspec
written to a temporary folder, so no user-wide kernel is needed or used), with
``HIERPLAN_NOTEBOOK_SMALL=1`` for smaller live examples. The notebooks assert their own
claims, so a notebook that stops working fails here.
"""

from __future__ import annotations

import base64
import json
import sys
from pathlib import Path

import jupytext
import nbformat
import pytest
from jupyter_client.kernelspec import KernelSpecManager
from jupyter_client.manager import KernelManager
from nbclient import NotebookClient

NOTEBOOK_DIR = Path(__file__).resolve().parent.parent / "notebooks"
NAMES = sorted(p.stem for p in NOTEBOOK_DIR.glob("*.py"))
MAX_BYTES = 1_000_000  # outputs stay small: figures at low resolution
KERNEL = "hierplan-test"


def test_every_notebook_is_a_pair() -> None:
    pys = {p.stem for p in NOTEBOOK_DIR.glob("*.py")}
    ipynbs = {p.stem for p in NOTEBOOK_DIR.glob("*.ipynb")}
    assert pys == ipynbs and len(pys) >= 4, (pys, ipynbs)


def _sources(nb: nbformat.NotebookNode) -> list[tuple[str, str]]:
    return [(c.cell_type, c.source.strip()) for c in nb.cells]


@pytest.mark.parametrize("name", NAMES)
def test_pair_holds_the_same_cells(name: str) -> None:
    py = jupytext.read(NOTEBOOK_DIR / f"{name}.py")
    ipynb_path = NOTEBOOK_DIR / f"{name}.ipynb"
    assert ipynb_path.stat().st_size < MAX_BYTES
    ipynb = nbformat.read(ipynb_path, as_version=4)
    nbformat.validate(ipynb)
    assert _sources(py) == _sources(ipynb), (
        f"{name}.ipynb differs from {name}.py: run `jupytext --sync notebooks/{name}.py`"
    )
    assert py.metadata["jupytext"]["formats"] == "ipynb,py:percent"
    for cell in ipynb.cells:
        for out in cell.get("outputs", []):
            assert out["output_type"] != "error", f"{name}.ipynb stores an error"
            png = out.get("data", {}).get("image/png")
            if png is not None:
                assert base64.b64decode(png)[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def kernel_specs(tmp_path_factory: pytest.TempPathFactory) -> KernelSpecManager:
    """A kernelspec for this interpreter in a private folder (no user-wide kernels)."""
    folder = tmp_path_factory.mktemp("kernels") / KERNEL
    folder.mkdir()
    spec = {
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "hierplan_opt tests",
        "language": "python",
    }
    (folder / "kernel.json").write_text(json.dumps(spec))
    ksm = KernelSpecManager()
    ksm.kernel_dirs = [str(folder.parent)]
    ksm.ensure_native_kernel = False
    return ksm


@pytest.mark.parametrize("name", NAMES)
def test_notebook_executes(
    name: str, kernel_specs: KernelSpecManager, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("HIERPLAN_NOTEBOOK_SMALL", "1")
    monkeypatch.delenv("MPLBACKEND", raising=False)  # the kernel's inline backend draws
    nb = jupytext.read(NOTEBOOK_DIR / f"{name}.py")
    km = KernelManager(kernel_name=KERNEL, kernel_spec_manager=kernel_specs)
    assert km.kernel_spec is not None and km.kernel_spec.argv[0] == sys.executable
    client = NotebookClient(
        nb, km=km, timeout=600, resources={"metadata": {"path": str(NOTEBOOK_DIR)}}
    )
    try:
        client.execute()  # raises CellExecutionError (with the cell and traceback) on failure
    finally:
        km.shutdown_kernel(now=True)  # nbclient leaves a kernel manager it was given running
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code and all(c.execution_count for c in code)


def test_a_failing_cell_fails_the_run(kernel_specs: KernelSpecManager) -> None:
    from nbclient.exceptions import CellExecutionError

    nb = jupytext.reads("# %%\nx = 1\n\n# %%\nassert x == 2, 'claim broken'\n", fmt="py:percent")
    km = KernelManager(kernel_name=KERNEL, kernel_spec_manager=kernel_specs)
    with pytest.raises(CellExecutionError, match="claim broken"):
        try:
            NotebookClient(nb, km=km, timeout=60).execute()
        finally:
            km.shutdown_kernel(now=True)
