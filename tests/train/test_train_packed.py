"""Packed runs: several conditions of a task in one trainer equal the same conditions trained apart."""

from __future__ import annotations

import numba
import numpy as np
import pytest
import torch
from run_metrics import metrics_without_timing

from train.agent.learner import DQNLearner, Learner, RowSettings
from train.agent.network import QNetwork
from train.config import TrainConfig
from train.experiments.catalog import get_experiment
from train.experiments.jobs import Pack, execute, execute_pack
from train.experiments.sweep import pack_jobs, plan
from train.loop.packing import check_packable, group_packable
from train.loop.trainer import Trainer

TINY = TrainConfig().replace(task="salad", dynamism=0.1, eps_start=0.3, warmup_steps=200, epoch_steps=100,
                             updates_per_epoch=30, buffer_size=2_000, eval_every=100, eval_rollouts=4,
                             eval_horizon=20, steps=500, checkpoint_every=200, progress=False)


def test_the_salad_panel_packed_equals_its_conditions_run_apart(tmp_path):
    exp = get_experiment("headline-waypoint")
    apart = plan(exp, "smoke", tmp_path / "apart")
    together = plan(exp, "smoke", tmp_path / "packed")
    units = pack_jobs(together)  # one worker: one pack
    assert len(units) == 1 and isinstance(units[0], Pack) and len(units[0].jobs) == 4  # one process for all four
    for job in apart:
        assert execute(job).status == "done"
    assert [r.status for r in execute_pack(units[0])] == ["done"] * 4
    for a, b in zip(apart, together):
        _same_metrics(tmp_path / "packed" / exp.name / "salad" / b.condition,
                      tmp_path / "apart" / exp.name / "salad" / a.condition)
    assert [r.status for r in execute_pack(units[0])] == ["skipped"] * 4  # done conditions are skipped


ROUNDED = ("loss", "max_q")
"""Columns computed by batched products, whose float rounding depends on how many rows share the product."""


def _same_metrics(run, reference) -> None:
    """The same metrics, exactly but for float rounding (1e-5 relative) in `ROUNDED`."""
    rows, expected = metrics_without_timing(run), metrics_without_timing(reference)
    assert [{k: v for k, v in r.items() if k not in ROUNDED} for r in rows] == \
        [{k: v for k, v in r.items() if k not in ROUNDED} for r in expected]
    for key in ROUNDED:
        assert np.allclose([float(r[key]) for r in rows], [float(r[key]) for r in expected], rtol=1e-5, atol=1e-9)


def _trained(cfgs: list[TrainConfig], epochs: int = 3) -> Trainer:
    trainer = Trainer.packed(cfgs, [None] * len(cfgs), [False] * len(cfgs))
    for _ in range(epochs):
        trainer.train_epoch()
    return trainer


def test_rows_with_their_own_rate_epsilon_and_rnd_follow_their_separate_runs():
    a = TINY.replace(seeds=2, lr=3e-4)
    b = TINY.replace(seeds=1, first_seed=5, lr=1e-4, reset_free=True, eps_start=0.6, rnd=True)
    packed = _trained([a, b])
    for cfg, rows in ((a, slice(0, 2)), (b, slice(2, 3))):
        alone = _trained([cfg])
        assert np.array_equal(alone.replay.obs, packed.replay.obs[rows])  # the same experience, exactly
        assert torch.allclose(alone.agent.online, packed.agent.online[rows], rtol=1e-4, atol=1e-6)
        assert torch.allclose(alone.agent.adam.state_dict()["exp_avg_sq"],
                              packed.agent.adam.state_dict()["exp_avg_sq"][rows], rtol=1e-3, atol=1e-12)
    assert packed.learner.rnd is not None and packed.learner.rnd.predictor.shape[0] == 1  # RND only where asked


def test_a_packed_checkpoint_resumes_alone_to_the_same_run(tmp_path):
    a, b = TINY.replace(seeds=2), TINY.replace(seeds=2, reset_free=True)
    Trainer(b, tmp_path / "reference").run()
    first = Trainer.packed([a.replace(steps=300), b.replace(steps=300)], [tmp_path / "a", tmp_path / "b"],
                           [False, False])
    first.run()
    first.close()
    resumed = Trainer(b, tmp_path / "b", resume=True)  # the packed run's checkpoint, continued on its own
    assert resumed.step == 300
    resumed.run()
    resumed.close()
    _same_metrics(tmp_path / "b", tmp_path / "reference")


def test_conditions_that_cannot_share_a_trainer_are_refused_and_kept_apart():
    with pytest.raises(ValueError, match="differ in dqn.batch_size"):
        check_packable([TINY, TINY.replace(batch_size=32)])
    cfgs = [TINY, TINY.replace(dynamism=0.5, lr=1e-3), TINY.replace(batch_size=32), TINY.replace(task="hunting")]
    assert group_packable(cfgs) == [[0, 1], [2], [3]]
    with_rnd = [TINY, TINY.replace(rnd=True), TINY.replace(rnd=True, rnd_weight=0.5)]
    assert group_packable(with_rnd) == [[0, 1], [2]]  # the RND flag is a row's own, its settings are shared
    with pytest.raises(ValueError, match="differ in rnd.rnd_weight"):
        check_packable(with_rnd)


