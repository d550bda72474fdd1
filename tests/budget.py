"""Hypothesis example counts that follow the active profile (the profiles are in conftest.py).

``@settings(max_examples=examples(300))`` runs 300 examples under ``ci`` (a plain
``python -m pytest``), 3000 under ``deep`` and 30 under ``quick`` (the quick loop,
``pytest -m "not slow"``). Write a literal count only where the number itself matters (a test
that must find a planted bug within so many examples).
"""

from __future__ import annotations

from hypothesis import settings


def examples(n: int) -> int:
    """``n`` under the ci profile, scaled with the active profile (deep: 10x, quick: 1/10)."""
    return max(1, n * settings.default.max_examples // 100)
