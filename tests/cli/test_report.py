"""`volleybots report` on run directories with known metrics: the means, IQMs and bootstrap intervals it
prints, how it groups runs into task x algorithm x variant, and the runs it lists as running or failed."""

from __future__ import annotations

import itertools
import json
import os
import re
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.stats import trim_mean
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.report import build_report, find_runs

runner = CliRunner()
HOUR_AGO = time.time() - 3600  # when the "killed" runs were last written


def make_run(root: Path, name: str, *, task="hover", algo="ppo", seed=0, final=1.0, curve=(), summary=True, age=None, **extra) -> Path:
    """A run directory as `volleybots train` writes it, with a known final metric and eval curve."""
    d = root / name
    d.mkdir(parents=True)
    summary_frames = extra.pop("summary_frames", None)
    metric = "distance" if task == "hover" else "hits"
    cfg = {"task": {"name": task}, "algo": {"name": algo, "lr": extra.pop("lr", 0.001)}, "env": {"num_envs": 8, "device": "cpu"},
           "seed": seed, "total_frames": 2_000_000, "threads": seed + 1, "checkpoint": {"every": 10 + seed}, **extra}
    (d / "config.yaml").write_text(yaml.safe_dump(cfg))
    (d / ".hydra").mkdir()
    (d / ".hydra" / "config.yaml").write_text(yaml.safe_dump(cfg))  # Hydra's copy: not a second run
    points = [*curve, (2_000_000, final)]
    rows = ["phase,frames,distance,eval_distance,eval_hits"] + [f"eval,{f},,{v},{v}" for f, v in points]
    (d / "metrics.csv").write_text("\n".join(rows) + "\n")
    if summary:
        stats = {metric: {"mean": final, "std": 0.1}, "return": {"mean": 5.0, "std": 1.0}}
        frames = summary_frames or cfg["total_frames"]
        (d / "summary.json").write_text(json.dumps({"metric": metric, "seed": seed, "frames": frames, "final_eval": {"stats": stats}}))
    if age is not None:
        for p in [*d.rglob("*"), d]:
            os.utime(p, (age, age))
    return d


def exact_bootstrap(x, statistic) -> np.ndarray:
    """The exact bootstrap distribution of ``statistic``: its value on every ordered resample."""
    x = np.asarray(x, dtype=float)
    return np.array([statistic(x[list(idx)]) for idx in itertools.product(range(len(x)), repeat=len(x))])


def is_quantile(dist: np.ndarray, q: float, value: float, tol: float = 0.01) -> bool:
    """Whether ``value`` is a ``q``-quantile of the (discrete) distribution ``dist``, up to the Monte
    Carlo error of a 10,000-resample bootstrap."""
    return np.mean(dist < value - 1e-9) <= q + tol and np.mean(dist <= value + 1e-9) >= q - tol


@pytest.fixture
def sweep(tmp_path):
    root = tmp_path / "multirun"
    finals = [1.0, 2.0, 3.0, 4.0, 10.0]
    for s, v in enumerate(finals):
        make_run(root, f"ppo/{s}", seed=s, final=v, curve=[(1_000_000, v + 1.0)])
    for s, v in enumerate([7.0, 9.0]):
        make_run(root, f"sac/{s}", algo="sac", seed=s, final=v)
    make_run(root, "ppo_lr/0", seed=0, final=0.5, lr=0.01)
    make_run(root, "bump/0", task="solo_bump", seed=0, final=12.0)
    make_run(root, "diverged", seed=9, final=float("nan"))
    make_run(root, "killed", seed=7, summary=False, age=HOUR_AGO)
    make_run(root, "live", seed=8, summary=False)
    make_run(root, "resumed_killed", seed=5, summary_frames=1_000_000, age=HOUR_AGO)
    population = make_run(root, "psro", task="1v1", algo="psro_nash", summary=False)
    (population / "summary.json").write_text(
        json.dumps({"metric": "win", "frames": 2_000_000, "population": {"members": ["random", "br1"]}})
    )
    job = root / "never_started" / ".hydra"
    job.mkdir(parents=True)
    (job / "overrides.yaml").write_text(yaml.safe_dump(["seed=6", "algo.lr=-1"]))
    for p in [job / "overrides.yaml", job, job.parent]:
        os.utime(p, (HOUR_AGO, HOUR_AGO))
    return root, finals