def test_the_double_dqn_learner_is_a_learner():
    row = RowSettings(0, TINY.dqn, TINY.rnd)
    net = QNetwork.from_config(view_dim=125, obs_dim=130, num_actions=7, dqn=TINY.dqn)
    learner = DQNLearner([row, RowSettings(1, TINY.dqn, TINY.rnd)], net, binary_obs=True)
    assert isinstance(learner, Learner) and learner.num_agents == 2 and learner.device.type == "cpu"
    assert learner.steps_to_collect(0) == 300 and learner.steps_to_collect(300) == 100


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")
def test_cuda_without_cuda_is_a_one_line_error(cli):
    for args in (["train", "salad", "--device", "cuda", "--steps", "300"],
                 ["run", "headline", "--budget", "smoke", "--device", "cuda", "--dry-run"]):
        proc = cli(*args, check=False)
        assert proc.returncode == 2 and "no CUDA device" in proc.stderr and "use --device cpu" in proc.stderr
        assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_packs_spread_over_the_worker_processes(tmp_path):
    jobs = plan(get_experiment("headline-waypoint"), "smoke", tmp_path)
    assert sorted(len(u.jobs) for u in pack_jobs(jobs, workers=2)) == [2, 2]
    assert len(pack_jobs(jobs, workers=8)) == 4 and not any(isinstance(u, Pack) for u in pack_jobs(jobs, 8))


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba's thread pool holds one thread on this machine")
def test_grid_worlds_stepped_on_threads_train_the_same_run(tmp_path):
    Trainer(TINY.replace(steps=300), tmp_path / "one").run()
    Trainer(TINY.replace(steps=300, env_threads=2), tmp_path / "two").run()
    assert metrics_without_timing(tmp_path / "two") == metrics_without_timing(tmp_path / "one")


def test_a_condition_that_cannot_open_does_not_stop_its_pack(tmp_path):
    jobs = plan(get_experiment("headline-waypoint"), "smoke", tmp_path, conditions=["static-reset-free",
                                                                                    "dynamic-reset-free"])
    kept = tmp_path / "headline-waypoint" / "salad" / "static-reset-free"
    kept.mkdir(parents=True)
    (kept / "metrics.csv").write_text("step,seed\n")  # results without a checkpoint: kept, never deleted
    results = {r.job.rsplit("/", 1)[1]: r for r in execute_pack(Pack(tuple(jobs)))}
    assert results["static-reset-free"].status == "kept" and "--restart static-reset-free" in \
        results["static-reset-free"].error
    assert results["dynamic-reset-free"].status == "done"
    assert (kept / "metrics.csv").read_text() == "step,seed\n"


def test_the_learners_epsilon_is_each_rows_config_epsilon():
    dqns = [TINY.dqn, TINY.replace(eps_start=0.6, eps_end=0.05, eps_decay_steps=1234).dqn,
            TINY.replace(eps_decay_steps=0).dqn]
    net = QNetwork.from_config(view_dim=125, obs_dim=130, num_actions=7, dqn=TINY.dqn)
    learner = DQNLearner([RowSettings(i, d, TINY.rnd) for i, d in enumerate(dqns)], net, binary_obs=True)
    for step in (0, 1, 617, 1234, 89_999, 90_000, 10**7):
        assert np.array_equal(learner.epsilon(step), [d.epsilon(step) for d in dqns])


def test_a_run_interrupted_inside_an_evaluation_is_reported_interrupted(tmp_path, monkeypatch):
    from train.experiments import jobs as jobs_module
    from train.loop.runlog import Interrupted

    def interrupted(*args):
        raise Interrupted("a signal during a long evaluation")

    monkeypatch.setattr(jobs_module, "_train", interrupted)  # Interrupted is a KeyboardInterrupt, not an Exception
    jobs = plan(get_experiment("headline-waypoint"), "smoke", tmp_path)
    assert execute(jobs[0]).status == "interrupted"
    assert [r.status for r in execute_pack(Pack(tuple(jobs)))] == ["interrupted"] * 4


def test_experiments_run_together_share_a_pack_across_experiments_and_train_a_copy_once(tmp_path, capsys):
    from train.cli import main
    from train.experiments.multi import plan_many, split_copies

    asked = ["--budget", "smoke", "--steps", "700", "--task", "salad",
             "--condition", "static-reset-free", "p0", "p0.05"]
    exps = [get_experiment("headline"), get_experiment("dynamism-sweep")]
    train, copies = split_copies(plan_many(exps, "smoke", tmp_path / "plan", ["salad"], asked[-3:], steps=700))
    assert [(c.name, o.name) for c, o in copies] == [("dynamism-sweep/salad/p0", "headline/salad/static-reset-free")]
    [unit] = pack_jobs(train)  # the headline's run and the sweep's p 0.05 in one process
    assert isinstance(unit, Pack) and {j.experiment for j in unit.jobs} == {"headline", "dynamism-sweep"}
    together = tmp_path / "together"
    assert main(["run", "headline", "dynamism-sweep", *asked, "--pack", "--jobs", "1", "--no-progress",
                 "--out", str(together)]) == 0
    for exp, condition in (("headline", "static-reset-free"), ("dynamism-sweep", "p0.05")):
        assert main(["run", exp, *asked[:6], "--condition", condition, "--no-progress",
                     "--out", str(tmp_path / "apart")]) == 0
        _same_metrics(together / exp / "salad" / condition, tmp_path / "apart" / exp / "salad" / condition)
    copy = together / "dynamism-sweep" / "salad" / "p0"
    assert metrics_without_timing(copy) == metrics_without_timing(together / "headline" / "salad" / "static-reset-free")
    assert (copy / "done.json").exists() and not (copy / "checkpoint.npz").exists()
    assert main(["run", "dynamism-sweep", *asked[:6], "--condition", "p0", "--no-progress",
                 "--out", str(together)]) == 0  # the copy counts as done for the experiment run alone
    printed = capsys.readouterr()
    assert "dynamism-sweep, this run:" in printed.out  # the results on stdout, so `> log.txt` keeps them
    assert "dynamism-sweep, this run:" not in printed.err
