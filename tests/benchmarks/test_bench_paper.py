"""benchmarks/bench_paper.py, the whole-paper projection a GPU lease runs first: its census and a tiny timing."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

from train.loop.packing import check_packable

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_paper.py"


def _bench():
    spec = importlib.util.spec_from_file_location("bench_paper", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_paper"] = module  # its dataclass looks its module up there
    spec.loader.exec_module(module)
    return module


def test_the_census_counts_each_configuration_once_in_packs_one_process_can_train():
    bench = _bench()
    packs = bench.census("cpu")
    names = [name for p in packs for name in p.names]
    identities = [repr(sorted(c.identity().items())) for p in packs for c in p.cfgs]
    assert len(set(identities)) == len(identities)  # a copy (p 0 of a sweep = a headline run) is trained once
    assert "headline-waypoint/salad/static-reset-free" in names or \
        "dynamism-sweep-waypoint/salad/p0" in names
    assert not ({"headline-waypoint/salad/static-reset-free", "dynamism-sweep-waypoint/salad/p0"} <= set(names))
    for pack in packs:
        check_packable(pack.cfgs)
        assert {c.env.task for c in pack.cfgs} == {pack.task}
    assert {p.task for p in packs} == {"salad", "walled-salad", "hunting", "scavenging", "factory", "foodcollector"}


def test_a_tiny_timing_projects_a_time(capsys):
    _bench().main(["--device", "cpu", "--max-k", "2", "--epochs", "1", "--tasks", "walled-salad"])
    out = capsys.readouterr().out
    assert "| walled-salad | 10 | 100 | 1,000,200 | 100.0 | 2 |" in out
    assert "the whole paper, one pack after another on this cpu:" in out


def test_packs_are_picked_by_their_census_row_and_a_row_past_the_end_is_refused(capsys):
    import pytest

    bench = _bench()
    bench.main(["--census", "--tasks", "salad", "hunting", "--pack", "0"])
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| hunting") or
            line.startswith("| salad")]
    first = [p for p in bench.census("cpu") if p.task in ("salad", "hunting")][0]
    assert len(rows) == 1 and rows[0].startswith(f"| {first.task} | {len(first.names)} | {first.k} |")
    with pytest.raises(SystemExit):
        bench.main(["--census", "--pack", "99"])
    assert "--pack: rows 0 to" in capsys.readouterr().err
