"""TOML text of plain values: what a study writes back as a file a user can run again
(``calibrated.toml`` of a calibration, ``study.toml`` of a what-if)."""

from __future__ import annotations

import json
import math
import re
from typing import Any


def toml_key(k: str) -> str:
    """A bare key where TOML allows one, else a quoted one (``"sites.at_pixels"``)."""
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k, ensure_ascii=False)


def toml_value(v: Any) -> str:
    """A TOML value: booleans, numbers (nan and ±inf as TOML spells them), strings, arrays and
    inline tables."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else
                                                 ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return ("{ " + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items())
                + " }") if v else "{}"
    raise TypeError(f"no TOML form for {v!r}")
