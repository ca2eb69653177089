"""Import a script of ``bench/`` as a module (its directory on ``sys.path`` while it loads, for its own
imports of the other bench scripts)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

BENCH = Path(__file__).resolve().parents[2] / "bench"


def load_bench(name: str) -> ModuleType:
    path = BENCH / f"{name}.py"
    sys.path.insert(0, str(BENCH))
    try:
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None
        assert spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up while the script loads
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCH))
    return module
