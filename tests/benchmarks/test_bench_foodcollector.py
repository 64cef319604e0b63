"""benchmarks/bench_foodcollector.py: its comparison of the arena's two ways into Chipmunk runs, and restores."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from foodcollector import chipmunk

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_foodcollector.py"


def test_the_calls_comparison_prints_both_rates_and_their_ratio():
    if chipmunk.CALLS is not chipmunk.ChipmunkCalls:
        out = subprocess.run([sys.executable, str(SCRIPT), "--calls"], capture_output=True, text=True)
        assert out.returncode != 0 and "public API" in out.stderr
        return
    out = subprocess.run([sys.executable, str(SCRIPT), "--calls", "--decisions", "40", "--rounds", "2"],
                         capture_output=True, text=True, check=True)
    lines = out.stdout.splitlines()
    assert any(line.strip().startswith("direct calls:") and len(line.split()) == 5 for line in lines)
    assert any(line.strip().startswith("public calls:") for line in lines)
    assert "direct / public (medians):" in lines[-1] and lines[-1].endswith("x")
