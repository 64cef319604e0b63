"""The experiments as data: budgets, conditions and configs follow SPEC and the paper."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from train.config import TrainConfig
from train.experiments.catalog import (
    BUDGETS,
    DYNAMIC_P,
    EXPERIMENTS,
    GRID_TASKS,
    RELEASED_SALAD_SCHEDULES,
    SHAPING_SCHEDULE,
    SPARSE_EQUIVALENT,
    get_experiment,
    job_config,
)
from train.experiments.choices import shaping_window_acts
from train.experiments.sweep import plan
from train.storage.rundir import FILM_FILES, setting_differences
from train.tasks import get_task

REPO = Path(__file__).resolve().parents[3]


def _paper_config(exp_name: str, task: str, condition: str) -> TrainConfig:
    """The config that ``ecorl run EXP_NAME --budget paper`` builds for one condition of one task."""
    exp = get_experiment(exp_name)
    cond = {c.name: c for c in exp.conditions[task]}[condition]
    return job_config(task, cond, exp.budget("paper"))

SPEC_TABLE = {  # name: (paper seeds, {task: steps}) from SPEC's experiment table
    "episodic-vs-reset-free": (10, {"salad": 1_000_000}),
    "dynamism": (10, {"salad": 1_000_000, "hunting": 1_500_000, "scavenging": 1_250_000, "factory": 1_250_000,
                      "foodcollector": 1_000_000}),
    "dynamism-sweep": (10, {"salad": 1_000_000, "hunting": 1_500_000}),
    "shaping": (10, dict.fromkeys(("salad", "hunting", "scavenging", "factory", "foodcollector"), 1_250_000)),
    "rnd": (10, {"factory": 1_250_000}),
    "walls": (10, {"walled-salad": 1_000_000}),
    "measure": (25, dict.fromkeys(("factory", "salad", "hunting", "scavenging", "walled-salad"), 50_000)),
}


def test_every_spec_experiment_is_defined_with_the_papers_budget():
    for name, (seeds, steps) in SPEC_TABLE.items():
        exp = get_experiment(name)
        paper = exp.budget("paper")
        assert paper.seeds == seeds, name
        assert {t: paper.steps_for(t) for t in exp.tasks} == steps, name
        if not exp.is_measurement:
            assert paper.eval_every == 5_000 and paper.eval_rollouts is None
    assert "headline" in EXPERIMENTS


def test_unknown_names_are_explained():
    with pytest.raises(ValueError, match="choose one of"):
        get_experiment("nope")
    with pytest.raises(ValueError, match="choose one of"):
        get_experiment("dynamism").budget("huge")
    with pytest.raises(ValueError, match="unknown rnd task .salad.; choose one of factory"):
        get_experiment("rnd").select_tasks(["salad"])


@pytest.mark.parametrize("budget", BUDGETS)
def test_every_condition_builds_a_valid_config(budget, tmp_path):
    for exp in EXPERIMENTS.values():
        jobs = plan(exp, budget, tmp_path)
        assert len({j.run_dir for j in jobs}) == len(jobs)
        for job in jobs:
            assert Path(job.run_dir) == tmp_path.resolve() / exp.name / job.task / job.condition
            if job.is_measurement:
                continue
            cfg = job_config(job.task, next(c for c in exp.conditions[job.task] if c.name == job.condition),
                             exp.budget(budget))
            assert cfg.to_dict() == job.config
            # the trainer reads the test MDP's horizon, but where a released validation was shorter
            assert cfg.eval.eval_horizon is None or budget == "smoke" or exp.name in RELEASED_VALIDATION
            assert cfg.run.threads == 1 and not cfg.run.progress
            assert cfg.dqn.eps_decay_steps == 90_000  # the paper's clock at every budget


RELEASED_VALIDATION = {"hunting-released": 100}
"""Experiments validated as a released script did, with its shorter rollouts (Fig. 5 hunting: 100 steps)."""


def test_smoke_budget_is_small():
    for exp in EXPERIMENTS.values():
        b = exp.budget("smoke")
        assert b.seeds <= 3 and all(b.steps_for(t) <= 2_000 for t in exp.tasks)


def test_dynamism_conditions_are_static_dynamic_by_episodic_reset_free():
    exp = get_experiment("dynamism")
    for task, conds in exp.conditions.items():
        assert [c.name for c in conds] == ["static-episodic", "static-reset-free", "dynamic-episodic",
                                           "dynamic-reset-free"]
        knobs = [(c.overrides["dynamism"] > 0, c.overrides["reset_free"]) for c in conds]
        assert knobs == [(False, False), (False, True), (True, False), (True, True)], task
    salad = {c.name: c.overrides for c in exp.conditions["salad"]}
    assert salad["dynamic-reset-free"]["dynamism"] == 0.1
    hunting = {c.name: c.overrides for c in exp.conditions["hunting"]}
    assert hunting["dynamic-episodic"]["dynamism"] == 0.2
    assert [c.overrides for c in get_experiment("headline").conditions["salad"]] == list(salad.values())


def test_shaping_conditions_follow_the_paper():
    exp = get_experiment("shaping")
    assert SHAPING_SCHEDULE["salad"] == "linear:1:0:280000"  # the original (40000, 20000) window on 8x8
    for task, conds in exp.conditions.items():
        names = [c.name for c in conds]
        expected = {"foodcollector": ["env-shaping-sparse", "no-shaping"],
                    "scavenging": ["env-shaping-sparse", "distance-reward", "no-shaping"]}.get(
            task, ["env-shaping-sparse", "env-shaping-subgoal", "distance-reward", "one-time-reward", "no-shaping"])
        assert names == expected, task
        for c in conds:
            assert c.overrides["reset_free"] is True
            assert ("shaping" in c.overrides) == c.name.startswith("env-shaping")
    hunting = exp.conditions["hunting"][0]
    cfg = job_config("hunting", hunting, exp.budget("paper"))
    assert cfg.env.env_kwargs == {"deer_kind": "hard", "deer_speed": 0.2}  # the original directed steps (re-run)
    assert cfg.env.shaping == SHAPING_SCHEDULE["hunting"]
    assert {c.overrides["dynamism"] for c in exp.conditions["salad"]} == {0.05}


def test_walls_cover_both_settings_and_rnd_turns_rnd_on():
    walls = get_experiment("walls").conditions["walled-salad"]
    assert sum(c.overrides["reset_free"] for c in walls) == 5 and len(walls) == 10
    rnd = {c.name: c.overrides for c in get_experiment("rnd").conditions["factory"]}
    assert rnd["rnd"].get("rnd") is True and not rnd["static"].get("rnd")
    assert all(o["reset_free"] for o in rnd.values())


def test_run_overrides_change_seeds_and_steps(tmp_path):
    jobs = plan(get_experiment("rnd"), "smoke", tmp_path, seeds=3, steps=1500)
    assert {j.config["run"]["seeds"] for j in jobs} == {3}
    assert {j.config["run"]["steps"] for j in jobs} == {1500}


def test_paper_numbers_name_real_experiments_and_conditions():
    files = sorted((REPO / "train" / "data" / "paper").glob("*.json"))
    assert len(files) >= 6
    seen_exact = seen_approx = 0
    for path in files:
        data = json.loads(path.read_text())
        assert data["figure"] and data["source"]
        experiments = [get_experiment(name) for name in data["experiments"]]
        for v in data["values"]:
            assert isinstance(v["approximate"], bool) and v["where"]
            seen_exact += not v["approximate"]
            seen_approx += v["approximate"]
            # a value speaks of each listed experiment that trains its task (Fig. 4's salad numbers are not
            # `dynamism-waypoint`'s, which has no salad), and of at least one
            having = [exp for exp in experiments if v["task"] in exp.conditions]
            assert having, (path.name, v)
            for exp in having:
                names = [c.name for c in exp.conditions[v["task"]]]
                if "measure" in v:
                    assert v["measure"] in names
                else:
                    assert v["condition"] in names and 0.0 <= v["value"] <= 1.0
    assert seen_exact >= 8 and seen_approx >= 4  # Table 1 exact; text-quoted figure values approximate


SPEC_TEST_HORIZON = {"salad": 100, "hunting": 200, "scavenging": 200, "factory": 200, "walled-salad": 500,
                     "foodcollector": 1000}
"""Each task's test horizon (SPEC): the length of every validation rollout."""


