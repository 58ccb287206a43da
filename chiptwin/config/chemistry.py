"""``[assay] chemistry``: a named preset of the flow-value model, applied to the raw table.

The preset's values (:data:`chiptwin.kinetics.chemistry_presets.PRESETS`) fill the ``[assay]``
keys the scene does not give; a key the scene gives (or a ``--set`` override) wins. An unknown
name is left for the field check, which refuses it naming the key, the value and the allowed
names.
"""

from __future__ import annotations

from typing import Any

from chiptwin.config.schema import CHEMISTRIES


def with_chemistry(raw: dict[str, Any]) -> dict[str, Any]:
    """``raw`` with its chemistry preset's values under the scene's own (a copy; ``raw``
    itself when it names none)."""
    assay = raw.get("assay")
    if not isinstance(assay, dict):
        return raw
    name = assay.get("chemistry", "")
    if not isinstance(name, str) or not name or name not in CHEMISTRIES:
        return raw
    from chiptwin.kinetics.chemistry_presets import preset_values

    return {**raw, "assay": {**preset_values(name), **assay}}