def _cell(report, algo, task="hover", variant=None):
    cells = [c for c in report["cells"] if c["algo"] == algo and c["task"] == task and (variant is None or variant in c["variant"])]
    assert len(cells) == 1, [(c["algo"], c["variant"]) for c in report["cells"]]
    return cells[0]


def test_means_iqm_and_bootstrap_intervals_across_seeds(sweep):
    root, finals = sweep
    rep = build_report([root])
    ppo = _cell(rep, "ppo", variant="algo.lr=0.001")
    assert ppo["seeds"] == [0, 1, 2, 3, 4] and ppo["values"] == finals
    assert ppo["mean"] == pytest.approx(4.0) and ppo["iqm"] == pytest.approx(3.0)  # IQM drops the 1.0 and the 10.0
    assert ppo["iqm"] == pytest.approx(trim_mean(finals, 0.25))
    for key, stat in (("mean_ci", np.mean), ("iqm_ci", lambda x: trim_mean(x, 0.25))):
        dist = exact_bootstrap(finals, stat)
        assert is_quantile(dist, 0.025, ppo[key][0]) and is_quantile(dist, 0.975, ppo[key][1]), (key, ppo[key])
        assert not is_quantile(dist, 0.025, ppo[key][0] + 0.5) and not is_quantile(dist, 0.975, ppo[key][1] - 0.5)
    # two seeds: the resampled means are 7, 8 or 9, so the 95 % interval is [7, 9] exactly
    sac = _cell(rep, "sac")
    assert sac["mean"] == 8.0 and sac["mean_ci"] == [7.0, 9.0] and sac["variant"] == ""
    # one seed: a value, no interval
    lone = _cell(rep, "ppo", variant="algo.lr=0.01")
    assert lone["mean"] == 0.5 and lone["mean_ci"] is None and lone["iqm_ci"] is None
    assert _cell(rep, "ppo", task="solo_bump")["metric"] == "hits"
    assert build_report([root])["cells"] == rep["cells"]  # the intervals are seeded: the same every time


def test_learning_curve_band_is_the_mean_over_seeds(sweep):
    root, finals = sweep
    cv = _cell(build_report([root]), "ppo", variant="algo.lr=0.001")["curve"]
    assert cv["frames"] == [1_000_000, 2_000_000]
    assert cv["mean"] == pytest.approx([np.mean(finals) + 1.0, np.mean(finals)])
    assert all(lo < m < hi for lo, m, hi in zip(cv["low"], cv["mean"], cv["high"], strict=True))


def test_runs_without_a_result_are_listed_with_their_state(sweep):
    root, _ = sweep
    runs = {str(r.path.relative_to(root)): r for r in find_runs([root])}
    assert runs["diverged"].status == "failed" and "nan" in runs["diverged"].reason
    assert runs["killed"].status == "failed" and "no summary.json" in runs["killed"].reason
    assert re.search(r"last written 1\.\d h ago", runs["killed"].reason), runs["killed"].reason
    assert runs["live"].status == "running"
    assert runs["psro"].status == "not aggregated" and "population run" in runs["psro"].reason
    assert runs["resumed_killed"].status == "failed" and "summary.json is of the first 1000000" in runs["resumed_killed"].reason
    assert runs["never_started"].status == "failed" and "seed=6 algo.lr=-1" in runs["never_started"].reason
    assert sum(r.status == "complete" for r in runs.values()) == 9  # 5 + 2 + 1 + 1; .hydra/ config copies are no runs
    # a longer patience turns the killed run back into a running one
    assert {r.path.name: r.status for r in find_runs([root], stale_after=7200)}["killed"] == "running"
    assert len(runs) == 15


