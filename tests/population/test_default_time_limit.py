"""The bare 6v6 headline is bounded: ``population.default_time_limit`` gives a population run on 6v6 an
hour where it names no ``time_limit`` (its five oracles take about 90 minutes on 2 cores), and the
run's summary says when that bound ended it."""

from volleybots.cli.train import _time_bound
from volleybots.config import load
from volleybots.runs import RunDir


def test_a_bare_6v6_population_stops_at_an_hour_and_nothing_else_changes():
    assert load(["task=6v6", "algo=psro_nash"]).time_limit == 3600.0
    assert load(["task=6v6", "algo=fsp"]).time_limit == 3600.0  # every population method composes psro_nash's keys
    assert load(["task=6v6", "algo=psro_nash", "time_limit=90"]).time_limit == 90.0  # a given limit wins
    assert load(["task=6v6", "algo=psro_nash", "population.default_time_limit={6v6: 0}"]).time_limit == 0.0  # lifted
    assert load(["task=3v3", "algo=psro_nash"]).time_limit == 0.0  # other tasks keep no bound
    assert load(["task=6v6", "algo=mappo"]).time_limit == 0.0  # and so does a run of one learner


def test_the_summary_says_which_bound_ended_the_run(tmp_path):
    run = RunDir(tmp_path / "bare")
    run.path.mkdir()
    run.write_config(load(["task=6v6", "algo=psro_nash"]))
    line = _time_bound({"iterations": 2}, run.path)
    assert line == (f"  time_limit 3600 s (population.default_time_limit) ended the run after 2 of 5 iteration(s); "
                    f"resume={run.path} time_limit=SECONDS (above 3600) continues it")
    done = _time_bound({"iterations": 5}, run.path)
    assert done == "  time_limit 3600 s (population.default_time_limit): not reached, all 5 iteration(s) done"
    given = RunDir(tmp_path / "given")
    given.path.mkdir()
    given.write_config(load(["task=6v6", "algo=psro_nash", "time_limit=60"]))
    assert _time_bound({"iterations": 1}, given.path).startswith("  time_limit 60 s (time_limit) ended the run after 1 of 5")
    none = RunDir(tmp_path / "none")
    none.path.mkdir()
    none.write_config(load(["task=3v3", "algo=psro_nash"]))
    assert _time_bound({"iterations": 1}, none.path) == ""
