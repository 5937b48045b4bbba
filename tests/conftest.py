"""Hooks and fixtures of the suite: the scheduling order, one torch thread per test, and a session-wide
cache of tiny trained runs, so that tests which only read a run (evaluate it, start from it, replay it) do
not each train their own. Plain helpers are in helpers.py.

Markers (registered in pyproject.toml) only select: `python -m pytest -q` runs every test, and
`python -m pytest -q -m "not slow"` is the quick local loop."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import torch
from helpers import QUIET, TINY_1V1

# Seconds each of the heaviest test modules took on the 2-core machine (xdist, 2 workers, 2026-11-28, main 904c7e0).
# Only the order of scheduling reads them; no test is selected or skipped by them.
MODULE_SECONDS = {
    "test_offpolicy_learning": 142, "test_population": 102, "test_reliability": 88, "test_cli": 83, "test_scripted_set_and_spike": 70,
    "test_launchers": 70, "test_marl": 64, "test_scripted_set_and_spike_ctbr": 63, "test_crossplay": 61, "test_ppo": 59, "test_zoo": 58,
    "test_exploitability": 55, "test_scripted_bump_and_pass": 47, "test_bc": 44, "test_docs": 36, "test_registries": 32,
    "test_payoff_pool": 29, "test_scripted": 28, "test_sac_init": 25, "test_lookahead": 24, "test_wandb": 23, "test_hierarchical": 23,
    "test_config": 23, "test_compiled_step": 22, "test_env": 21,
}


# Tests that are not slow by their nature but took the quick tier over 4 minutes: the longest, by total seconds
# (all their parameters, setup included) in a `-m "not slow" --durations=0` run on the 2-core machine at load
# 5-7 (2026-11-29), marked slow until the rest summed under 200 s. Only the tier they run in changes.
QUICK_TIER_SLOW = {
    "test_scripted_bump_and_pass::test_bump_and_pass_pair_keeps_passing_for_the_whole_episode",  # 32 s once the module cost moved here
    "test_bc::test_a_resumed_bc_run_repeats_the_uninterrupted_one", "test_cli::test_bad_input_from_a_real_process_has_no_traceback",
    "test_cli::test_eval_compare_pairs_the_episodes_and_tells_the_better_player",
    "test_cli::test_eval_of_a_run_prints_a_table_and_json", "test_cli::test_eval_of_the_scripted_pair_on_a_multi_drone_task",
    "test_cli::test_list_names_every_task_algorithm_backend_and_action_space", "test_cli::test_multirun_sweeps_seeds",
    "test_cli::test_train_writes_a_complete_run_directory", "test_compiled_step::test_bench_training_rows",
    "test_compiled_step::test_compiled_step_compiles_once_and_matches_eager",
    "test_config::test_configs_are_found_from_any_working_directory", "test_config::test_every_registered_task_has_a_config",
    "test_coop::test_ten_thousand_random_steps_stay_finite", "test_crossplay::test_bad_input_exits_2_with_one_line_and_writes_nothing",
    "test_crossplay::test_crossplay_cli_writes_results_with_every_file_hash",
    "test_crossplay::test_elo_cli_played_and_from_a_results_file",
    "test_crossplay::test_reuse_copies_the_pairs_an_earlier_crossplay_played_and_the_table_is_the_fresh_one",
    "test_crossplay::test_scripted_beats_random_on_both_sides_equally_often",
    "test_damaged_runs::test_a_damaged_population_is_refused_and_its_resume_writes_nothing",
    "test_damaged_runs::test_a_damaged_run_is_refused_by_every_verb", "test_drills::test_scripted_drill_reaches_its_success_criterion",
    "test_env::test_random_rollouts_finite_every_task", "test_env::test_ten_thousand_random_steps_stay_finite",
    "test_eval_inputs::test_a_run_dir_named_with_comma_and_equals_is_usable",
    "test_eval_inputs::test_two_writers_of_one_out_never_overwrite_each_other",
    "test_exploitability::test_bad_input_is_one_line_and_writes_nothing",
    "test_exploitability::test_responses_on_two_seeds_fixed_ones_and_the_target_itself_give_a_lower_bound_never_below_zero",
    "test_exploitability::test_split_chooses_a_serve_and_a_receive_response_and_averages_their_figures",
    "test_exploitability::test_the_cli_names_the_trained_runs_and_json_keeps_progress_on_stderr",
    "test_game_content::test_crossplay_carries_content_through_json_table_and_ratings",
    "test_hierarchical::test_a_trained_drill_drives_its_drone_on_the_drill_observation",
    "test_hierarchical::test_hierarchical_team_never_touches_twice_in_a_row_with_one_drone",
    "test_init::test_best_pt_holds_the_policy_of_the_best_evaluation", "test_init::test_init_of_mappo_from_ppo_and_off_policy_targets",
    "test_lookahead::test_a_kept_choice_searches_every_k_steps_and_starts_as_the_memoryless_player",
    "test_marl::test_a_tiny_run_on_bump_and_pass_checkpoints_and_resumes_bit_for_bit",
    "test_marl::test_every_algorithm_trains_every_task_kind_it_claims_and_refuses_the_others",
    "test_match::test_ten_thousand_random_steps_stay_finite_and_stats_add_up",
    "test_match_scripted::test_scripted_1v1_team_never_loses_to_random_on_either_side",
    "test_offpolicy::test_losses_decrease_on_a_fixed_batch",
    "test_offpolicy_runs::test_a_tiny_run_writes_metrics_and_loadable_checkpoints",
    "test_offpolicy_runs::test_cli_trains_evaluates_and_replays_sac_and_picks_discrete_for_dqn",
    "test_offpolicy_runs::test_resume_with_the_buffer_repeats_the_uninterrupted_run",
    "test_offpolicy_runs::test_resume_without_the_buffer_warms_up_again_and_goes_on",
    "test_physics::test_skipping_the_contacts_where_no_drone_can_meet_the_ball_changes_no_number",
    "test_ppo::test_target_kl_stops_an_update_once_the_actor_has_moved",
    "test_progress::test_a_population_run_reports_progress_final_eval_curves_and_its_wall_time_split",
    "test_progress::test_a_time_limited_run_prints_lines_and_stops_before_a_batch_would_overshoot",
    "test_ranking::test_elo_cli_from_a_file_is_finite_and_the_same_for_a_seed",
    "test_ranking::test_elo_of_played_games_does_not_depend_on_the_order_of_the_side_batches",
    "test_ranking::test_the_nash_weight_comes_with_how_often_each_member_carries_it_on_resampled_payoffs",
    "test_registries::test_a_run_dir_evaluates_after_the_files_it_was_trained_against_have_moved",
    "test_registries::test_every_algorithm_composes_validates_and_builds_on_a_task_it_accepts",
    "test_registries::test_every_built_in_player_acts_in_the_space_of_the_tasks_it_fits",
    "test_registries::test_every_population_preset_accepts_its_own_default_start_and_refuses_the_others_by_name",
    "test_reliability::test_a_benchmark_rerun_never_removes_a_run_another_process_is_training",
    "test_reliability::test_a_run_killed_before_its_first_checkpoint_can_be_retried",
    "test_reliability::test_claim_gives_a_fresh_suffix_when_the_default_dir_is_taken_or_in_use",
    "test_reliability::test_every_numeric_key_rejects_values_outside_its_range_by_name",
    "test_reliability::test_out_of_range_on_the_command_line_is_one_line_and_writes_nothing",
    "test_reliability::test_resume_onto_a_mismatched_checkpoint_names_both_and_writes_nothing",
    "test_reliability::test_two_resumes_at_once_train_once_and_lose_nothing",
    "test_reliability::test_two_starts_at_once_make_two_intact_runs",
    "test_reliability::test_two_starts_into_one_dir_end_with_one_run_and_one_refusal",
    "test_replay::test_replay_of_the_scripted_policy_or_a_clear_error",
    "test_rows::test_a_payoff_row_plays_every_opponent_its_games_and_a_chunk_is_its_own_seed",
    "test_sac_init::test_a_guided_sac_run_passes_its_guide_on",
    "test_sac_init::test_resume_keeps_the_guide_and_repeats_the_uninterrupted_run",
    "test_sac_init::test_the_guide_is_exactly_the_saved_actor_and_drives_the_warm_up",
    "test_sac_init::test_with_a_guide_the_warm_up_lasts_guide_warmup_transitions",
    "test_scripted::test_heading_control_turns_the_drone", "test_scripted::test_position_controller_reaches_and_holds_a_target",
    "test_scripted::test_scripted_solo_bump_keeps_bumping",
    "test_scripted_bump_and_pass::test_bump_and_pass_pair_opens_with_a_counted_bump_and_stays_airborne",
    "test_scripted_match_rally::test_scripted_3v3_team_rallies_against_itself",
    "test_zoo::test_every_zoo_entry_loads_weights_only_fits_its_task_and_beats_random",
}


def pytest_collection_modifyitems(items):
    """A learning test trains to a floor: it is slow by nature, so ``-m "not slow"`` leaves it out too, and
    so does every test of ``QUICK_TIER_SLOW``.

    The longest modules are collected first (``MODULE_SECONDS``, then the ones holding slow tests):
    xdist's ``loadscope`` hands modules out in collection order, so the long ones start at once and
    the short ones fill in behind them (longest-first scheduling), instead of one worker finishing a
    long module alone at the end."""
    for item in items:
        if item.get_closest_marker("learning") and not item.get_closest_marker("slow"):
            item.add_marker(pytest.mark.slow)
        if f"{item.module.__name__}::{item.originalname}" in QUICK_TIER_SLOW:
            item.add_marker(pytest.mark.slow)
    slow = {item.module.__name__ for item in items if item.get_closest_marker("slow")}

    def cost(item) -> tuple:
        name = item.module.__name__
        return -MODULE_SECONDS.get(name, 0), name not in slow

    items.sort(key=cost)  # stable: a module's own order is kept


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """One intra-op thread for every test (on a shared machine it is several times faster than two under
    contention), and the count put back afterwards, so one test's setting (``threads=N``) never leaks into the next."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """``tiny_run(*overrides)``: the run directory of ``train(load(overrides + QUIET))``, trained once per session
    for each distinct list of overrides. Tests that only read a run share it; a test that writes into a run dir
    (resume, extra checkpoints) trains its own instead."""
    from volleybots.config import load
    from volleybots.train import train

    runs: dict[tuple[str, ...], Path] = {}

    def get(*overrides: str) -> Path:
        key = tuple(overrides)
        if key not in runs:
            torch.set_num_threads(1)
            path = tmp_path_factory.mktemp("tiny_run") / "run"
            given = {o.split("=", 1)[0] for o in overrides}
            train(load([*overrides, *(q for q in QUIET if q.split("=", 1)[0] not in given)]), path)
            runs[key] = path
        return runs[key]

    return get


# ---- session-scoped tiny runs for the tests of damaged runs and of the evaluation verbs' input checks:
# each is trained once and copied by a test that damages it


def _train(path: Path, *args) -> Path:
    from typer.testing import CliRunner

    from volleybots.cli import app

    res = CliRunner().invoke(app, ["train", *TINY_1V1, *args, f"hydra.run.dir={path}"])
    assert res.exit_code == 0, res.output
    return path


@pytest.fixture(scope="session")
def tiny_1v1_run(tmp_path_factory) -> Path:
    """A finished 1v1 MAPPO run of 128 frames (final.pt, summary.json listing it)."""
    return _train(tmp_path_factory.mktemp("shared") / "run", "algo=mappo", "total_frames=128")


@pytest.fixture(scope="session")
def tiny_population(tmp_path_factory) -> Path:
    """A finished PSRO run of one iteration over a random seed member: members random and br1."""
    return _train(tmp_path_factory.mktemp("shared") / "pop", "algo=psro_uniform", "algo.start=scratch", "algo.iterations=1",
                  "total_frames=256", "algo.min_updates=1", "algo.max_updates=1", "algo.payoff_games=2")


@pytest.fixture
def copy_run(tmp_path):
    """``copy_run(src, name)``: a copy of a shared run in this test's folder, free to damage."""

    def copy(src: Path, name: str = "copy") -> Path:
        return Path(shutil.copytree(src, tmp_path / name, ignore=shutil.ignore_patterns(".lock")))

    return copy


