"""The generated large-fleet instances load, and their generator reproduces them."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from hierplan_opt.io.movingai import load_movingai

ROOT = Path(__file__).resolve().parents[1]
LARGE = ROOT / "instances" / "large"
FILES = ["empty-64-64.map", "empty-64-64-gen-1.scen", "warehouse-10-20-10-2-1-gen-1.scen"]


def test_they_load_with_all_agents():
    empty = load_movingai(LARGE / "empty-64-64.map", LARGE / "empty-64-64-gen-1.scen")
    assert empty.num_agents == 2000 and empty.graph.num_vertices == 64 * 64
    wh = load_movingai(
        ROOT / "instances" / "movingai" / "warehouse-10-20-10-2-1.map",
        LARGE / "warehouse-10-20-10-2-1-gen-1.scen",
    )
    assert wh.num_agents == 1000


@pytest.mark.slow
def test_generator_reproduces_the_files(tmp_path, monkeypatch):
    spec = importlib.util.spec_from_file_location("large_generate", LARGE / "generate.py")
    assert spec is not None and spec.loader is not None
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    monkeypatch.setattr(gen, "HERE", tmp_path)
    gen.main()
    for name in FILES:
        assert (tmp_path / name).read_bytes() == (LARGE / name).read_bytes(), name
