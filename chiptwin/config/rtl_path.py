"""Where the ``rtl_ref`` package is: installed beside chiptwin, or at the root of a source
checkout (an editable install lists only chiptwin's packages).

The reference RTL sits above the DSP it verifies (``rtl_ref`` imports ``chiptwin.dsp``), so only
the layers above it import it: the twin (:mod:`chiptwin.twin.rtl`, the ``rtl`` DSP level) and
the scenario checks (:mod:`chiptwin.config.consistency`), both through this module, which imports
nothing of it: it only makes it importable.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path


def make_importable() -> None:
    """Put the source checkout's root on ``sys.path`` when ``rtl_ref`` is not installed.

    Raises
    ------
    ModuleNotFoundError
        Neither installed nor in a checkout beside this package.
    """
    if importlib.util.find_spec("rtl_ref") is not None:
        return
    root = Path(__file__).resolve().parents[2]
    if not (root / "rtl_ref" / "__init__.py").is_file():
        raise ModuleNotFoundError(
            "the rtl DSP level needs the rtl_ref package of the chiptwin source tree"
        )
    sys.path.insert(0, str(root))