def test_report_command_prints_and_writes_the_report(sweep, tmp_path):
    root, _ = sweep
    out = tmp_path / "report"
    res = runner.invoke(app, ["report", str(root), "--out", str(out)])
    assert res.exit_code == 0, res.output
    rows = [line for line in res.stdout.splitlines() if line.startswith("| ppo | algo.lr=0.001")]
    assert len(rows) == 1 and "| 2M | 0,1,2,3,4 | 4 |" in rows[0] and "| 3 |" in rows[0], rows
    assert "| sac | - | 2M | 0,1 | 8 | [7, 9] |" in res.stdout
    for name in ("diverged", "killed", "live", "never_started", "resumed_killed", "psro"):
        assert str(root / name) in res.stdout, name
    assert "## Runs not counted (6)" in res.stdout
    assert (out / "report.md").read_text().startswith(res.stdout.rstrip("\n"))
    assert json.loads((out / "report.json").read_text())["cells"] == build_report([root])["cells"]
    for task in ("hover", "solo_bump"):
        assert (out / f"curves_{task}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    res = runner.invoke(app, ["report", str(root / "sac"), "--json"])
    assert res.exit_code == 0 and [c["mean"] for c in json.loads(res.stdout)["cells"]] == [8.0]


def test_report_bad_input_exits_2_with_one_line(sweep, tmp_path):
    root, _ = sweep
    (tmp_path / "empty").mkdir()
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "report.md").write_text("an older report")
    cases = [
        (["report", str(tmp_path / "nowhere")], ["nowhere", "does not exist"]),
        (["report", str(tmp_path / "empty")], ["empty", "no run directories"]),
        (["report", str(root), "--out", str(tmp_path / "taken")], ["taken", "already holds a report", "report.md"]),
    ]
    for args, words in cases:
        res = runner.invoke(app, args)
        assert res.exit_code == 2, (args, res.output)
        err = res.stderr.strip()
        assert len(err.splitlines()) == 1 and err.startswith("error: ") and all(w in err for w in words), (args, err)
    assert (tmp_path / "taken" / "report.md").read_text() == "an older report"


def test_few_seeds_are_warned_and_each_metric_says_which_way_is_better(sweep):
    from volleybots.report import format_markdown, higher_is_better

    root, _ = sweep
    rep = build_report([root])
    sac, ppo, lone = _cell(rep, "sac"), _cell(rep, "ppo", variant="algo.lr=0.001"), _cell(rep, "ppo", variant="algo.lr=0.01")
    assert sac["warning"] == ("hover / sac: only 2 seeds; with fewer than 5 the 95% bootstrap interval is about the seeds' "
                              "[min, max] (exactly it here), not a reliable interval")
    assert sac["mean_ci"] == [min(sac["values"]), max(sac["values"])]  # what the warning says
    assert ppo["warning"] is None and lone["warning"] is None  # five seeds: enough; one seed: no interval to warn about
    assert sac["higher_is_better"] is False  # hover's distance: lower is better
    assert _cell(rep, "ppo", task="solo_bump")["higher_is_better"] is None  # "hits" is not solo_bump's metric: unknown
    assert higher_is_better("solo_bump", "bumps") is True and higher_is_better("no_such_task", "x") is None
    md = format_markdown(rep)
    assert "## hover: final `distance` across seeds (lower is better)" in md
    assert "## solo_bump: final `hits` across seeds (direction unknown)" in md
    warnings = [line for line in md.splitlines() if line.startswith("Warning:")]
    assert warnings == [f"Warning: {sac['warning']}."]
    res = runner.invoke(app, ["report", str(root / "sac")])
    assert res.exit_code == 0 and f"Warning: {sac['warning']}." in res.stdout
