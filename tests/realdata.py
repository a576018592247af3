"""Files saved by real instruments and published by others, which the repository does not hold.

Each folder's README under ``tests/data/`` names its files with their source, licence and
digest. The tests read them from ``$VISCORIG_REAL_DATA/<kind>``, else from
``shared/data/<kind>`` beside the checkout, and are skipped where neither holds them.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def real_data(kind: str, *names: str) -> Path:
    """The folder of the real ``kind`` files (``"sdf"``, ``"dma"``); skips the calling test or
    module when any of ``names`` is missing there."""
    base = os.environ.get("VISCORIG_REAL_DATA")
    folder = Path(base) / kind if base else ROOT.parent / "shared" / "data" / kind
    missing = [name for name in names if not (folder / name).is_file()]
    if missing:
        pytest.skip(f"real {kind} files not in {folder} ({', '.join(missing)}; "
                    f"see tests/data/{kind}/README.md)", allow_module_level=True)
    return folder
