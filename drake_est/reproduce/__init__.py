"""Registry of thesis reproductions for ``drake-est reproduce NAME``.

Each module in this package defines ``EXPERIMENTS = {"name": func}`` where
``func(out_dir: Path, quick: bool = False, seed: int = 0, **kw) -> dict`` writes
PNG figures under ``out_dir`` and returns the numbers (JSON-serializable) that
the CLI saves as ``out_dir/NAME.json``.
"""
from __future__ import annotations

import importlib
import pkgutil


def experiments() -> dict:
    found = {}
    for info in pkgutil.iter_modules(__path__):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{__name__}.{info.name}")
        for name, func in getattr(mod, "EXPERIMENTS", {}).items():
            if name in found:
                raise RuntimeError(f"duplicate experiment name {name!r} in {info.name}")
            found[name] = func
    return found
