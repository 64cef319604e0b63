"""Every experiment's jobs build the same `TrainConfig` as before the restructure (issue 11).

``catalog_golden.json`` was dumped from the code before train/ was split into layers (commit dc84084): the
defaults of `TrainConfig`, the experiments' order, and for every experiment its description and each job's
settings that differ from the defaults. Regenerated once, on purpose, for issue 48: three new settings
(``completion_terminal``, ``eval_dynamism``, ``eval_env_kwargs``, at defaults that change no job), the released
experiments (`train.experiments.released`) and factory's shipped subgoal-mode arms naming the flat ladder
(``reward_ladder=flat``), now that the released ladder is factory's default; every other job is unchanged.
``hunting-inventory`` was appended later (its entry dumped from its own code; nothing else changed).
``hunting-behaviour`` gained two arms with the released network (``eps-1-inv8``, ``eps-floor-0.3-inv8``) and a
sentence; its entry was dumped again from its code, its two earlier arms' jobs checked unchanged first.
``factory-make-axe`` gained one arm, its dynamic non-episodic condition with the released network
(``dynamic-reset-free-inv8``), and a sentence; dumped the same way, its nine earlier arms' jobs checked unchanged.
``walls``' paper budget went from 3 seeds to the 10 its shipped runs have (its ten paper jobs' ``seeds`` edited).
``hunting-behaviour`` gained a static arm (``static-eps-floor-0.3-inv8``) and a sentence, and ``factory-behaviour``
was appended; both dumped from their code, ``hunting-behaviour``'s earlier jobs checked unchanged first.
``salad-shaping-released`` and ``scavenging-released`` were appended (dumped from their code; nothing else changed),
then ``scavenging-released-fig4`` and ``walls-released`` the same way.
When ecorl's scavenging took the original code's predator respawn as its default, the 42 scavenging jobs of
``dynamism``, ``shaping``, ``scavenging-released`` and ``scavenging-released-fig4`` gained ``predator_respawn:
off-agent`` in their ``env_kwargs`` (`SHIPPED_RULES`, the rule their shipped runs trained with), checked to be the
only change, and were dumped again. When hunting's and factory's directed steps took the original code's rule as
their default, the 30 jobs whose creatures take such steps (``shaping``'s five hunting arms, its two factory
env-shaping arms, ``rnd``'s factory env-shaping arm and ``factory-make-axe``'s two env-shaping arms, at three
budgets) gained ``directed_moves: current-free`` the same way; a condition re-run under the original rule and
shipped lost it again, until none kept it. When the shaping window took the original code's rule (clipped at the
grid's edge) as its default, the 63 jobs in which a window acts (`shaping_window_acts`: the env-shaping arms of
salad, walled salad and scavenging, and hunting's released spawns, at three budgets) gained ``spawn_window:
shifted`` the same way, checked to be the only change; ``salad-shaping-released``'s ``env-shaping-sparse``,
re-run under the original window, names ``spawn_window: original`` instead (its three jobs and its entry in the
experiment's description), and so later each arm re-run under it, each checked to be the only change, until all 21
conditions with a window named it and the experiments dropped the shifted window (`with_window_named`).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from train.config import TrainConfig
from train.experiments.catalog import BUDGETS, EXPERIMENTS, job_config

GOLDEN = json.loads((Path(__file__).parent / "catalog_golden.json").read_text())


def _flat(cfg: TrainConfig) -> dict:
    """Every field of a config by its section-less name (JSON values)."""
    return json.loads(json.dumps({k: v for section in cfg.to_dict().values() for k, v in section.items()}))


def test_the_defaults_are_unchanged():
    assert _flat(TrainConfig()) == GOLDEN["defaults"]


def test_the_same_experiments_exist():
    assert list(EXPERIMENTS) == GOLDEN["order"]


@pytest.mark.parametrize("name", list(GOLDEN["experiments"]))
def test_every_job_builds_the_same_config(name):
    exp, golden = EXPERIMENTS[name], GOLDEN["experiments"][name]
    assert json.loads(json.dumps(exp.describe())) == golden["describe"]
    jobs = {}
    for budget in BUDGETS:
        b = exp.budget(budget)
        for task, conds in exp.conditions.items():
            for c in conds:
                key = f"{budget}/{task}/{c.name}"
                if c.measure:
                    jobs[key] = {"measure": c.measure, "seeds": b.seeds, "steps": b.steps_for(task)}
                else:
                    flat = _flat(job_config(task, c, b))
                    jobs[key] = {k: v for k, v in flat.items() if v != GOLDEN["defaults"][k]}
    assert jobs == golden["jobs"]
