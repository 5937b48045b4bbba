"""``key=value`` words are read one way everywhere (volleybots.overrides)."""

from volleybots.overrides import names_key, override_key, override_value, split_arg


def test_a_word_splits_at_its_first_equals_sign_and_a_bare_word_has_no_value():
    assert split_arg("init=runs/a=b") == ("init", "runs/a=b")
    assert split_arg("scripted") == ("scripted", None)
    assert split_arg("task=") == ("task", "")


def test_hydra_prefixes_name_the_same_key():
    assert [override_key(o) for o in ("+total_frames=1", "++total_frames=2", "~total_frames", "total_frames=3")] == ["total_frames"] * 4
    assert names_key(["task=3v3", "+algo=sp"], "algo") and not names_key(["algo.iterations=3"], "algo")
    assert names_key(["~env.action_space"], "env.action_space", "total_frames")


def test_the_last_value_of_a_key_is_the_one_hydra_uses():
    assert override_value(["algo.learner=mat", "x=1", "+algo.learner=happo"], "algo.learner") == "happo"
    assert override_value(["~algo.learner"], "algo.learner", "mappo") == "mappo"