def test_every_condition_is_evaluated_at_the_test_horizon(tmp_path):
    from train.loop.trainer import resolve
    from train.tasks import get_task, probe

    seen = set()
    for exp in EXPERIMENTS.values():
        for job in plan(exp, "quick", tmp_path):
            if job.is_measurement:
                continue
            cfg = TrainConfig.from_dict(job.config)
            key = (job.task, json.dumps(cfg.env.env_make_kwargs, sort_keys=True, default=str))
            if key in seen:
                continue
            seen.add(key)
            task = get_task(job.task)
            resolved = resolve(cfg, task, probe(task, cfg.env))
            horizon = RELEASED_VALIDATION.get(exp.name, SPEC_TEST_HORIZON[job.task])
            assert resolved.eval.eval_horizon == horizon, (exp.name, job.condition)
    assert len(seen) > 20


def test_tuned_settings_apply_per_task_and_conditions_still_win():
    """Salad trains at the settings study's learning rate; other tasks keep the original default;
    a condition that names its own rate (the study's arms) keeps it.
    """
    assert TrainConfig().dqn.lr == 1e-4  # the original code's default, unchanged for `ecorl train`
    dyn = get_experiment("dynamism")
    lrs = {task: job_config(task, conds[0], dyn.budget("smoke")).dqn.lr for task, conds in dyn.conditions.items()}
    assert lrs == {"salad": 3e-4, "hunting": 1e-4, "scavenging": 1e-4, "factory": 1e-4, "foodcollector": 1e-4}
    settings = get_experiment("settings")
    arm = next(c for c in settings.conditions["salad"] if c.name == "rf-lr1e-4")
    assert job_config("salad", arm, settings.budget("smoke")).dqn.lr == 1e-4


