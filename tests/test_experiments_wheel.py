"""Canned sweeps and ``hierplan bench`` work from an installed wheel, not only a checkout.

The slow test builds a wheel from a copy of the repository, installs it (without its
dependencies, which it borrows from this environment through a ``.pth`` file) into a
fresh virtual environment, and runs a canned sweep and a benchmark from a folder outside
the checkout. The fast test checks that the package-data patterns in pyproject.toml
cover every file a canned spec names.
"""

from __future__ import annotations

import shutil
import site
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

from hierplan_opt.experiments import data
from hierplan_opt.experiments.spec import load_spec

ROOT = Path(__file__).resolve().parents[1]


def test_package_data_covers_the_canned_specs_and_their_instances() -> None:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    patterns = cfg["package-data"]
    pkg = ROOT / "hierplan_opt"
    shipped = {p.resolve() for pat in patterns["hierplan_opt"] for p in pkg.glob(pat)}
    shipped |= {
        p.resolve()
        for pat in patterns["hierplan_opt.experiments"]
        for p in pkg.glob(f"experiments/{pat}")
    }
    for name in data.canned_specs():
        spec_file = data.canned_spec(name)
        assert spec_file.resolve() in shipped, spec_file
        for inst in load_spec(spec_file).instances:
            for f in inst.files:
                assert f.resolve() in shipped, f"{name}: {f} is not package data"


def test_package_data_covers_the_bench_instances() -> None:
    """The files ``hierplan bench`` reads (lacam, trajectory, post) are package data."""
    from hierplan_opt.bench import lacam, post, trajectory

    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    pkg = ROOT / "hierplan_opt"
    shipped = {p.resolve() for pat in cfg["package-data"]["hierplan_opt"] for p in pkg.glob(pat)}
    files = [f for pair in lacam.CASES.values() for f in pair]
    files += [
        data.shipped_file(name)
        for name in (
            trajectory.WAREHOUSE_MAP,
            trajectory.WAREHOUSE_SCEN,
            "instances/paper/formation-usc.yaml",
            post.DEFAULT_MAP,
            post.DEFAULT_SCEN,
        )
    ]
    for f in files:
        assert f.is_relative_to(pkg / "data") and f.resolve() in shipped, f


@pytest.mark.slow
def test_canned_sweep_and_bench_run_from_an_installed_wheel(tmp_path: Path) -> None:
    src = tmp_path / "src"
    shutil.copytree(
        ROOT,
        src,
        symlinks=True,  # hierplan_opt/data stays a link to instances/, as in a checkout
        ignore=shutil.ignore_patterns(".venv", ".git", "build", "dist", "*.egg-info", "*.sqlite"),
    )
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps",
         "-w", str(tmp_path / "dist"), str(src)],
        check=True,
    )  # fmt: skip
    (wheel,) = (tmp_path / "dist").glob("hierplan_opt-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "hierplan_opt/data/movingai/random-32-32-20.map" in names
    assert "hierplan_opt/experiments/specs/cbs-quick.yaml" in names
    assert "hierplan_opt/experiments/specs/post-quick.yaml" in names
    assert "hierplan_opt/data/large/empty-64-64-gen-1.scen" in names

    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    purelib = subprocess.run(
        [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True, capture_output=True, text=True,
    ).stdout.strip()  # fmt: skip
    subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(py), "install", "-q", "--no-deps",
         "--no-index", str(wheel)],
        check=True,
    )  # fmt: skip
    # the dependencies come from this environment, after the wheel's own files
    (Path(purelib) / "deps.pth").write_text("\n".join(site.getsitepackages()) + "\n")

    work = tmp_path / "elsewhere"
    work.mkdir()
    where = subprocess.run(
        [str(py), "-c", "import hierplan_opt; print(hierplan_opt.__file__)"],
        cwd=work, check=True, capture_output=True, text=True,
    ).stdout  # fmt: skip
    assert where.startswith(purelib), where
    hierplan = [str(venv / "bin" / "hierplan")]
    res = subprocess.run(
        [*hierplan, "-q", "sweep", "--canned", "cbs-quick"],
        cwd=work, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "4 runs (0 re-used, 4 run, 0 skipped)" in res.stdout and "OPTIMAL 4" in res.stdout
    assert (work / "cbs-quick.sqlite").exists()  # in the working folder, not the package
    res = subprocess.run(
        [*hierplan, "bench", "cbs", "--instance", "empty-8-8-even-1:4"],
        cwd=work, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "OPTIMAL" in res.stdout
    # the areas that read more than MovingAI samples: generated scenarios, paper instances
    for area in (
        ["lacam", "--quick", "--instance", "first:random-32-32-10-random-1:20"],
        ["formulations", "--sizes-only", "--maps", "room-32-32-4", "--agents", "2"],
        ["post", "--quick", "--agents", "20", "--fleet", "0"],
    ):
        res = subprocess.run(
            [*hierplan, "bench", *area], cwd=work, capture_output=True, text=True, timeout=600
        )
        assert res.returncode == 0, (area, res.stderr[-2000:])
        assert " ERROR " not in res.stdout, (area, res.stdout[-2000:])  # rows of failed runs
