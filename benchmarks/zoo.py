"""Put a trained run into the zoo: ``volleybots/zoo/<task>/<method>.pt`` and its card ``<method>.yaml``;
a population run as a mixture, its members in ``<task>/<method>/``.

    python benchmarks/zoo.py RUN_DIR METHOD games=400 seed=9000
    python benchmarks/zoo.py TEAM.yaml METHOD games=400 seed=9000 command="..."   # a hierarchical 3v3 team

A checkpoint keeps what acting needs and what ``load_algo_state`` reads (networks, observation
statistics, counters) with a fresh optimiser state: a few hundred KB instead of the run's megabytes.
A population run (``volleybots.runs.is_population_run``) ships its final meta-strategy: every member
of nonzero weight, slimmed so, as ``<method>/<label>.pt``, and the card's ``mixture:`` lists them with
their weights (``volleybots.zoo``).
A hierarchical team's file (``hierarchical: {drill: run or checkpoint, high_level: file}``, as
benchmarks/hcsp.py writes it) ships as a team entry: each drill's policy slimmed so and its learned
high level as ``<method>/<drill>.pt`` and ``<method>/high_level.pt``, the card's ``hierarchical:``
naming them (its frames: the drills' frames; its seed: the high level's).
The card records the command, frames, seed and wall time from the run's files, and the figures of
``games=`` games per pair of the entry (a mixture as the one competitor it is) against ``random`` and
``scripted`` on the evaluation seed ``seed=`` (a seed no setting was chosen on), both sides equally.
"""

from __future__ import annotations

import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import torch
import yaml

from volleybots.algos import method_name
from volleybots.config import make_env, to_dict
from volleybots.config.args import option, script_options
from volleybots.eval.crossplay import crossplay, match_config, resolve_all
from volleybots.policies.store import load_learner, saved_config
from volleybots.runs import RunDir, is_population_run, read_checkpoint, read_population, run_policy_checkpoint
from volleybots.zoo import PREFIX, ZOO_DIR, lookup

NOTE = "both sides equally; the seed was never used to choose a setting"


def slim_checkpoint(src: Path) -> dict:
    """The checkpoint ``src`` with a fresh optimiser and no training-only state (rng, evals, anchor);
    a population's record of a built-in player (no drills) is already only what plays."""
    state = read_checkpoint(src)
    if "builtin" in state:
        if state.get("drills"):  # they name checkpoint files of this machine, which the zoo does not ship
            raise SystemExit(f"{src} is the hierarchical team with trained drills: the zoo cannot ship its drills' files")
        return state
    env = make_env(saved_config(state, f"checkpoint {str(src)!r}"), num_envs=1)
    learner, _ = load_learner(src, env, int(state["n_agents"]))
    algo = learner.state_dict()
    algo.pop("anchor", None)
    if "optim" in algo:  # the moments are training state: an empty state with the same parameter groups loads as fresh
        algo["optim"] = {"state": {}, "param_groups": algo["optim"]["param_groups"]}
    if "data" in algo:  # a clone's imitation dataset is what it learned from, not what it acts with
        algo["data"] = {k: v[:0].clone() for k, v in algo["data"].items()}
        algo["counters"] = torch.tensor([int(algo["counters"][0]), 0, 0])
    keep = ("format", "version", "config", "task", "action_space", "obs_dim", "n_agents", "frames", "iteration", "wall_time", "label")
    return {**{k: state[k] for k in keep if k in state}, "algo": algo}


def save(state: dict, out: Path) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    torch.save(state, out)
    torch.load(out, weights_only=True)  # what every user does


def single_entry(ckpt: Path, task_dir: Path, method: str) -> dict:
    """Write ``<method>.pt`` from the checkpoint ``ckpt`` and return the card's run fields."""
    slim = slim_checkpoint(ckpt)
    save(slim, task_dir / f"{method}.pt")
    cfg = slim["config"]
    return {"algo": cfg["algo"]["name"], "frames": int(slim["frames"]), "seed": int(cfg["seed"]), "wall_time": slim.get("wall_time", 0.0),
            "config": to_dict(cfg)}