def test_headline_waypoint_is_the_headline_with_the_released_reward():
    """Same conditions and budgets as the headline; only the reward differs. Both headlines' dynamic
    non-episodic runs share every setting but the length with a settings arm, so they continue it.
    """
    plain, waypoint = get_experiment("headline"), get_experiment("headline-waypoint")
    for a, b in zip(plain.conditions["salad"], waypoint.conditions["salad"], strict=True):
        assert a.name == b.name and {**a.overrides, "reward": "waypoint"} == b.overrides
        assert job_config("salad", a, plain.budget("paper")).env.reward == "sparse"
    settings = get_experiment("settings")
    for exp, arm_name in ((plain, "rf-lr3e-4"), (waypoint, "rf-waypoint")):
        arm = next(c for c in settings.conditions["salad"] if c.name == arm_name)
        study = job_config("salad", arm, settings.budget("paper"))
        long = job_config("salad", exp.conditions["salad"][3], exp.budget("paper"))
        assert exp.conditions["salad"][3].name == "dynamic-reset-free"
        assert long.replace(steps=study.run.steps) == study, arm_name


SALAD_PAIR = {"p0": "static-reset-free", "p0.1": "dynamic-reset-free"}


@pytest.mark.parametrize("sweep_name, fig4, task, same", [
    ("dynamism-sweep", "headline", "salad", SALAD_PAIR),
    ("dynamism-sweep-waypoint", "headline-waypoint", "salad", SALAD_PAIR),
    ("dynamism-sweep", "dynamism", "hunting", {"p0": "static-reset-free", "p0.2": "dynamic-reset-free"}),
])
def test_the_dynamism_sweep_repeats_fig_4s_non_episodic_pair(sweep_name, fig4, task, same):
    """Fig. 6's p 0 and its task's Fig. 4 dynamism build the very configs of Fig. 4's non-episodic runs of the
    same task and reward, so the shipped Fig. 4 runs stand for them; every other level differs from all of
    Fig. 4's conditions.
    """
    sweep, panel = get_experiment(sweep_name), get_experiment(fig4)
    ours = {c.name: job_config(task, c, sweep.budget("paper")) for c in sweep.conditions[task]}
    theirs = {c.name: job_config(task, c, panel.budget("paper")) for c in panel.conditions[task]}
    for name, config in ours.items():
        if name in same:
            assert config == theirs[same[name]], name
        else:
            assert all(config != other for other in theirs.values()), name


