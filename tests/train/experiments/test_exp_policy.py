"""Policy files: export from a run, load, act like the run's network, refuse bad files; the shipped ones."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from train import cli
from train.config import TrainConfig
from train.storage.policy import (
    POLICY_DIR,
    export_policy,
    export_run_policies,
    load_policy,
    load_policy_file,
    policy_from_run,
    save_policy,
    shipped_policy,
)

RUN = ("headline", "salad", "dynamic-reset-free")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A finished smoke run of salad (several seeds) inside its experiment's results, as `ecorl run` leaves it
    (this module's own: the whole smoke results directory is another test file's, built on another worker).
    """
    from train.experiments.catalog import EXPERIMENTS
    from train.experiments.sweep import plan, run_jobs, write_experiment_file

    root = tmp_path_factory.mktemp("policy-run")
    experiment, task, condition = RUN
    jobs = plan(EXPERIMENTS[experiment], "smoke", root, [task], conditions=[condition])
    write_experiment_file(EXPERIMENTS[experiment], "smoke", jobs, root)
    assert [r.status for r in run_jobs(jobs, "local", workers=1, progress=False)] == ["done"]
    return root.joinpath(*RUN)


def _random_obs(policy, n: int = 64) -> torch.Tensor:
    draws = np.random.default_rng(0).integers(0, 2, (1, n, policy.obs_dim))
    return torch.from_numpy(draws.astype(np.float32))


def test_exported_policy_acts_like_the_run(run_dir, tmp_path):
    seeds = json.loads((run_dir / "config.json").read_text())["run"]["seeds"]
    assert seeds >= 2
    for index in range(seeds):
        from_run = policy_from_run(run_dir, index)
        path = export_policy(run_dir, tmp_path / f"p{index}.npz", index)
        assert path.stat().st_size < 1_000_000
        loaded = load_policy(path)
        obs = _random_obs(loaded)
        np.testing.assert_array_equal(loaded.greedy(obs), from_run.greedy(obs))
        assert loaded.task == "salad" and loaded.seed == from_run.seed and loaded.meta["agent"] == index
    seeds_differ = [policy_from_run(run_dir, i).greedy(obs) for i in range(2)]
    assert not np.array_equal(*seeds_differ), "two seeds' networks should not act identically"


def test_metadata_pairs_the_checkpoint_with_its_evaluation(run_dir):
    policy = policy_from_run(run_dir, 1)
    rows = [r for r in csv.DictReader((run_dir / "metrics.csv").open()) if int(r["step"]) == policy.meta["step"]]
    assert rows, "the checkpoint's step should have an evaluation row"
    row = next(r for r in rows if int(r["seed"]) == policy.seed)
    assert policy.meta["validation_success"] == float(row["success"])
    assert policy.seed == policy.cfg.run.seed_list[1]


def test_the_provenance_names_the_run_not_the_machines_path(run_dir, tmp_path):
    assert policy_from_run(run_dir, 0).meta["source"] == "/".join(RUN)  # inside an experiment's results
    alone = tmp_path / "deep" / "my-run"
    shutil.copytree(run_dir, alone)
    assert policy_from_run(alone, 0).meta["source"] == "my-run"  # an ``ecorl train`` run directory
    header = load_policy(export_policy(alone, tmp_path / "p.npz")).meta
    assert str(tmp_path) not in json.dumps(header)


