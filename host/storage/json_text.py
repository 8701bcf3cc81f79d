"""The one rule of the JSON documents ``gaitlog`` prints (``--json``): numpy values as numbers and lists, NaN and
infinities as ``null`` (valid JSON), other objects as their text; indented by two."""

from __future__ import annotations

import json
import math


def json_text(doc: object) -> str:
    """``doc`` as an indented JSON document (no trailing newline) by the rule of this module."""
    return json.dumps(json_ready(doc), indent=2, allow_nan=False)


def json_ready(value: object) -> object:
    """``value`` with numpy scalars and arrays as Python numbers and lists, non-finite floats as None."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if hasattr(value, "tolist"):                    # numpy arrays and scalars
        return json_ready(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value if isinstance(value, (str, int, float, bool, type(None))) else str(value)