def test_dynamism_waypoint_is_fig_4_with_the_released_reward():
    """Each condition of `dynamism-waypoint` is the `dynamism` condition of the same name and task with the
    waypoint reward, and nothing else changed.
    """
    waypoint, fig4 = get_experiment("dynamism-waypoint"), get_experiment("dynamism")
    assert waypoint.tasks == ("hunting", "factory")  # scavenging's waypoint reward is its sparse one
    for task in waypoint.tasks:
        ours = {c.name: c for c in waypoint.conditions[task]}
        assert list(ours) == [c.name for c in fig4.conditions[task]]
        for cond in fig4.conditions[task]:
            plain = job_config(task, cond, fig4.budget("paper"))
            released = job_config(task, ours[cond.name], waypoint.budget("paper"))
            assert plain.env.reward == "sparse" and released.env.reward == "waypoint"
            # factory keeps the flat ladder its shipped runs trained with ('factory-released' has the released one)
            flat = {"env_kwargs": {}} if task == "factory" else {}
            assert released.env.env_kwargs == ({"reward_ladder": "flat"} if task == "factory" else {})
            assert released.replace(reward="sparse", **flat) == plain, (task, cond.name)


@pytest.mark.parametrize(("arm", "fig4_name"), [("rf-lr3e-4", "dynamism"), ("rf-waypoint-lr3e-4", "dynamism-waypoint")])
def test_hunting_gap_is_fig_4s_dynamic_non_episodic_hunting_with_another_rate(arm, fig4_name):
    """Each `hunting-gap` arm builds Fig. 4's dynamic non-episodic hunting config of its reward with only the
    learning rate changed (from the released scripts' 1e-4 to 3e-4).
    """
    ours = _paper_config("hunting-gap", "hunting", arm)
    theirs = _paper_config(fig4_name, "hunting", "dynamic-reset-free")
    assert (theirs.dqn.lr, ours.dqn.lr) == (1e-4, 3e-4)
    assert ours.replace(lr=1e-4) == theirs


def test_lr_sweep_repeats_the_arms_it_shares_a_rate_with():
    """Fig. 7's sweep spans the released script's five rates in both modes; its 1e-4 and 3e-4 arms build the
    very configs of the salad-gap and settings arms they repeat, so those runs stand for them.
    """
    sweep = get_experiment("lr-sweep")
    arms = {c.name: c for c in sweep.conditions["salad"]}
    assert sorted({job_config("salad", c, sweep.budget("paper")).dqn.lr for c in arms.values()}) == [
        1e-5, 3e-5, 1e-4, 3e-4, 1e-3]
    for name, (other, other_arm) in {"ep-lr1e-4": ("salad-gap", "ep-lr1e-4"), "rf-lr1e-4": ("salad-gap", "rf-lr1e-4"),
                                     "ep-lr3e-4": ("settings", "ep-h100-waypoint"),
                                     "rf-lr3e-4": ("settings", "rf-waypoint")}.items():
        assert job_config("salad", arms[name], sweep.budget("paper")) == \
            _paper_config(other, "salad", other_arm), name


def test_shaping_no_shaping_salad_is_the_sparse_sweeps_p0_05_run_longer():
    """Fig. 5's salad 'no shaping' arm trains Fig. 6 (left)'s sparse p 0.05 arm for 1.25 M steps instead of
    1 M, nothing else changed (the exploration schedule does not depend on the length): its first 1 M steps
    are a replicate of the shipped p 0.05 run, and every other shaping arm differs from it.
    """
    shaping = get_experiment("shaping")
    p005 = _paper_config("dynamism-sweep", "salad", "p0.05")
    ours = {c.name: job_config("salad", c, shaping.budget("paper")) for c in shaping.conditions["salad"]}
    assert (p005.run.steps, ours["no-shaping"].run.steps) == (1_000_000, 1_250_000)
    assert ours["no-shaping"].replace(steps=p005.run.steps) == p005
    assert all(cfg.replace(steps=p005.run.steps) != p005 for name, cfg in ours.items() if name != "no-shaping")


def _random_policy_stream(task: str, reward: str, steps: int = 20_000) -> tuple[np.ndarray, np.ndarray]:
    """Observations and rewards of a uniform random policy in ``task``'s non-episodic world, shaped and dynamic."""
    env = gym.make(get_task(task).env_id, reward=reward, reset_free=True, dynamism=DYNAMIC_P[task],
                   shaping=SHAPING_SCHEDULE[task]).unwrapped
    obs, _ = env.reset(seed=5)
    actions = np.random.default_rng(0).integers(env.action_space.n, size=steps)
    stream = [env.step(int(a))[:2] for a in actions]
    return np.stack([obs, *(o for o, _ in stream)]), np.array([r for _, r in stream])


