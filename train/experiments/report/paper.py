"""The paper's own numbers, transcribed in ``train/data/paper/*.json``, and how the report quotes them."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

PAPER_DIR = Path(__file__).resolve().parents[2] / "data" / "paper"
"""Where the paper's transcribed numbers live (``train/data/paper`` of the source tree)."""


def load_paper(paper_dir: Path = PAPER_DIR) -> dict[str, dict[str, list[dict[str, Any]]]]:
    """The paper's numbers by experiment, {'values', 'claims', 'sources'}, from ``train/data/paper/*.json``."""
    out: dict[str, dict[str, list[dict[str, Any]]]] = {}
    if not paper_dir.is_dir():
        return out
    for path in sorted(paper_dir.glob("*.json")):
        data = json.loads(path.read_text())
        for exp in data.get("experiments", []):
            entry = out.setdefault(exp, {"values": [], "claims": [], "sources": []})
            entry["values"] += [{**v, "figure": data["figure"]} for v in data.get("values", [])]
            entry["claims"] += [{**c, "figure": data["figure"]} for c in data.get("claims", [])
                                if _claim_applies(c, exp)]
            entry["sources"].append({"figure": data["figure"], "source": data.get("source", ""),
                                     "note": data.get("note", "")})
    return out


def _claim_applies(claim: dict[str, Any], exp: str) -> bool:
    """Whether a claim speaks of experiment ``exp``: its ``experiment`` (a name or a list of names), or every
    experiment of its file when it names none.
    """
    scope = claim.get("experiment", exp)
    return exp in scope if isinstance(scope, list) else scope == exp


def paper_value(paper: dict, task: str, condition: str) -> dict[str, Any] | None:
    """The paper's reported final value of a condition, if any."""
    for v in paper.get("values", []):
        if v.get("task") == task and v.get("condition") == condition and "value" in v:
            return v
    return None


def format_paper(v: dict[str, Any] | None, scale: float = 100.0, unit: str = "%") -> str:
    """'≈ 12%' for approximate values, '= 12%' for exact ones, '—' when the paper has none."""
    if v is None:
        return "—"
    mark = "≈" if v.get("approximate", True) else "="
    return f"{mark} {v['value'] * scale:.0f}{unit} ({v['figure']})"
