"""The ``ecorl`` CLI: flags generated from the config dataclasses, help from their docstrings."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys

import pytest

from train.cli import build_parser, main
from train.cli.flags import config_from_args
from train.cli.train import default_run_dir
from train.config import SECTIONS, DQNConfig, TrainConfig, field_docs


def _parse(*argv):
    return config_from_args(build_parser().parse_args(["train", "salad", *argv]))


def test_every_field_is_documented_and_has_a_flag():
    help_text = " ".join(build_parser().parse_args(["train", "salad"]).command_parser.format_help().split())
    for section in SECTIONS.values():
        docs = field_docs(section)
        for f in dataclasses.fields(section):
            assert docs.get(f.name), f"{section.__name__}.{f.name} has no docstring"
            if f.name != "task":
                flag = "--" + f.name.replace("_", "-")
                flag = flag.removesuffix("s") if f.name.endswith("env_kwargs") else flag  # --env-kwarg K=V
                assert flag in help_text
    assert field_docs(DQNConfig)["lr"] in help_text


def test_defaults_are_the_original_hyperparameters():
    cfg = _parse()
    assert cfg == TrainConfig().replace(task="salad")
    d = cfg.dqn
    assert (d.lr, d.gamma, d.batch_size, d.buffer_size, d.tau, d.grad_clip) == (1e-4, 0.99, 64, 500_000, 1e-3, 5.0)
    assert (d.eps_start, d.eps_end, d.eps_decay_steps, d.warmup_steps) == (1.0, 0.1, 90_000, 200)
    assert (d.epoch_steps, d.updates_per_epoch, cfg.env.horizon, cfg.eval.eval_every) == (500, 500, 200, 5000)
    assert (d.view_layers, d.inventory_layers, d.head_layers) == ((64, 64, 32), (16, 16, 16), (16, 16))


def test_flags_set_config_fields():
    cfg = _parse("--dynamism", "0.1", "--shaping", "linear:1:0:280000", "--reset-free", "--reward", "subgoal",
                 "--seeds", "10", "--steps", "5000", "--rnd", "--rnd-weight", "0.5", "--lr", "3e-4",
                 "--view-layers", "32", "32", "--env-kwarg", "initial_count=1", "--env-kwarg", "grid_size=10")
    assert cfg.env.reset_free and cfg.env.dynamism == 0.1 and cfg.env.shaping == "linear:1:0:280000"
    assert cfg.env.env_kwargs == {"initial_count": 1, "grid_size": 10}
    evaluated = config_from_args(build_parser().parse_args(["train", "hunting", "--eval-env-kwarg", "deer_count=1",
                                                            "--eval-dynamism", "0.2"]))
    assert evaluated.eval.eval_env_kwargs == {"deer_count": 1} and evaluated.eval.eval_dynamism == 0.2
    assert cfg.run.seeds == 10 and cfg.rnd.rnd and cfg.rnd.rnd_weight == 0.5 and cfg.dqn.lr == 3e-4
    assert cfg.dqn.view_layers == (32, 32)


def test_integer_flags_take_scientific_notation_and_underscores_but_not_fractions(capsys):
    cfg = _parse("--steps", "1.5e5", "--seeds", "1e1", "--eval-every", "5_000", "--view-layers", "6.4e1", "32")
    assert (cfg.run.steps, cfg.run.seeds, cfg.eval.eval_every, cfg.dqn.view_layers) == (150_000, 10, 5_000, (64, 32))
    assert main(["run", "headline", "--steps", "2e3", "--dry-run"]) == 0
    assert "x 2200 steps" in capsys.readouterr().out  # the budget adds its warm-up of 200
    for text, said in (("1.5", "expected an integer, got 1.5"), ("3e5x", "expected an integer, got 3e5x"),
                       ("inf", "expected an integer, got inf")):
        with pytest.raises(SystemExit):
            _parse("--steps", text)
        assert capsys.readouterr().err.strip() == f"ecorl train: error: argument --steps: {said}"


def test_reset_free_and_episodic_exclude_each_other():
    assert not _parse("--episodic").env.reset_free
    with pytest.raises(SystemExit):
        _parse("--reset-free", "--episodic")


def test_unknown_task_lists_the_choices(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "pacman"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "unknown task 'pacman'" in err and "salad, hunting, scavenging, factory, walled-salad, foodcollector" in err


def test_a_misspelt_task_names_the_nearest_one(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "salda"])
    assert exit_info.value.code == 2
    assert "unknown task 'salda'; did you mean salad? (choose one of salad, hunting" in capsys.readouterr().err


def test_invalid_values_are_reported(capsys):
    with pytest.raises(SystemExit):
        main(["train", "salad", "--reward", "dense"])
    assert main(["train", "salad", "--shaping", "cubic:1"]) == 2
    assert "malformed shaping schedule" in capsys.readouterr().err


def test_a_value_error_names_the_flag_the_user_typed(capsys):
    assert main(["train", "salad", "--eval-every", "0"]) == 2
    assert capsys.readouterr().err.strip() == "ecorl train: error: --eval-every must be an integer >= 1, got 0"


def test_a_misspelt_flag_or_choice_is_named_by_its_subcommand_with_the_nearest_valid_one(capsys):
    for argv, said in ((["train", "salad", "--sed=3"], "ecorl train: error: unrecognized arguments: --sed=3; did "
                        "you mean --seeds?"),
                       (["run", "headline", "--budgte", "paper"], "ecorl run: error: unrecognized arguments: --budgte "
                        "paper; did you mean --budget?"),
                       (["train", "salad", "--seed", "3"], "ecorl train: error: unrecognized arguments: --seed 3; "
                        "did you mean --seeds?"),  # an abbreviation is not taken for --seeds
                       (["run", "--lis"], "ecorl run: error: unrecognized arguments: --lis; did you mean --list?"),
                       (["train", "salad", "--zzz"], "ecorl train: error: unrecognized arguments: --zzz (see ecorl "
                        "train --help)"),
                       (["trian"], "did you mean train?"), (["merge"], "did you mean merge-seeds?"),
                       (["run", "headline", "--budget", "papr"], "did you mean paper?")):
        with pytest.raises(SystemExit) as stop:
            main(argv)
        err = capsys.readouterr().err.strip()
        assert stop.value.code == 2 and len(err.splitlines()) == 1 and said in err, err
    with pytest.raises(SystemExit):
        main(["run", "headlin", "--dry-run"])
    assert "unknown experiment 'headlin'; did you mean headline?" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["run", "headline", "--condition", "statc-reset-free", "--dry-run"])
    assert "unknown headline/salad condition 'statc-reset-free'; did you mean static-reset-free? (choose one of " \
        "static-episodic, " in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["run", "headline", "--condition", "statc-reset-free", "zzz", "--dry-run"])
    assert "unknown headline/salad conditions 'statc-reset-free', 'zzz'; did you mean static-reset-free?" in \
        capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["run", "shaping", "--task", "hunitng", "--dry-run"])
    assert "unknown shaping task 'hunitng'; did you mean hunting? (choose one of " in \
        capsys.readouterr().err


def test_default_run_dir_names_the_condition():
    cfg = _parse("--dynamism", "0.1", "--reset-free", "--seeds", "3", "--shaping", "linear:1:0:1000")
    assert str(default_run_dir(cfg)) == "runs/salad-p0.1-slinear_1_0_1000-resetfree-sparse-seeds0-2"


def test_cli_trains_a_tiny_run(tmp_path, capsys):
    code = main(["train", "hunting", "--steps", "700", "--updates-per-epoch", "10", "--eval-every", "500",
                 "--eval-rollouts", "2", "--eval-horizon", "10", "--buffer-size", "1000", "--no-progress",
                 "--out", str(tmp_path / "run")])
    assert code == 0
    assert "mean success over 1 seed(s)" in capsys.readouterr().out  # the result on stdout, kept by `> log.txt`
    assert (tmp_path / "run" / "metrics.csv").exists()


def test_train_uses_the_tasks_tuned_settings_unless_overridden():
    from train.cli.train import train_config

    def cfg_of(*argv):
        return train_config(build_parser().parse_args(["train", *argv]))[0]

    assert cfg_of("salad").dqn.lr == 3e-4  # the experiments' rate (TUNED), not TrainConfig's 1e-4
    assert cfg_of("salad", "--lr", "1e-4").dqn.lr == 1e-4
    assert cfg_of("hunting").dqn.lr == TrainConfig().dqn.lr


def test_train_prints_the_tuned_settings(tmp_path, capsys):
    code = main(["train", "salad", "--steps", "500", "--updates-per-epoch", "5", "--eval-every", "500",
                 "--eval-rollouts", "1", "--eval-horizon", "5", "--buffer-size", "1000", "--no-progress",
                 "--out", str(tmp_path / "run")])
    assert code == 0
    assert "tuned settings, as the experiments do: --lr 0.0003" in capsys.readouterr().err


def test_run_help_lists_every_experiment_apart_from_its_description():
    from train.experiments.catalog import EXPERIMENTS
    help_text = build_parser().parse_args(["run"]).command_parser.format_help()
    for name in EXPERIMENTS:
        assert f"  {name}  " in help_text, f"{name} runs into its description in `ecorl run --help`"


def test_a_config_built_in_python_names_the_nearest_choice_for_a_misspelt_one():
    from train.config import EnvConfig
    from train.experiments.catalog import get_experiment

    with pytest.raises(ValueError, match=r"^unknown reward mode 'waypont'; did you mean waypoint\? \(choose one of "
                                         r"sparse, waypoint, .*\)$"):
        TrainConfig(env=EnvConfig(reward="waypont"))
    with pytest.raises(ValueError, match=r"^unknown budget 'huge'; choose one of smoke, "):
        get_experiment("dynamism").budget("huge")


def test_a_value_of_the_wrong_type_gets_the_choices_without_a_hint():
    from train.config import DQNConfig, EnvConfig

    with pytest.raises(ValueError, match=r"^unknown reward mode 3; choose one of sparse, waypoint, "):
        TrainConfig(env=EnvConfig(reward=3))
    with pytest.raises(ValueError, match=r"^init must be one of rlkit, torch, got 7$"):
        TrainConfig(dqn=DQNConfig(init=7))
    with pytest.raises(ValueError, match=r"^init must be one of rlkit, torch, got 'rlkt'; did you mean rlkit\?$"):
        TrainConfig(dqn=DQNConfig(init="rlkt"))


def test_a_reader_that_leaves_early_stops_the_command_quietly():
    """``ecorl run --list | head -1`` printed 'error: [Errno 32] Broken pipe; check the path, its permissions ...'."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader has gone before the first line
    done = subprocess.run([sys.executable, "-m", "train.cli", "run", "--list"], stdout=write_end,
                          stderr=subprocess.PIPE, text=True, timeout=120)
    os.close(write_end)
    assert (done.returncode, done.stderr) == (141, "")


def test_an_eval_every_off_the_epochs_names_a_value_that_fits(capsys):
    assert main(["train", "salad", "--steps", "1200", "--eval-every", "1400"]) == 2
    assert capsys.readouterr().err.strip().endswith("give --eval-every 1500 or change --epoch-steps")