def ship_team_member(path: Path, state: dict, out: Path, label: str) -> None:
    """A hierarchical population member (``volleybots.population.hierarchical``): its record as it is and
    the files it names (drills, high level; paths relative to the member's folder) copied beside it."""
    for rel in state["drills"].values():
        if Path(rel).is_absolute():
            raise SystemExit(f"{path} names {rel}, a file of this machine, which the zoo cannot ship")
        dst = out.parent / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        dst.write_bytes((path.parent / rel).read_bytes())
    save({**state, "label": label}, out)


def mixture_entry(run: RunDir, pop, task_dir: Path, method: str) -> dict:
    """Write ``<method>/<label>.pt`` for every member of nonzero weight in the final meta-strategy
    ``pop`` and return the card's run fields, with ``members`` (all of them) and ``mixture`` (those shipped)."""
    members, mixture = [], []
    for k, (path, label, weight) in enumerate(zip(pop.members, pop.labels, pop.mixture, strict=True)):
        state = read_checkpoint(path)
        members.append({"label": label, "frames": int(state.get("frames", 0)), "weight": float(weight)})
        if weight > 0:
            # a label that is no plain file name, or one two members share, names the file by its index
            plain = re.fullmatch(r"[A-Za-z0-9_.-]+", label) and pop.labels.count(label) == 1
            file = f"{method}/{label if plain else f'member_{k:03d}'}.pt"
            # the population's label, which the card lists: a seed member copied from a checkpoint
            # (seed_members=[zoo:1v1/bc]) carries none of its own
            if state.get("builtin") == "hierarchical" and state.get("drills"):
                ship_team_member(path, state, task_dir / file, label)
            else:
                save({**slim_checkpoint(path), "label": label}, task_dir / file)
            mixture.append({"file": file, "weight": float(weight)})
    cfg = run.load_config()
    last = pop.metas[-1]
    return {"algo": method_name(cfg), "frames": int(last["frames"]), "seed": int(cfg.seed), "wall_time": last["wall_time"],
            "config": to_dict(cfg), "iteration": pop.iteration, "members": members, "mixture": mixture}


def entry(run: RunDir, task_dir: Path, method: str) -> dict:
    """Write the entry's files and return the card's run fields: a population whose final meta-strategy
    plays more than one member is a mixture; any other run ships its one policy."""
    what = f"run {str(run.path)!r}"
    for old in [task_dir / f"{method}.pt", *(task_dir / method).glob("**/*.pt")]:  # a rerun replaces the entry whole, of either kind
        old.unlink(missing_ok=True)
    if not is_population_run(run.path):
        return single_entry(run_policy_checkpoint(run.path, what), task_dir, method)
    pop = read_population(run.path, what)
    playing = [p for p, w in zip(pop.members, pop.mixture, strict=True) if w > 0]
    if len(playing) > 1:
        return mixture_entry(run, pop, task_dir, method)
    # one member plays: its file ships alone, but the card is the run's (a member's config is its
    # iteration's: seed + iteration x 1000, the oracle's own budget and time limit)
    cfg = run.load_config()
    label = pop.labels[pop.members.index(playing[0])]
    return {**single_entry(playing[0], task_dir, method), "algo": method_name(cfg), "seed": int(cfg.seed), "config": to_dict(cfg),
            "iteration": pop.iteration, "member": label}


def team_entry(team: Path, task_dir: Path, method: str) -> dict:
    """Write ``<method>/<drill>.pt`` and ``<method>/high_level.pt`` from the team file ``team`` and return
    the card's fields (``hierarchical:`` naming them)."""
    from volleybots.policies.builtin import HIGH_LEVEL, read_drills_file
    from volleybots.policies.high_level import load_high_level

    listed, files, frames, seed, wall = read_drills_file(team), {}, 0, None, 0.0
    for old in (task_dir / method).glob("*.pt"):
        old.unlink()
    for drill, spec in listed.items():
        file = f"{method}/{drill}.pt"
        if drill == HIGH_LEVEL:
            load_high_level(spec)  # checked before it ships
            state = torch.load(spec, weights_only=True)
            seed = int(state["info"].get("seed", 0))
            save(state, task_dir / file)
        else:
            src = Path(spec)
            slim = slim_checkpoint(run_policy_checkpoint(src, f"drill {drill!r}") if src.is_dir() else src)
            frames += int(slim["frames"])
            wall += float(slim.get("wall_time", 0.0))
            save(slim, task_dir / file)
        files[drill] = file
    return {"algo": "hcsp", "frames": frames, "seed": seed if seed is not None else 0, "wall_time": wall, "config": {},
            "hierarchical": files}