@pytest.mark.parametrize("task", GRID_TASKS)
def test_the_modes_called_sparse_equivalent_are_exactly_those_that_reward_as_sparse_does(task):
    """`SPARSE_EQUIVALENT` lists, per task, the reward modes under which a random policy sees the very observations
    and rewards of the sparse mode, and no other: the arms the experiments leave out would repeat a listed arm.
    """
    sparse = _random_policy_stream(task, "sparse")
    assert sparse[1].any(), task  # the stream reaches rewards, so equal streams say something
    same = set()
    for mode in ("waypoint", "subgoal", "one_time", "distance"):
        obs, rewards = _random_policy_stream(task, mode)
        if np.array_equal(obs, sparse[0]) and np.array_equal(rewards, sparse[1]):
            same.add(mode)
    assert same == set(SPARSE_EQUIVALENT.get(task, ())), task


def test_shaping_gap_arms_are_fig_5s_salad_arms_with_one_setting_changed():
    """Each `shaping-gap` arm builds Fig. 5's salad env-shaping (sparse) or no-shaping config with only the named
    setting changed: the released script's longer spawn windows, or its learning rate.
    """
    gap, fig5 = get_experiment("shaping-gap"), get_experiment("shaping")
    ours = {c.name: job_config("salad", c, gap.budget("paper")) for c in gap.conditions["salad"]}
    theirs = {c.name: job_config("salad", c, fig5.budget("paper")) for c in fig5.conditions["salad"]}
    shaped, plain = theirs["env-shaping-sparse"], theirs["no-shaping"]
    assert ours["env-shaping-560k"] == shaped.replace(shaping=RELEASED_SALAD_SCHEDULES["560k"])
    assert ours["env-shaping-840k"] == shaped.replace(shaping=RELEASED_SALAD_SCHEDULES["840k"])
    assert ours["env-shaping-lr1e-4"] == shaped.replace(lr=1e-4)
    assert ours["no-shaping-lr1e-4"] == plain.replace(lr=1e-4)
    assert (shaped.dqn.lr, shaped.env.shaping) == (3e-4, RELEASED_SALAD_SCHEDULES["280k"])


def test_hunting_inventory_arms_are_the_shipped_fig_4_runs_with_only_the_inventory_read_8_times():
    inv = get_experiment("hunting-inventory")
    for arm, shipped in (("rf-sparse-inv8", "dynamism"), ("rf-waypoint-inv8", "dynamism-waypoint")):
        exp = get_experiment(shipped)
        [cond] = [c for c in exp.conditions["hunting"] if c.name == "dynamic-reset-free"]
        [ours] = [c for c in inv.conditions["hunting"] if c.name == arm]
        theirs = job_config("hunting", cond, exp.budget("paper"))
        assert theirs.dqn.inventory_repeat == 1
        assert job_config("hunting", ours, inv.budget("paper")) == theirs.replace(inventory_repeat=8)


def test_make_axe_released_input_arm_is_its_dynamic_non_episodic_arm_with_only_the_inventory_read_8_times():
    exp = get_experiment("factory-make-axe")
    arms = {c.name: job_config("factory", c, exp.budget("paper")) for c in exp.conditions["factory"]}
    assert arms["dynamic-reset-free"].dqn.inventory_repeat == 1
    assert arms["dynamic-reset-free-inv8"] == arms["dynamic-reset-free"].replace(inventory_repeat=8)



@pytest.mark.parametrize(("arm", "baseline"), [
    (("factory-behaviour", "factory", "make-axe-eps-floor-0.3"),
     ("factory-make-axe", "factory", "dynamic-reset-free-inv8")),
    (("factory-behaviour", "factory", "released-eps-floor-0.3"), ("factory-released", "factory", "dynamic-reset-free")),
    (("hunting-behaviour", "hunting", "eps-floor-0.3-inv8"), ("hunting-inventory", "hunting", "rf-waypoint-inv8")),
])
def test_an_epsilon_floor_arm_is_its_baseline_with_only_the_floor_raised(arm, baseline):
    theirs = _paper_config(*baseline)
    assert theirs.dqn.eps_end == 0.1
    assert _paper_config(*arm) == theirs.replace(eps_end=0.3)


