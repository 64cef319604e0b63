"""The evaluation grid: layouts split by the first view, fresh layouts, the table and its CSV."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from ecology import validation_seeds
from gridtasks.codes import Code
from train.evaluation.grid import SPLITS, evaluate_grid, fresh_seeds, needed_in_first_view, wilson
from train.storage.policy import load_policy, shipped_policy
from train.tasks import get_task, make_vector_env


def _in_view_from_the_grid(test_kwargs, seeds):
    """The same question answered from the worlds' cells: an ingredient within 2 cells of the agent."""
    env = make_vector_env(get_task("salad").env_id, len(seeds), test_kwargs)
    env.reset(seed=list(seeds))
    out = []
    for world in env.worlds:
        ys, xs = np.nonzero(np.isin(world["grid"], [Code.LETTUCE, Code.CARROT]))
        ax, ay = world["agent"]
        out.append(bool(np.any((np.abs(xs - ax) <= 2) & (np.abs(ys - ay) <= 2))))
    env.close()
    return np.array(out)


def test_first_view_split_agrees_with_the_grid():
    policy = load_policy(shipped_policy("salad"))
    seeds = validation_seeds(100)
    in_view = needed_in_first_view("salad", policy.test_kwargs, seeds)
    np.testing.assert_array_equal(in_view, _in_view_from_the_grid(policy.test_kwargs, seeds))
    assert 0 < in_view.sum() < len(seeds)
    with pytest.raises(ValueError, match="first-view split"):
        needed_in_first_view("hunting", policy.test_kwargs, seeds[:2])


def test_fresh_layouts_are_neither_validation_nor_training_seeds():
    fresh = set(fresh_seeds(5000))
    assert not fresh & set(validation_seeds(100)) and min(fresh) > 10**9 and max(fresh) < 2**32


def test_wilson_interval():
    low, high = wilson(40, 100)
    assert low < 0.4 < high and high - low == pytest.approx(0.19, abs=0.01)
    assert wilson(0, 10)[0] == pytest.approx(0.0) and wilson(10, 10)[1] == pytest.approx(1.0)


def test_grid_rows_and_csv(tmp_path, cli):
    policy = load_policy(shipped_policy("salad"))
    rows = evaluate_grid(policy, [0.0, 1.0], [5], validation=6, fresh=4)
    assert [(r["layouts"], r["epsilon"], r["split"]) for r in rows[:3]] == [("validation", 0.0, s) for s in SPLITS]
    assert len(rows) == 2 * 2 * 3
    for i in range(0, len(rows), 3):
        assert rows[i]["rollouts"] == rows[i + 1]["rollouts"] + rows[i + 2]["rollouts"]
    out = tmp_path / "grid.csv"
    proc = cli("evaluate", str(shipped_policy("salad")), "--epsilons", "0", "0.3", "--horizons", "5", "--rollouts",
               "4", "--fresh", "3", "--out", str(out))
    assert "nothing needed in first view" in proc.stdout
    table = list(csv.DictReader(out.open()))
    assert len(table) == 2 * 2 * 3 and {r["layouts"] for r in table} == {"validation", "fresh"}


def test_grid_of_a_task_without_a_first_view_need_is_not_split(cli):
    proc = cli("evaluate", str(shipped_policy("hunting")), "--epsilons", "0", "--horizons", "5", "--rollouts", "3")
    rows = [line for line in proc.stdout.splitlines() if line.startswith("validation")]
    assert len(rows) == 1 and " all " in rows[0]


def test_the_grid_can_evaluate_in_a_dynamic_test_mdp(monkeypatch, cli):
    import train.storage.policy

    made = []

    class Spy(train.storage.policy.Evaluator):
        def __init__(self, env_id, kwargs, *args, **kw):
            made.append(kwargs["dynamism"])
            super().__init__(env_id, kwargs, *args, **kw)

    monkeypatch.setattr(train.storage.policy, "Evaluator", Spy)
    policy = load_policy(shipped_policy("hunting"))
    evaluate_grid(policy, [0.1], [5], validation=2, dynamism=0.2)
    evaluate_grid(policy, [0.1], [5], validation=2)
    assert made == [0.2, 0.0]
    proc = cli("evaluate", str(shipped_policy("hunting")), "--test-dynamism", "0.2", "--horizons", "5",
               "--rollouts", "2")
    assert "test MDP (dynamism 0.2):" in proc.stdout
    bad = cli("evaluate", str(shipped_policy("hunting")), "--test-dynamism", "1.5", check=False)
    assert bad.returncode == 2 and "--test-dynamism" in bad.stderr


def test_grid_out_is_checked_before_the_rollouts_and_its_folder_made(tmp_path, monkeypatch, capsys):
    """An --out under a file, or a directory, used to fail only after the whole grid was evaluated; an --out in a
    folder not yet made failed the same way ([Errno 2] No such file or directory).
    """
    import train.evaluation.grid
    from train.cli import main

    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "grids").mkdir()
    base = ["evaluate", str(shipped_policy("salad")), "--horizons", "3", "--rollouts", "2", "--out"]
    with monkeypatch.context() as patch:
        patch.setattr(train.evaluation.grid, "evaluate_grid", lambda *a, **k: pytest.fail("evaluated first"))
        assert main([*base, str(tmp_path / "notes.txt" / "grid.csv")]) == 2
        assert "lies under" in capsys.readouterr().err
        assert main([*base, str(tmp_path / "grids")]) == 2
        assert "is a directory; give the CSV file to write" in capsys.readouterr().err
    assert main([*base, str(tmp_path / "new" / "grid.csv")]) == 0
    assert len(list(csv.DictReader((tmp_path / "new" / "grid.csv").open()))) == 3
