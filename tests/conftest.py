from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"


@pytest.fixture
def small_scenario_path() -> Path:
    """4 UAVs, 300 s, with a partition, a crash, a late joiner, corruption and 30% drops."""
    return DATA / "faults-small.toml"