def test_the_static_epsilon_floor_arm_differs_from_the_dynamic_one_in_dynamism_alone():
    dynamic = _paper_config("hunting-behaviour", "hunting", "eps-floor-0.3-inv8")
    assert dynamic.env.dynamism == 0.2
    assert _paper_config("hunting-behaviour", "hunting", "static-eps-floor-0.3-inv8") == dynamic.replace(dynamism=0.0)

# (experiment, task, condition) pairs that build the very same config: one run stands for both, so the
# shipped results copy it and the not-yet-run list counts it once (docs/results/paper/README.md).
SAME_RUNS = [
    (("shaping", "scavenging", "no-shaping"), ("dynamism", "scavenging", "static-reset-free")),
    (("shaping", "factory", "no-shaping"), ("dynamism", "factory", "static-reset-free")),
    (("rnd", "factory", "static"), ("dynamism", "factory", "static-reset-free")),
    (("rnd", "factory", "dynamic"), ("dynamism", "factory", "dynamic-reset-free")),
    (("rnd", "factory", "env-shaping"), ("shaping", "factory", "env-shaping-sparse")),
]


@pytest.mark.parametrize(("copy", "source"), SAME_RUNS)
def test_runs_that_stand_for_each_other_build_the_same_config(copy, source):
    assert _paper_config(*copy) == _paper_config(*source)


@pytest.mark.parametrize(("copy", "source"), SAME_RUNS)
def test_a_shipped_copy_is_its_source_file_for_file(copy, source):
    """Where both are shipped, the copy holds the source's files unchanged (and where one is, both are); it may
    add only the film that its own experiment's report renders.
    """
    root = REPO / "docs" / "results" / "paper"
    copy_dir, source_dir = root.joinpath(*copy), root.joinpath(*source)
    if not copy_dir.exists():
        pytest.skip(f"{'/'.join(copy)} is not shipped yet")
    assert source_dir.exists(), f"{copy_dir} is shipped without its source {source_dir}"
    film = {Path(name) for name in FILM_FILES}
    files = {p.relative_to(source_dir) for p in source_dir.rglob("*") if p.is_file()} - film
    copied = {p.relative_to(copy_dir) for p in copy_dir.rglob("*") if p.is_file()} - film
    assert copied == files
    assert all((copy_dir / f).read_bytes() == (source_dir / f).read_bytes() for f in files)


def test_salad_shaping_released_arms_are_fig_5s_with_only_the_rate_and_the_inventory_changed():
    released, paper = get_experiment("salad-shaping-released"), get_experiment("shaping")
    shipped = {c.name: job_config("salad", c, paper.budget("paper")) for c in paper.conditions["salad"]}
    arms = {c.name: job_config("salad", c, released.budget("paper")) for c in released.conditions["salad"]}
    assert list(arms) == ["env-shaping-sparse", "no-shaping", "distance-reward", "one-time-reward"]
    for name, cfg in arms.items():
        assert (shipped[name].dqn.lr, shipped[name].dqn.inventory_repeat) == (3e-4, 1)
        assert cfg == shipped[name].replace(lr=1e-4, inventory_repeat=8)


def test_scavenging_released_arms_train_the_released_world_and_differ_in_the_spawn_window_alone():
    exp = get_experiment("scavenging-released")
    arms = {c.name: job_config("scavenging", c, exp.budget("paper")) for c in exp.conditions["scavenging"]}
    plain = arms.pop("no-shaping")
    assert (plain.env.dynamism, plain.env.env_kwargs, plain.env.reset_free, plain.env.reward) == (
        0.25, {"predator_respawn": "off-agent", "food_growth": 0.2}, True, "sparse")  # off-agent: SHIPPED_RULES
    assert (plain.eval.eval_dynamism, plain.eval.eval_env_kwargs) == (0.25, {"predator_count": 1,
                                                                           "predator_lifespan": 1})
    assert plain.dqn.lr == 1e-4 and plain.env.shaping == "0"
    assert {name: cfg.env.shaping for name, cfg in arms.items()} == {
        "env-shaping-540k": "linear:1:0:540000", "env-shaping-1080k": "linear:1:0:1080000"}
    for cfg in arms.values():  # both name the window they grow food in (with_window_named)
        window = {"spawn_window": "original", **plain.env.env_kwargs}
        assert cfg == plain.replace(shaping=cfg.env.shaping, env_kwargs=window)


