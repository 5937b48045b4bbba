"""``volleybots replay A B``: one match between two competitors recorded to rerun."""

from __future__ import annotations

from pathlib import Path

from volleybots.config.args import split_args
from volleybots.errors import ConfigError
from volleybots.eval.crossplay import setup


REPLAY_OPTIONS = {"seed": int, "scenario": str, "deterministic": bool}


def is_competitor_spec(arg: str) -> bool:
    """A replay argument names a competitor (rather than a config override) when it has no ``=`` or
    labels a built-in player or an existing path: ``replay A B`` records a match, ``replay A k=v`` one policy."""
    from volleybots.policies import BUILTIN

    label, eq, value = arg.partition("=")
    return not eq or value in BUILTIN or (bool(value) and Path(value).exists())


def replay_match(args, out: Path | None, viewer: bool) -> tuple[dict, Path | None, list[str]]:
    """``volleybots replay A B task=3v3``: one match between two competitors recorded to rerun (team
    colours, touches, the point and its fault); returns (env 0's statistics, the file, the labels)."""
    import time

    from volleybots.play.games import side_env
    from volleybots.replay import record_match
    from volleybots.tasks.multi import TeamPolicies

    specs = split_args(args, REPLAY_OPTIONS)[0]
    if len(specs) != 2:
        raise ConfigError(f"a match replay takes two competitors; got {len(specs)}: {' '.join(specs)}")
    comps, specs, opts, cfg = setup(args, REPLAY_OPTIONS)
    labels = [c.label for c in comps]
    if out is None and not viewer:
        stamp = time.strftime("%Y%m%d-%H%M%S")
        name = "_vs_".join(lab.replace("@", "_").replace("/", "_") for lab in labels)
        out = Path("outputs") / "replays" / f"replay_{cfg.task.name}_{name}_{stamp}.rrd"
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
    seed = opts.get("seed", 0)
    env = side_env(cfg, 0, opts.get("scenario", "any"), 1, seed)  # A is team 0 (blue)
    gen = torch_generator(seed)
    policy = TeamPolicies(env, tuple(c.team_policy(env, opts.get("deterministic", False), gen) for c in comps))
    return record_match(env, policy, tuple(labels), out, viewer=viewer), out, labels


def torch_generator(seed: int):
    import torch

    torch.manual_seed(seed)
    return torch.Generator().manual_seed(seed)
