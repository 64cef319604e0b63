"""Reading a run's metrics.csv in tests."""

from __future__ import annotations

import csv
from pathlib import Path


def metrics_without_timing(run: Path) -> list[dict[str, str]]:
    """metrics.csv rows without the wall-clock column, so two runs of the same config compare equal."""
    with open(run / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        row.pop("steps_per_s")
    return rows
