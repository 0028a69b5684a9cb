"""Plain-JSON conversion of results (numpy arrays and scalars, paths, NaN -> null).

numpy objects are recognised by their ``dtype`` and ``tolist`` instead of by
``isinstance``, so that this module (imported by the command line for every
command) does not import numpy: that import is 0.17 s of the 0.2 s CPU that
``labid --help`` would otherwise cost (``bench/bench_cli.py``).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any


def to_jsonable(obj: Any) -> Any:
    """``obj`` with numpy arrays/scalars as lists/numbers, paths as str, non-finite floats as None."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if hasattr(obj, "dtype") and hasattr(obj, "tolist"):   # numpy array or scalar
        return to_jsonable(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj
