"""`volleybots train -m` through Hydra's launcher plugins (the `cluster` extra): a 2-job sweep on joblib,
on submitit's local executor and on a local Ray instance each writes two complete run directories,
and a seed gives the same run whichever launcher ran it. A launcher whose plugin is missing is one
line naming the extra, exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
from typer.testing import CliRunner

from volleybots.cli import app

pytestmark = [pytest.mark.slow, pytest.mark.subprocess]

SWEEP = [
    "seed=0,1",
    "task=hover",
    "task.episode_len=20",
    "env.num_envs=4",
    "algo.steps_per_batch=16",
    # one small gradient step per batch: the jobs are here for what the launchers do with them
    "algo.minibatches=1",
    "algo.epochs=1",
    "algo.hidden=[16]",
    "total_frames=128",
    "threads=1",
    "progress=false",
    "checkpoint.every=64",
    "evaluation.every=64",
    "evaluation.episodes=2",
    "evaluation.record=false",
]
LAUNCHERS = {
    "joblib": ["hydra/launcher=joblib", "hydra.launcher.n_jobs=2"],
    "submitit_local": ["hydra/launcher=submitit_local"],
    # a local Ray instance of 2 CPUs, without its web dashboard
    "ray": ["hydra/launcher=ray", "+hydra.launcher.ray.init.num_cpus=2", "+hydra.launcher.ray.init.include_dashboard=false"],
}


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    """The three sweeps, each started in this process as ``volleybots train -m`` (a child process would spend
    about 10 s of CPU importing torch before its launcher even starts); their jobs run in the launchers' own
    processes (joblib's loky workers, submitit's job processes, Ray's workers)."""
    root = tmp_path_factory.mktemp("sweeps")
    out = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(root)
        # the jobs' processes inherit these: one OpenMP thread each, and Ray's local instance without a token
        mp.setenv("OMP_NUM_THREADS", "1")
        mp.setenv("RAY_AUTH_MODE", "disabled")
        for name, args in LAUNCHERS.items():
            out[name] = root / name
            try:
                res = CliRunner().invoke(app, ["train", "-m", *args, *SWEEP, f"hydra.sweep.dir={out[name]}"])
            finally:
                # both launchers leave their workers running in this process for a next sweep
                if name == "joblib":
                    from joblib.externals.loky import get_reusable_executor

                    get_reusable_executor().shutdown(wait=True)
                if name == "ray":
                    import ray

                    ray.shutdown()
            assert res.exit_code == 0, name + ": " + res.output[-5000:]
    return out


def finals(sweep_dir: Path) -> dict[int, dict]:
    """seed -> the final evaluation's stats of each run of a sweep."""
    out = {}
    for summary in sorted(sweep_dir.glob("*/summary.json")):
        s = json.loads(summary.read_text())
        out[s["seed"]] = s["final_eval"]["stats"]
    return out


@pytest.mark.parametrize("launcher", list(LAUNCHERS))
def test_a_two_job_sweep_writes_two_complete_runs(sweeps, launcher):
    runs = sorted(p for p in sweeps[launcher].iterdir() if p.is_dir() and not p.name.startswith("."))
    assert [p.name for p in runs] == ["0", "1"]
    # the sweep's report is written beside its jobs when it ends, over both seeds
    report = json.loads((sweeps[launcher] / "report.json").read_text())
    assert [c["seeds"] for c in report["cells"]] == [[0, 1]]
    for seed, run in enumerate(runs):
        summary = json.loads((run / "summary.json").read_text())
        assert summary["seed"] == seed and summary["frames"] == 128 and summary["final_eval"]["episodes"] == 2
        assert (run / "config.yaml").is_file() and (run / ".hydra" / "overrides.yaml").is_file()
        assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["best.pt", "ckpt_000000000064.pt", "final.pt"]
        assert torch.load(run / "checkpoints" / "final.pt", weights_only=True)["frames"] == 128
        evals = [line for line in (run / "metrics.csv").read_text().splitlines() if line.startswith("eval,")]
        assert len(evals) == 2  # at 64 frames and the final one


def test_a_seed_gives_the_same_run_on_every_launcher(sweeps):
    results = {name: finals(path) for name, path in sweeps.items()}
    assert results["joblib"] == results["submitit_local"] == results["ray"]
    assert results["joblib"][0] != results["joblib"][1]  # and the two seeds differ


def test_report_of_a_sweep_aggregates_its_seeds(sweeps):
    res = CliRunner().invoke(app, ["report", str(sweeps["joblib"]), "--json"])
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout)
    (cell,) = report["cells"]
    values = [f["distance"]["mean"] for _, f in sorted(finals(sweeps["joblib"]).items())]
    assert cell["task"] == "hover" and cell["algo"] == "ppo" and cell["seeds"] == [0, 1]
    assert cell["values"] == pytest.approx(values) and cell["mean"] == pytest.approx(sum(values) / 2)
    assert cell["mean_ci"] == pytest.approx(sorted(values))  # two seeds: the interval spans both
    assert all(r["status"] == "complete" for r in report["runs"]) and len(report["runs"]) == 2


def test_the_slurm_launcher_composes_with_its_options(tmp_path):
    res = CliRunner().invoke(
        app,
        [
            "train",
            "--cfg",
            "hydra",
            "hydra/launcher=submitit_slurm",
            "hydra.launcher.partition=gpu",
            "hydra.launcher.gpus_per_node=1",
            "hydra.launcher.timeout_min=600",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "_target_: hydra_plugins.hydra_submitit_launcher.submitit_launcher.SlurmLauncher" in res.stdout
    assert "partition: gpu" in res.stdout and "gpus_per_node: 1" in res.stdout and "timeout_min: 600" in res.stdout


@pytest.mark.parametrize(
    "launcher,package", [("joblib", "hydra-joblib-launcher"), ("submitit_slurm", "hydra-submitit-launcher"), ("ray", "hydra-ray-launcher")]
)
def test_a_launcher_that_is_not_installed_names_the_extra(monkeypatch, tmp_path, launcher, package):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name.startswith("hydra_plugins.") else real(name, *a))
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["train", "-m", f"hydra/launcher={launcher}", "seed=0,1"])
    assert res.exit_code == 2, res.output
    err = res.stderr.strip()
    assert err == f"error: hydra/launcher={launcher} needs the {package} plugin: pip install 'volleybots[cluster]'"
    assert not any(tmp_path.iterdir())  # nothing ran, nothing was written


class _NoHydraPlugins:
    """A finder that makes ``hydra_plugins`` (and every plugin under it) unimportable, as on a plain
    ``pip install -e .``: hydra-core itself ships no ``hydra_plugins`` package."""

    def find_spec(self, name, path=None, target=None):
        if name == "hydra_plugins" or name.startswith("hydra_plugins."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None


def test_a_plain_install_without_any_plugin_names_the_extra(monkeypatch, tmp_path):
    import sys

    for mod in [m for m in sys.modules if m == "hydra_plugins" or m.startswith("hydra_plugins.")]:
        monkeypatch.delitem(sys.modules, mod)
    monkeypatch.setattr(sys, "meta_path", [_NoHydraPlugins(), *sys.meta_path])
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["train", "-m", "hydra/launcher=joblib", "seed=0,1"])
    assert res.exit_code == 2, res.output
    assert res.stderr.strip() == "error: hydra/launcher=joblib needs the hydra-joblib-launcher plugin: pip install 'volleybots[cluster]'"
    assert not any(tmp_path.iterdir())