def figures(name: str, method: str, games: int, seed: int) -> dict:
    """The entry's figures against ``random`` and ``scripted``: ``games`` games per pair on ``seed``."""
    comps = resolve_all([f"{method}={PREFIX}{name}", "random", "scripted"])
    res = crossplay(match_config(comps, ["threads=1"]), comps, games, seed=seed)
    wr, lo_hi = res.win_rate(), res.interval()
    out = {}
    for j, opponent in ((1, "random"), (2, "scripted")):
        w, d, l_ = res.wdl[0, j].astype(int).tolist()
        out[f"vs_{opponent}"] = f"{wr[0, j]:.3f} of decisive games [{lo_hi[0][0, j]:.2f}, {lo_hi[1][0, j]:.2f}], W/D/L {w}/{d}/{l_}"
    return out


def start_fields(init: str | None, frames: int) -> dict:
    """The card's record of what the run started from (its config's ``init=``): the start, and for a zoo
    start the frames of both together (a zoo entry's card knows its own)."""
    if not init:
        return {}
    start = lookup(init)
    out = {"init": init}
    if start is not None and isinstance(start.card.get("frames"), int):
        out["frames_with_start"] = frames + start.card["frames"]
    return out


@dataclass
class Args:
    run: Optional[Path] = option(None, "the run dir (or a hierarchical team's .yaml)", positional=True)
    method: Optional[str] = option(None, "the zoo entry's method name", positional=True)
    games: int = option(400, "games played")
    seed: int = option(9000, "the seed")
    command: str = option("", "the command that trained the run, for the card")
    init: str = option("", "the zoo name of the policy the run started from, when the run was "
                   "trained from that policy's file before it shipped (its config names the file)")


def main(argv=None) -> int:
    a = script_options(Args, argv, __doc__)
    if a.init and lookup(a.init) is None:
        print(f"error: init={a.init!r} is not a zoo entry", file=sys.stderr)
        raise SystemExit(2)
    if a.run.suffix in (".yaml", ".yml"):  # a hierarchical team's file
        task, summary = "3v3", {}
        task_dir = ZOO_DIR / task
        fields = team_entry(a.run, task_dir, a.method)
        init = None
    else:
        run = RunDir(a.run)
        cfg = run.load_config()
        task = cfg.task.name
        task_dir = ZOO_DIR / task
        fields = entry(run, task_dir, a.method)
        init = fields["config"]["init"] = a.init or cfg.get("init")
        summary = json.loads(run.summary_path.read_text()) if run.summary_path.is_file() else {}
    name = f"{task}/{a.method}"
    head = {
        "name": PREFIX + name,
        "task": task,
        "algo": fields["algo"],
        "command": a.command or f"volleybots train task={task} algo={fields['algo']} seed={fields['seed']}",
        "frames": fields["frames"],
        **start_fields(init, fields["frames"]),
        "seed": fields["seed"],
        "wall_time_s": round(float(summary.get("wall_time_s", fields["wall_time"])), 1),
        **{k: fields[k] for k in ("iteration", "member", "members", "mixture", "hierarchical") if k in fields},
        "evaluation": {"games_per_pair": a.games, "seed": a.seed, "note": NOTE},
    }
    card = task_dir / f"{a.method}.yaml"
    # the entry must be listed to be played by its name; until its figures are measured its card lacks them
    card.write_text(yaml.safe_dump({**head, "config": fields["config"]}, sort_keys=False))
    figs = figures(name, a.method, a.games, a.seed)
    card.write_text(yaml.safe_dump({**head, "figures": figs, "config": fields["config"]}, sort_keys=False))
    files = ([task_dir / m["file"] for m in fields["mixture"]] if "mixture" in fields else
             [task_dir / f for f in fields["hierarchical"].values()] if "hierarchical" in fields else [task_dir / f"{a.method}.pt"])
    print(f"wrote {PREFIX + name} ({', '.join(f'{f.stat().st_size / 1024:.0f} KB' for f in files)}) and its card: {figs}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
