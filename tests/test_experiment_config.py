"""The run's configuration tree (``imitation.config``): one typed, frozen tree with the quick
preset, written as TOML or JSON and read back, with every unknown key and wrong type refused by
name; the command line maps its options onto it."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import dataclasses
import json

import pytest

from associator.hierarchy import HierarchicalAssociator
from associator.network import Associator
from imitation import config as run_config
from imitation.cli import build_parser, reproduce_config
from imitation.config import RunConfig


def test_the_tree_is_frozen_and_typed():
    config = RunConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.seed = 3  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.learning.train_steps = 3  # type: ignore[misc]
    assert isinstance(config.network.hidden_shape, tuple)


def test_defaults_are_the_estimators_own():
    """The [network] and [hierarchical] defaults come from the classes, not copies of them."""
    config = RunConfig()
    network = Associator(**config.network_params()).get_params()
    assert network == {**Associator().get_params(), "n_steps_total": config.learning.train_steps}
    model = HierarchicalAssociator(
        lower=Associator(**config.network_params()), **config.hierarchical.hyper_parameters()
    )
    defaults = HierarchicalAssociator().get_params()
    for name, value in config.hierarchical.hyper_parameters().items():
        assert model.get_params()[name] == defaults[name] == value, name


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_written_config_reads_back_equal(tmp_path, suffix):
    config = RunConfig.quick().replace(
        {
            "seed": 11,
            "network.hidden_shape": (8, 24),
            "teacher.max_seconds": {"go": 100.0, "pick": 50, "lift": 20},
        }
    )
    path = tmp_path / f"config{suffix}"
    run_config.dump(config, path)
    assert run_config.load(path) == config
    if suffix == ".toml":
        assert path.read_text().startswith("# A run of `peoplebot reproduce`")
    else:
        assert json.loads(path.read_text())["network"]["hidden_shape"] == [8, 24]


def test_quick_is_a_preset_of_the_same_tree():
    quick, full = RunConfig.quick(), RunConfig()
    assert type(quick) is type(full)
    assert quick.learning.train_steps < full.learning.train_steps
    assert quick.performance.trials < full.performance.trials
    assert quick.network == full.network and quick.teacher == full.teacher


def test_a_partial_file_keeps_the_other_values(tmp_path):
    path = tmp_path / "partial.toml"
    path.write_text("seed = 4\n[performance]\ntrials = 7\n")
    config = run_config.load(path, base=RunConfig.quick())
    assert (config.seed, config.performance.trials) == (4, 7)
    assert config.learning == RunConfig.quick().learning


@pytest.mark.parametrize(
    "text, message",
    [
        ("sed = 4\n", "unknown config key 'sed'"),
        ("[learning]\ntrain_step = 4\n", "unknown config key 'learning.train_step'"),
        ("[lerning]\ntrain_steps = 4\n", "unknown config key 'lerning'"),
        ("seed = 'four'\n", "config key 'seed' must be an integer"),
        ("[learning]\ntrain_steps = 2.5\n", "'learning.train_steps' must be an integer"),
        ("[network]\neta = 'fast'\n", "'network.eta' must be a number"),
        ("[videos]\nenabled = 1\n", "'videos.enabled' must be true or false"),
        ("[network]\nhidden_shape = [8, 'x']\n", r"'network.hidden_shape\[1\]' must be an integer"),
        ("learning = 3\n", "'learning' must be a table"),
        (
            "[teacher.max_seconds]\ngo = 1.0\n",
            "'teacher.max_seconds' must be a table with the keys",
        ),
        ("[learning]\ntrain_steps = 0\n", r"learning\.train_steps must be a positive integer"),
        (
            "[vision]\nmode = 'sonar'\n",
            "unknown vision.mode 'sonar'; allowed: truth, overhead, head",
        ),
        ("[network]\neta = -1.0\n", "network: eta must be a positive"),
        ("[hierarchical]\npose_weight = 0.0\n", "hierarchical: pose_weight must be a positive"),
        ("[drive]\nlinear_mps = 2.0\n", r"linear_mps must be in \(0, 0.75\]"),
        ("[teacher]\nsettle_pattern = ['jump']\n", "teacher.settle_pattern holds unknown"),
        ("seed = \n", "is not valid toml"),
    ],
)
def test_bad_files_are_refused_naming_the_key(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        run_config.load(path)


def test_a_missing_file_is_refused_with_its_name(tmp_path):
    with pytest.raises(ValueError, match="cannot read config .*missing.toml"):
        run_config.load(tmp_path / "missing.toml")


def test_cli_options_override_the_file_which_overrides_the_preset(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text("seed = 4\n[performance]\ntrials = 7\ntrial_seconds = 30.0\n")
    args = build_parser().parse_args(
        ["reproduce", "--quick", "--config", str(path), "--trials", "2", "--no-videos"]
    )
    config = reproduce_config(args)
    assert config.seed == 4  # the file
    assert config.performance.trials == 2  # the option
    assert config.performance.trial_seconds == 30.0  # the file
    assert config.learning == RunConfig.quick().learning  # the preset
    assert not config.videos.enabled