def test_scavenging_released_fig4_is_fig_4_in_the_released_world_with_the_sweeps_dynamism():
    exp, world = get_experiment("scavenging-released-fig4"), get_experiment("scavenging-released")
    [plain] = world.select_conditions("scavenging", ["no-shaping"])
    released = job_config("scavenging", plain, world.budget("paper"))
    arms = {c.name: job_config("scavenging", c, exp.budget("paper")) for c in exp.conditions["scavenging"]}
    assert arms["dynamic-reset-free"] == released.replace(dynamism=0.4)
    assert arms["static-reset-free"] == released.replace(dynamism=0.0)
    for name in ("static", "dynamic"):
        episodic = arms[f"{name}-episodic"]
        assert not episodic.env.reset_free
        assert episodic == arms[f"{name}-reset-free"].replace(reset_free=False)


def test_walls_released_is_walls_with_the_released_network():
    exp, paper = get_experiment("walls-released"), get_experiment("walls")
    assert [c.name for c in exp.conditions["walled-salad"]] == [c.name for c in paper.conditions["walled-salad"]]
    for ours, theirs in zip(exp.conditions["walled-salad"], paper.conditions["walled-salad"]):
        released = job_config("walled-salad", ours, exp.budget("paper"))
        shipped = job_config("walled-salad", theirs, paper.budget("paper"))
        assert released.dqn.inventory_repeat == 8 and shipped.dqn.inventory_repeat == 1
        assert released == shipped.replace(inventory_repeat=8)


def test_every_experiment_keeps_the_rules_its_shipped_runs_trained_with_and_names_its_window():
    """`SHIPPED_RULES`: the envs' default is the original's predator respawn; every scavenging condition keeps the
    shipped one beside its own env_kwargs; no condition of any task sets anything else (its directed steps included:
    every shipped run trained with the original's); every condition whose world grows objects in a shaping window
    names the original code's window, and no other condition names one (`with_window_named`).
    """
    for exp in EXPERIMENTS.values():
        for task, conditions in exp.conditions.items():
            for c in conditions:
                if c.measure:
                    continue
                env = job_config(task, c, exp.budget("smoke")).env
                kwargs = env.env_kwargs
                kept = {"predator_respawn": "off-agent"} if task == "scavenging" else {}
                own = c.overrides.get("env_kwargs", {})
                assert kwargs == {**kept, **own}, (exp.name, task, c.name)  # a condition's own rule wins
                assert "directed_moves" not in kwargs, (exp.name, task, c.name)
                window = shaping_window_acts(task, env.shaping, own)
                assert kwargs.get("spawn_window") == ("original" if window else None), (exp.name, task, c.name)


def test_shaping_window_acts_where_objects_grow_near_the_agent():
    """A condition names its window where one acts: shaped salad, walled salad and scavenging, and hunting's
    released spawns; not without shaping, nor in hunting's easy-deer shaping or in factory's cooperative workers.
    """
    assert shaping_window_acts("salad", "linear:1:0:280000", {})
    assert shaping_window_acts("walled-salad", 0.5, {})
    assert shaping_window_acts("scavenging", "linear:1:0:540000", {"predator_respawn": "off-agent"})
    assert shaping_window_acts("hunting", "linear:1:0:260000", {"shaping_mechanism": "nearby"})
    assert not shaping_window_acts("hunting", "linear:1:0:100000", {})
    assert not shaping_window_acts("salad", 0.0, {})
    assert not shaping_window_acts("factory", "linear:0.2:0:400000", {})


def test_every_shipped_run_is_the_run_its_experiment_builds():
    """Each shipped run directory's config.json has the settings its experiment builds at the paper's budget, so
    ``ecorl run NAME --budget paper --out docs/results/paper`` takes it as its own run (done, or resumed) and a
    re-run trains what is shipped (the kept rules included).
    """
    root = REPO / "docs/results/paper"
    checked = 0
    for exp in EXPERIMENTS.values():
        for task, conditions in exp.conditions.items():
            for c in conditions:
                path = root / exp.name / task / c.name / "config.json"
                if c.measure or not path.exists():
                    continue
                saved = TrainConfig.from_dict(json.loads(path.read_text()))
                assert setting_differences(saved, job_config(task, c, exp.budget("paper"))) == [], path
                checked += 1
    assert checked > 150

