"""The paper's experiments as data: conditions x tasks x seeds x steps x evaluation, at three budgets.

An `Experiment` names a figure or table of the paper. For each task it lists `Condition`s, each a name and
the flat `TrainConfig` overrides that make it (env knobs, reward mode, RND). A `Budget` says how many seeds
and steps every condition gets and how often it is evaluated:

* ``smoke``: seconds, for tests (2 seeds, 1 000 steps, evaluation every 500 steps on 10 layouts);
* ``quick``: minutes on a laptop (a few seeds, 10^5 steps);
* ``paper``: the paper's seeds and steps (SPEC's experiment table), evaluation every 5 000 steps on the
  100 validation layouts.

Smaller budgets run the paper's conditions unchanged, only shorter and with fewer seeds: a quick curve is
the beginning of the paper's curve (the exploration decay and the shaping schedules keep the paper's clock;
with epsilon decaying over 15 000 steps instead of 90 000, dynamic episodic salad solved ~1% of the layouts
after 120 000 steps instead of ~17%, 3 seeds). `job_config` builds the `TrainConfig` of one (task, condition,
budget) of an experiment.

The values the paper leaves open (each task's dynamic p, shaping schedule and base task, the tuned trainer
settings, the steps per seed) are in `train.experiments.choices`, with where each comes from.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from types import MappingProxyType
from typing import Any

from train.config import TrainConfig
from train.config.checks import unknown_choice
from train.experiments.choices import (
    DYNAMIC_P,
    GRID_TASKS,
    PAPER_STEPS,
    PAPER_TASKS,
    RELEASED_SALAD_SCHEDULES,
    SHAPING_BASE,
    SHAPING_SCHEDULE,
    SHIPPED_RULES,
    SPARSE_EQUIVALENT,
    TUNED,
    with_window_named,
)
from train.experiments.conditions import (
    FLAT_LADDER,
    SMOKE,
    dynamism_conditions,
    quick,
    shaping_conditions,
    sweep_conditions,
    walls_conditions,
    with_reward,
)
from train.experiments.experiment import BUDGETS, Budget, Condition, Experiment
from train.experiments.released import released_experiments

__all__ = ["BUDGETS", "DYNAMIC_P", "EXPERIMENTS", "GRID_TASKS", "PAPER_STEPS", "PAPER_TASKS",
           "RELEASED_SALAD_SCHEDULES", "SHAPING_BASE", "SHAPING_SCHEDULE", "SHIPPED_RULES", "SMOKE",
           "SPARSE_EQUIVALENT", "TUNED", "WAYPOINT_TASKS", "Budget", "Condition", "Experiment", "get_experiment",
           "job_config"]

# ---- building configs ----------------------------------------------------------------------------------


def job_config(task: str, condition: Condition, budget: Budget) -> TrainConfig:
    """The full `TrainConfig` of one condition of one task at ``budget`` (the task's tuned settings, then the
    condition's, then the budget's: a later one wins).
    """
    flat: dict[str, Any] = {"task": task, **TUNED.get(task, {}), **condition.overrides}
    own = flat.get("env_kwargs", {})
    flat["env_kwargs"] = {**SHIPPED_RULES.get(task, {}), **own}
    flat.update(budget.overrides)
    flat.update(budget.task_overrides.get(task, {}))
    steps = budget.steps_for(task)
    flat.update(seeds=budget.seeds, steps=steps, eval_every=budget.eval_every, threads=1, progress=False)
    flat.setdefault("checkpoint_every", max(budget.eval_every, min(50_000, math.ceil(steps / 10))))
    if budget.eval_rollouts is not None:
        flat.setdefault("eval_rollouts", budget.eval_rollouts)
    return TrainConfig().replace(**flat)


# ---- the experiments -----------------------------------------------------------------------------------

SETTINGS_LR = 3e-4
"""Learning rate at the centre of the settings study (best of two earlier 10-seed runs at 500 000 steps: 27.5 %
at 3e-4, 9.3 % at 1e-4); every other arm varies one setting around it and names its rate (not `TUNED`)."""


def _settings_conditions() -> tuple[Condition, ...]:
    """Salad p = 0.1: the settings where the paper's text and the released code disagree, one at a time.

    Listed in the order they run: the learning-rate sweep first (the paper tuned it), then the reward of
    the released scripts, the episodic horizons of the text (200) and of the released script (100), the
    released training loop's replay of unsolved layouts, and the text's batch size.
    """
    p = DYNAMIC_P["salad"]
    rf = {"dynamism": p, "reset_free": True, "lr": SETTINGS_LR}
    ep = {"dynamism": p, "reset_free": False, "lr": SETTINGS_LR}
    return (
        Condition("rf-lr1e-4", "non-episodic, lr 1e-4 (released default)", {**rf, "lr": 1e-4}),
        Condition("rf-lr3e-4", "non-episodic, lr 3e-4", rf),
        Condition("rf-lr1e-3", "non-episodic, lr 1e-3", {**rf, "lr": 1e-3}),
        Condition("rf-waypoint", "non-episodic, waypoint reward (released scripts)", {**rf, "reward": "waypoint"}),
        Condition("ep-h200", "episodic, horizon 200 (paper text)", {**ep, "horizon": 200}),
        Condition("ep-h100", "episodic, horizon 100 (released script)", {**ep, "horizon": 100}),
        Condition("ep-h100-replay", "episodic, horizon 100, unsolved layouts replayed (released loop)",
                  {**ep, "horizon": 100, "env_kwargs": {"replay_unsolved": 500}}),
        Condition("rf-batch256", "non-episodic, batch 256 (paper text)", {**rf, "batch_size": 256}),
        Condition("ep-h100-waypoint", "episodic, horizon 100, waypoint reward",
                  {**ep, "horizon": 100, "reward": "waypoint"}),
    )


def _gap_conditions() -> tuple[Condition, ...]:
    """Issue 18's arms: the waypoint arms of the settings study (episodic H 100, non-episodic; lr 3e-4), each
    with one more setting of the released code changed.

    The baselines are the settings study's ``ep-h100-waypoint`` and ``rf-waypoint`` (and ``rf-lr3e-4`` for
    the sparse arm). Timeouts as terminals only exist episodically (a non-episodic world is never cut by a
    time limit).
    """
    p = DYNAMIC_P["salad"]
    ep = {"dynamism": p, "reset_free": False, "lr": SETTINGS_LR, "horizon": 100, "reward": "waypoint"}
    rf = {"dynamism": p, "reset_free": True, "lr": SETTINGS_LR, "reward": "waypoint"}
    one = {"env_kwargs": {"initial_count": 1}}
    inv8 = {"inventory_repeat": 8}
    return (
        Condition("ep-init1", "episodic H 100, waypoint, 1 of each ingredient (released sweep's 1/1)", {**ep, **one}),
        Condition("ep-lr1e-4", "episodic H 100, waypoint, lr 1e-4", {**ep, "lr": 1e-4}),
        Condition("ep-timeouts", "episodic H 100, waypoint, timeouts stored as terminals (released loop)",
                  {**ep, "timeouts_terminal": True}),
        Condition("rf-init1", "non-episodic, waypoint, 1 of each ingredient (released sweep's 1/1)", {**rf, **one}),
        Condition("rf-lr1e-4", "non-episodic, waypoint, lr 1e-4", {**rf, "lr": 1e-4}),
        Condition("ep-inv8", "episodic H 100, waypoint, inventory fed 8 times (released script)", {**ep, **inv8}),
        Condition("rf-inv8", "non-episodic, waypoint, inventory fed 8 times (released script)", {**rf, **inv8}),
        Condition("rf-sparse-inv8", "non-episodic, sparse reward, inventory fed 8 times (released script)",
                  {**rf, "reward": "sparse", **inv8}),
    )


LR_SWEEP = (("1e-5", 1e-5), ("3e-5", 3e-5), ("1e-4", 1e-4), ("3e-4", 3e-4), ("1e-3", 1e-3))
"""The released salad script's learning rates (its names and values), the paper's Fig. 7 sweep."""


def _lrsweep_conditions() -> tuple[Condition, ...]:
    """The released salad sweep (Fig. 7): each rate, waypoint reward, episodic (H 100) and non-episodic.

    Two rates of each mode share every setting with arms run before (3e-4: the settings study's
    ``ep-h100-waypoint`` and ``rf-waypoint``; 1e-4: the salad-gap study's ``ep-lr1e-4`` and ``rf-lr1e-4``).
    """
    p = DYNAMIC_P["salad"]
    modes = (("ep", "episodic H 100", {"reset_free": False, "horizon": 100}),
             ("rf", "non-episodic", {"reset_free": True}))
    return tuple(Condition(f"{mode}-lr{name}", f"{label}, waypoint, lr {name}",
                           {"dynamism": p, "reward": "waypoint", "lr": lr, **knobs})
                 for mode, label, knobs in modes for name, lr in LR_SWEEP)


def _salad_experiments() -> list[Experiment]:
    """The salad-only experiments: the headline, the settings study and Fig. 2."""
    salad_dyn = dynamism_conditions("salad")
    return [
        Experiment(
            "headline", "Fig. 4 (salad panel)", "Salad: dynamism and resets",
            "Salad-making trained static or dynamic (p = 0.1), episodic or non-episodic, with the paper text's "
            "sparse reward. The paper reports that static non-episodic training fails and dynamism helps; the "
            "quick budget (3 seeds x 120 000 steps) is far too short to show it.",
            {"salad": salad_dyn}, {"salad": 1_000_000}, 10,
            {"smoke": SMOKE, "quick": quick(3, 120_000)}, heatmaps=True, videos=True),
        Experiment(
            "headline-waypoint", "Fig. 4 (salad panel), released scripts' reward", "Salad: dynamism and resets, "
            "waypoint reward",
            "The headline's four conditions trained with the reward of the released Fig. 4 script (+1 for every "
            "ingredient picked up, farmable; +100 for the salad) instead of the paper text's sparse reward. "
            "The settings study found it the strongest setting after the learning rate. `make demo` runs its two "
            "non-episodic conditions at the quick budget, sized to the machine's speed (`ecorl run --minutes`).",
            {"salad": with_reward(salad_dyn, "waypoint", "waypoint reward")}, {"salad": 1_000_000}, 10,
            {"smoke": SMOKE, "quick": quick(3, 100_000)}, heatmaps=True, videos=True),
        Experiment(
            "settings", "Fig. 4 (salad), settings", "Which settings reproduce the salad headline",
            "Dynamic salad (p = 0.1), episodic and non-episodic, varying one setting at a time where the "
            "paper's text and the released code disagree (reward, learning rate, batch size, episodic "
            "horizon). Its paper budget is the study's: 10 seeds x 500 000 steps per arm.",
            {"salad": _settings_conditions()}, {"salad": 500_000}, 10,
            {"smoke": SMOKE, "quick": quick(3, 120_000)}, milestones=(250_000, 500_000)),
        Experiment(
            "salad-gap", "Fig. 4 (salad), the rest of the gap", "Why learned salad seeds plateau below the paper",
            "Issue 18's arms around the settings study's waypoint arms (dynamic salad p = 0.1, lr 3e-4; baselines "
            "'ep-h100-waypoint' and 'rf-waypoint' of 'settings'): one ingredient of each kind in training (the "
            "released script also sweeps 1/1), lr 1e-4 (no seed diverged at it), the inventory fed 8 times (the "
            "released script's np.repeat; also on the sparse non-episodic arm) and, episodic only, timeouts "
            "stored as terminals (the original's rule). Its paper budget is the study's: 10 seeds x 500 000 "
            "steps per arm.",
            {"salad": _gap_conditions()}, {"salad": 500_000}, 10,
            {"smoke": SMOKE, "quick": quick(3, 120_000)}, milestones=(250_000, 500_000)),
        Experiment(
            "lr-sweep", "Fig. 7", "The learning-rate sweep (salad)",
            "The released salad script's sweep, which the paper says chose its learning rate: lr 1e-5, 3e-5, "
            "1e-4, 3e-4 and 1e-3 on dynamic salad (p = 0.1) with the waypoint reward, episodic (horizon 100) "
            "and non-episodic. The rates 1e-4 and 3e-4 repeat arms of 'salad-gap' and 'settings'. Its paper "
            "budget is the settings study's: 10 seeds x 500 000 steps per arm.",
            {"salad": _lrsweep_conditions()}, {"salad": 500_000}, 10,
            {"smoke": SMOKE, "quick": quick(3, 120_000)}, milestones=(250_000, 500_000)),
        Experiment(
            "episodic-vs-reset-free", "Fig. 2", "Episodic vs non-episodic learning (static salad)",
            "Static salad-making with and without resets; heat-maps of where the agent spends its life.",
            {"salad": (salad_dyn[0], salad_dyn[1])}, {"salad": 1_000_000}, 10,
            {"smoke": SMOKE, "quick": quick(3, 250_000)}, heatmaps=True),
    ]


def _dynamism_sweep_waypoint() -> Experiment:
    """Fig. 6 (left)'s salad levels under the released salad script's waypoint reward."""
    return Experiment(
        "dynamism-sweep-waypoint", "Fig. 6 (left), released script's reward", "How much dynamism (salad), "
        "waypoint reward",
        "The salad half of 'dynamism-sweep' trained with the reward of the released salad script (+1 for "
        "every ingredient picked up, farmable; +100 for the salad), whose sweep lists these levels (all but "
        "0.1 commented out). Its p = 0 and p = 0.1 arms are the configs of 'headline-waypoint''s "
        "non-episodic pair.",
        {"salad": with_reward(sweep_conditions("salad", (0.0, 0.01, 0.05, 0.1, 0.5)), "waypoint",
                               "waypoint reward")},
        {"salad": 1_000_000}, 10, {"smoke": SMOKE, "quick": quick(3, 100_000)})


WAYPOINT_TASKS = tuple(t for t in ("hunting", "scavenging", "factory")
                       if "waypoint" not in SPARSE_EQUIVALENT.get(t, ()))
"""The Fig. 4 tasks whose released scripts train with the waypoint reward besides the text's sparse one, where
it differs from it (the salad's is `headline-waypoint`; the food collector has only its sparse reward;
scavenging's waypoint reward is its sparse one, so its panel is `dynamism`'s)."""


def _dynamism_waypoint() -> Experiment:
    """Fig. 4's other grid panels under the released scripts' waypoint reward."""
    return Experiment(
        "dynamism-waypoint", "Fig. 4, released scripts' reward", "Dynamism and resets, waypoint reward",
        "The 'dynamism' conditions of hunting and factory trained with a waypoint reward instead of the paper "
        "text's sparse reward: hunting's is the released script's (+1 for the first axe and the first food of a "
        "cycle, +100 on completion); factory's pays a flat +1 for every material, axe made or picked up and +100 "
        "per delivery, not the released factory ladder (1 / 100 / 100 / 10 000, experiment 'factory-released'). "
        "The released hunting script trains no sparse arm at all. Salad's is 'headline-waypoint'; scavenging has "
        "no intermediate object, so its waypoint reward is its sparse one and its panel is 'dynamism''s.",
        {t: with_reward(dynamism_conditions(t), "waypoint",
                        "waypoint reward" + (", flat ladder" if t == "factory" else ""),
                        {"env_kwargs": FLAT_LADDER} if t == "factory" else {}) for t in WAYPOINT_TASKS},
        {t: PAPER_STEPS[t] for t in WAYPOINT_TASKS}, 10, {"smoke": SMOKE, "quick": quick(3, 150_000)})


def _hunting_gap() -> Experiment:
    """Fig. 4's dynamic non-episodic hunting, which learned under neither reward, at salad's learning rate."""
    rf = {"dynamism": DYNAMIC_P["hunting"], "reset_free": True, "lr": 3e-4}
    label = f"dynamic p={DYNAMIC_P['hunting']:g}, non-episodic, lr 3e-4"
    return Experiment(
        "hunting-gap", "Fig. 4 (hunting), settings", "Why dynamic non-episodic hunting does not learn",
        "Fig. 4's dynamic non-episodic hunting, which learned in no seed at the released scripts' lr 1e-4 with "
        "either reward, at lr 3e-4: the rate that decides whether reset-free salad is learned at all.",
        {"hunting": (Condition("rf-lr3e-4", label, rf),
                     Condition("rf-waypoint-lr3e-4", f"{label}, waypoint reward", {**rf, "reward": "waypoint"}))},
        {"hunting": PAPER_STEPS["hunting"]}, 10, {"smoke": SMOKE, "quick": quick(3, 150_000)})


def _shaping_gap() -> Experiment:
    """Fig. 5's salad environment shaping, which did no better than no shaping, with the released shaping script's
    longer spawn windows and its learning rate.
    """
    base = {**SHAPING_BASE["salad"], "reset_free": True, "reward": "sparse"}
    arms = [Condition(f"env-shaping-{name}", f"env shaping over {name} steps (released {window})",
                      {**base, "shaping": RELEASED_SALAD_SCHEDULES[name]})
            for name, window in (("560k", "(80 000, 40 000)"), ("840k", "(120 000, 60 000)"))]
    arms += [Condition("env-shaping-lr1e-4", "env shaping, lr 1e-4 (released scripts)",
                       {**base, "shaping": SHAPING_SCHEDULE["salad"], "lr": 1e-4}),
             Condition("no-shaping-lr1e-4", "no shaping, lr 1e-4 (released scripts)", {**base, "lr": 1e-4})]
    return Experiment(
        "shaping-gap", "Fig. 5 (salad), settings", "Salad's environment shaping with the released script's settings",
        "Fig. 5's salad environment shaping (sparse reward) did no better than no shaping: its window has widened to "
        "the whole grid by 280 000 steps, while exploration is still mostly random. Here the released shaping "
        "script's two longer windows (full grid at 560 000 and 840 000 steps) and its learning rate, 1e-4 (with no "
        "shaping at the same rate to compare), each with the rest of Fig. 5's arm unchanged.",
        {"salad": tuple(arms)}, {"salad": 1_250_000}, 10, {"smoke": SMOKE, "quick": quick(3, 120_000)})


def _task_experiments() -> list[Experiment]:
    """The experiments over several tasks: Fig. 4, 5, 6, 8-10 and Table 1."""
    shaping_steps = dict.fromkeys(PAPER_TASKS, 1_250_000)
    return [
        Experiment(
            "dynamism", "Fig. 4", "Dynamism and resets on every task",
            "Per task: {static, dynamic} x {episodic, non-episodic}; evaluation on the static episodic test MDP.",
            {t: dynamism_conditions(t) for t in PAPER_TASKS}, {t: PAPER_STEPS[t] for t in PAPER_TASKS}, 10,
            {"smoke": SMOKE, "quick": quick(3, 150_000)}),
        _dynamism_waypoint(),
        _hunting_gap(),
        Experiment(
            "dynamism-sweep", "Fig. 6 (left, middle)", "How much dynamism",
            "Non-episodic training as the dynamic event probability grows: salad resource probability, hunting "
            "deer movement probability.",
            {"salad": sweep_conditions("salad", (0.0, 0.01, 0.05, 0.1, 0.5)),
             "hunting": sweep_conditions("hunting", (0.0, 0.1, 0.2, 0.4, 0.6))},
            {"salad": 1_000_000, "hunting": 1_500_000}, 10,
            {"smoke": SMOKE, "quick": quick(3, 100_000)}),
        _dynamism_sweep_waypoint(),
        Experiment(
            "shaping", "Fig. 5", "Environment shaping vs reward shaping",
            "Non-episodic training with environment shaping (sparse or subgoal reward), distance-based or "
            "one-time reward shaping, or no shaping. Scavenging has no intermediate object, so its subgoal and "
            "one-time rewards are its sparse one: those two arms would repeat 'env-shaping-sparse' and "
            "'no-shaping' step for step and are not listed. The report films each condition's best seed with "
            "a filmstrip of its first test episode (the paper's Fig. 11-12).",
            {t: shaping_conditions(t) for t in PAPER_TASKS}, shaping_steps, 10,
            {"smoke": SMOKE, "quick": quick(3, 100_000)}, videos=True),
        _shaping_gap(),
        Experiment(
            "rnd", "Fig. 6 (right)", "Dynamism and shaping vs an exploration bonus (factory)",
            "Non-episodic factory: static, static + RND bonus, dynamic (p = 0.2), environment shaping.",
            {"factory": (Condition("static", "static", {"reset_free": True}),
                         Condition("rnd", "static + RND", {"reset_free": True, "rnd": True}),
                         Condition("dynamic", f"dynamic p={DYNAMIC_P['factory']:g}",
                                   {"reset_free": True, "dynamism": DYNAMIC_P["factory"]}),
                         Condition("env-shaping", "env shaping",
                                   {"reset_free": True, "shaping": SHAPING_SCHEDULE["factory"]}))},
            {"factory": 1_250_000}, 10, {"smoke": SMOKE, "quick": quick(3, 100_000)}),
        Experiment(
            "walls", "Fig. 8-10", "Shaping methods in the walled salad maze",
            "Walled salad (10x10, three walls): environment vs reward shaping, episodic and non-episodic, "
            "with visitation heat-maps.",
            {"walled-salad": walls_conditions()},
            {"walled-salad": 1_000_000}, 10, {"smoke": SMOKE, "quick": quick(3, 100_000)}, heatmaps=True,
            panel_per_setting=True),
        Experiment(
            "measure", "Table 1", "What a random policy experiences",
            "Uniform random policy in the non-episodic training envs: first-reward hitting time (static, "
            "dynamic, shaped) and marginal entropy of the egocentric view as dynamism grows.",
            {t: (Condition("hitting-time", "first-reward hitting time (steps)", measure="hitting-time"),
                 Condition("entropy", "marginal view entropy (nats)", measure="entropy"))
             for t in ("factory", "salad", "hunting", "scavenging", "walled-salad")},
            dict.fromkeys(GRID_TASKS, 50_000), 25,
            {"smoke": Budget(3, 2_000, eval_every=500), "quick": Budget(10, 20_000, eval_every=500)}),
    ]


def _experiments() -> dict[str, Experiment]:
    """Every experiment by name, in the order ``ecorl run --list`` shows them, each condition with a shaping window
    naming it (`with_window_named`).
    """
    experiments = (*_salad_experiments(), *_task_experiments(), *released_experiments())
    return {e.name: replace(e, conditions={task: tuple(with_window_named(task, c) for c in conditions)
                                           for task, conditions in e.conditions.items()})
            for e in experiments}


EXPERIMENTS: Mapping[str, Experiment] = MappingProxyType(_experiments())
"""Every named experiment, by name."""


def get_experiment(name: str) -> Experiment:
    """The experiment called ``name`` (with a message listing the choices)."""
    if name not in EXPERIMENTS:
        raise unknown_choice("experiment", name, EXPERIMENTS)
    return EXPERIMENTS[name]