def test_export_picks_the_best_seed_at_the_checkpoint(run_dir, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    step = policy_from_run(copy, 0).meta["step"]
    rows = list(csv.DictReader((copy / "metrics.csv").open()))
    last_seed = max(int(r["seed"]) for r in rows)
    for r in rows:  # make the last seed the best at the checkpoint's step, and the first best elsewhere
        at_checkpoint = int(r["step"]) == step
        r["success"] = str(0.9 if at_checkpoint and int(r["seed"]) == last_seed else
                           0.1 if at_checkpoint else float(int(r["seed"]) == 0))
    with (copy / "metrics.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    policy = load_policy(export_policy(copy, tmp_path / "best.npz"))
    assert policy.seed == last_seed and policy.meta["validation_success"] == 0.9


def _rewrite_last_evaluation(run_dir, column: str, values: dict[int, float]) -> None:
    """Set ``column`` of the last evaluation's rows to ``values`` (by seed) and the success column to NaN
    where the column is another.
    """
    rows = list(csv.DictReader((run_dir / "metrics.csv").open()))
    last = max(int(r["step"]) for r in rows)
    for r in rows:
        if int(r["step"]) == last:
            r[column] = str(values[int(r["seed"])])
            if column != "success":
                r["success"] = "nan"
    with (run_dir / "metrics.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def test_a_finished_experiment_run_ships_its_best_and_median_seed(run_dir, tmp_path):
    success = {int(r["seed"]): float(r["success"]) for r in csv.DictReader((run_dir / "metrics.csv").open())
               if int(r["step"]) == policy_from_run(run_dir, 0).meta["step"]}
    ranked = sorted(success, key=lambda seed: (-success[seed], seed))
    for name, seed in (("best", ranked[0]), ("median", ranked[(len(ranked) - 1) // 2])):
        shipped = load_policy(run_dir / "policies" / f"{name}.npz")  # written when the smoke run finished
        assert shipped.seed == seed and shipped.meta["validation_success"] == success[seed]
        assert torch.equal(shipped.params, policy_from_run(run_dir, shipped.meta["agent"]).params)
    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    seeds = sorted(success)
    _rewrite_last_evaluation(copy, "return", {seed: float(i % 3) for i, seed in enumerate(seeds)})
    picked = {name: load_policy(path).seed for name, path in export_run_policies(copy).items()}
    returns = sorted(seeds, key=lambda seed: (-(seeds.index(seed) % 3), seed))  # no success: by return
    assert picked == {"best": returns[0], "median": returns[(len(returns) - 1) // 2]}


def test_bad_policy_files_are_refused(run_dir, tmp_path):
    junk = tmp_path / "junk.npz"
    junk.write_text("not a policy")
    with pytest.raises(ValueError, match="not an ecorl policy file.*ecorl export"):
        load_policy(junk)
    np.savez(tmp_path / "other.npz", weights=np.zeros(3))
    with pytest.raises(ValueError, match="not an ecorl policy file"):
        load_policy(tmp_path / "other.npz")
    good = load_policy(export_policy(run_dir, tmp_path / "good.npz", 0))
    with np.load(tmp_path / "good.npz") as data:
        header = json.loads(str(data["header"]))
        params = data["params"]
    np.savez(tmp_path / "future.npz", params=params, header=np.array(json.dumps({**header, "format": 99})))
    with pytest.raises(ValueError, match="format 99"):
        load_policy(tmp_path / "future.npz")
    good.params = good.params[:, :-1]
    save_policy(good, tmp_path / "cut.npz")
    with pytest.raises(ValueError, match="parameters have shape"):
        load_policy_file(tmp_path / "cut.npz")
    with pytest.raises(ValueError, match="must end in .npz"):
        save_policy(good, tmp_path / "policy.pt")
    with pytest.raises(FileNotFoundError, match="no policy file"):
        load_policy(tmp_path / "missing.npz")


def test_export_ranks_by_the_return_where_the_task_has_no_success(run_dir, tmp_path, capsys):
    # the food collector's metrics: success NaN in every row, the return ranks the seeds (as the report films)
    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    step = policy_from_run(copy, 0).meta["step"]
    rows = list(csv.DictReader((copy / "metrics.csv").open()))
    last_seed = max(int(r["seed"]) for r in rows)
    for r in rows:
        r["success"] = "nan"
        r["return"] = str(42.0 if int(r["step"]) == step and int(r["seed"]) == last_seed else 1.0)
    with (copy / "metrics.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    assert cli.main(["export", str(copy), "--out", str(tmp_path / "best.npz")]) == 0
    policy = load_policy(tmp_path / "best.npz")
    assert policy.seed == last_seed and policy.meta["validation_return"] == 42.0
    assert "validation return 42.0" in capsys.readouterr().out


def test_export_and_video_commands(run_dir, tmp_path, capsys):
    out = tmp_path / "salad.npz"
    assert cli.main(["export", str(run_dir), "--out", str(out), "--agent", "1"]) == 0
    assert "agent 1" in capsys.readouterr().out
    video = tmp_path / "salad.mp4"
    assert cli.main(["video", "salad", "--policy", str(out), "--steps", "8", "--out", str(video)]) == 0
    assert video.stat().st_size > 0
    assert cli.main(["video", "hunting", "--policy", str(out), "--out", str(tmp_path / "x.mp4")]) == 2
    assert "trained on 'salad'" in capsys.readouterr().err
    assert cli.main(["export", str(tmp_path), "--out", str(out)]) == 2
    assert "not a run directory" in capsys.readouterr().err
    assert cli.main(["export", str(tmp_path / "nowhere"), "--out", str(out)]) == 2
    assert f"{tmp_path / 'nowhere'} does not exist; give a run directory" in capsys.readouterr().err
    assert cli.main(["evaluate", str(out), "--rollouts", "5"]) == 0
    printed = capsys.readouterr().out
    assert "salad, 5 validation layouts" in printed and "policy (epsilon 0.1; other exploration draws" in printed
    assert "uniform random" in printed
    with pytest.raises(SystemExit):
        cli.main(["evaluate", str(out), "--epsilon", "1.5"])
    assert "probability in [0, 1]" in capsys.readouterr().err


def test_a_corrupt_checkpoint_is_refused_by_name(run_dir, tmp_path, capsys):
    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    with (copy / "checkpoint.npz").open("r+b") as f:
        f.seek(-100, 2)
        f.write(b"x" * 100)
    for command in (["export", str(copy), "--out", str(tmp_path / "p.npz")], ["evaluate", str(copy)],
                    ["video", "salad", "--policy", str(copy), "--steps", "2"]):
        assert cli.main(command) == 2
        assert "corrupt" in capsys.readouterr().err


def test_video_defaults_to_the_shipped_policy(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["video", "scavenging", "--steps", "5"]) == 0
    written = capsys.readouterr()
    name = "scavenging-trained.mp4" if shipped_policy("scavenging") else "scavenging-random.mp4"
    assert written.out.strip() == f"results/videos/{name}" and (tmp_path / "results" / "videos" / name).exists()
    assert cli.main(["video", "foodcollector", "--steps", "3"]) == 0
    assert "no trained policy for foodcollector" in capsys.readouterr().err


SHIPPED = sorted(POLICY_DIR.glob("*.npz"))


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_policy_beats_a_random_policy(path):
    policy = load_policy_file(path)
    assert path.stem == policy.task
    trained = policy.evaluate(rollouts=100)
    random = policy.evaluate(rollouts=100, epsilon=1.0)  # the paper's protocol with a uniform random policy
    assert trained.success[0] >= random.success[0] + 0.25, (trained, random)
    assert trained.returns[0] > random.returns[0], (trained, random)


RESULT_POLICIES = sorted(Path(__file__).resolve().parents[3].glob("docs/results/**/policies/*.npz"))


def test_every_shipped_policy_names_its_run_without_a_machines_path():
    for path in SHIPPED + RESULT_POLICIES:
        source = load_policy_file(path).meta["source"]
        assert source and not Path(source).is_absolute(), (path, source)
    assert len(RESULT_POLICIES) >= 16  # the salad-gap arms' best and median seeds


def test_a_run_kept_without_its_checkpoint_points_to_its_exported_policies(capsys):
    shipped = RESULT_POLICIES[0].parent.parent  # a shipped paper-budget run: metrics and policies, no checkpoint
    assert cli.main(["evaluate", str(shipped)]) == 2
    err = capsys.readouterr().err
    assert "kept without its checkpoint: pass one of its exported policies" in err
    assert str(shipped / "policies" / "best.npz") in err


def test_random_draws_spread_the_baseline_and_start_with_the_single_draw(run_dir, tmp_path, capsys):
    out = tmp_path / "salad.npz"
    assert cli.main(["export", str(run_dir), "--out", str(out)]) == 0
    policy = load_policy_file(out)
    single = policy.evaluate(rollouts=20, epsilon=1.0)
    draws = policy.random_draws(6, rollouts=20)
    assert draws.success.shape == (6,)
    np.testing.assert_array_equal(draws.steps_to_solve[0], single.steps_to_solve[0])  # draw 0 is the single draw
    assert len({tuple(row) for row in draws.steps_to_solve}) > 1  # the other draws are independent of it
    capsys.readouterr()
    assert cli.main(["evaluate", str(out), "--rollouts", "20", "--random-draws", "12"]) == 0
    printed = capsys.readouterr().out
    twelve = 100 * policy.random_draws(12, rollouts=20).success
    assert f"12 independent draws: success {twelve.mean():.1f} %, 95 % bootstrap CI [" in printed
    assert f"20 validation layouts of the test MDP (horizon {policy.test_kwargs['horizon']}, static):" in printed
    assert cli.main(["evaluate", str(out), "--rollouts", "20", "--random-draws", "6"]) == 0
    assert "6 independent draws: success" in (printed := capsys.readouterr().out) and "(no interval under 10" in printed
    assert cli.main(["evaluate", str(out), "--random-draws", "3", "--epsilons", "1"]) == 2
    assert "--random-draws goes without --epsilons" in capsys.readouterr().err
    assert cli.main(["evaluate", str(out), "--random-draws", "5000"]) == 2
    assert "would step 500,000 worlds at once; keep it to 100,000 (e.g. --random-draws 1000)" in capsys.readouterr().err
    assert cli.main(["evaluate", str(out), "--rollouts", "100001"]) == 2
    assert "--rollouts 100,001 would step 100,001 worlds at once; keep it to 100,000" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["evaluate", str(out), "--random-draws", "1.5"])
    assert "--random-draws: expected a positive integer, got 1.5" in capsys.readouterr().err


def test_random_draws_follow_the_test_dynamism(run_dir, tmp_path, capsys):
    out = tmp_path / "salad.npz"
    assert cli.main(["export", str(run_dir), "--out", str(out)]) == 0
    policy = load_policy_file(out)
    moving = policy.random_draws(10, rollouts=20, dynamism=0.5)
    assert not np.array_equal(moving.steps_to_solve, policy.random_draws(10, rollouts=20).steps_to_solve)
    capsys.readouterr()
    assert cli.main(["evaluate", str(out), "--rollouts", "20", "--random-draws", "10", "--test-dynamism", "0.5"]) == 0
    printed = capsys.readouterr().out
    assert "test MDP (dynamism 0.5):" in printed  # the grid's horizon is a column
    assert "success [95% CI]" in printed  # the grid's table, then the draws
    assert f"random (uniform random), 10 independent draws: success {100 * moving.success.mean():.1f} %" in printed


def test_a_task_measured_by_its_return_is_evaluated_by_its_return(capsys):
    path = Path(__file__).resolve().parents[3] / "docs/results/paper/dynamism/foodcollector/dynamic-reset-free/policies"
    policy = str(path / "best.npz")
    assert cli.main(["evaluate", policy, "--rollouts", "1", "--random-draws", "2"]) == 0
    printed = capsys.readouterr().out
    assert "success" not in printed and "random (uniform random), 2 independent draws: mean return" in printed
    assert cli.main(["evaluate", policy, "--rollouts", "1", "--epsilons", "0"]) == 2
    assert "foodcollector is measured by its return: evaluate it without the grid's options" in capsys.readouterr().err


def test_the_test_mdp_is_named_with_the_task_parameters_a_run_set():
    root = Path(__file__).resolve().parents[3] / "docs/results/paper"
    make_axe = load_policy_file(root / "factory-make-axe/factory/dynamic-reset-free/policies/best.npz")
    assert make_axe.describe_test_mdp() == "horizon 200, static, goal=make_axe"
    released = load_policy_file(root / "hunting-released-fig4/hunting/dynamic-reset-free-waypoint/policies/best.npz")
    assert released.describe_test_mdp() == "horizon 200, dynamism 0.2"
    assert released.describe_test_mdp(dynamism=0) == "horizon 200, static"


def test_shipped_scavenging_runs_name_the_predator_respawn_they_trained_with():
    """They trained before the original's respawn became the default (docs/fidelity.md): config and policies say
    ``off-agent``, so re-evaluating them uses their rule and resuming one under the new default is refused.
    """
    root = Path(__file__).resolve().parents[3] / "docs/results"
    runs = [p.parent for p in sorted(root.rglob("config.json"))
            if TrainConfig.from_dict(json.loads(p.read_text())).env.task == "scavenging"]
    assert len(runs) >= 14
    for run in runs:
        cfg = TrainConfig.from_dict(json.loads((run / "config.json").read_text()))
        assert cfg.env.env_kwargs["predator_respawn"] == "off-agent", run
        for path in (run / "policies").glob("*.npz"):
            policy = load_policy_file(path)
            assert policy.test_kwargs["predator_respawn"] == "off-agent", path


def test_every_shipped_run_trained_with_the_original_directed_steps():
    """Hunting's deer and factory's workers: every shipped run trained under the original's directed steps, the
    default (docs/fidelity.md), so no config or policy names another rule (those trained under ecorl's earlier
    one, ``current-free``, were re-run and replaced).
    """
    root = Path(__file__).resolve().parents[3] / "docs/results"
    configs = sorted(root.rglob("config.json"))
    assert configs
    for path in configs:
        env = TrainConfig.from_dict(json.loads(path.read_text())).env
        assert env.env_kwargs.get("directed_moves", "original") == "original", path
        for policy in (path.parent / "policies").glob("*.npz"):
            assert load_policy_file(policy).test_kwargs.get("directed_moves", "original") == "original", policy
