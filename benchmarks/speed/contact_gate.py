"""What skipping the contact tests saves: eager env steps with ``physics.torch_backend.may_touch`` as it is
and with it answering "yes" every time (every sub-step runs the contact tests, as before the gate).

    python benchmarks/speed/contact_gate.py                      # 32 envs, random actions, five tasks
    python benchmarks/speed/contact_gate.py num_envs=256 tasks=[hover,1v1]

Both ways give the same numbers (tests/physics/test_physics.py); only the time differs. The two ways take
turns within one process, so the machine's load falls on both alike; each figure is the mean of the
faster half of the rounds (CPU ms per env step, ``profile_step.cpu_ms``, one torch thread). Print the
machine's load beside it.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import torch

import volleybots
import volleybots.physics.torch_backend as tb

sys.path.insert(0, str(Path(__file__).parent))
from profile_step import cpu_ms  # noqa: E402  (the other benchmarks' helpers)

from volleybots.config.args import option, script_options  # noqa: E402


@dataclass
class Args:
    tasks: list[str] = option(help="tasks to step", factory=lambda: ["hover", "back_and_forth", "solo_bump", "1v1", "3v3"])
    num_envs: int = option(32, "worlds stepped together", ge=1)
    rounds: int = option(8, "rounds, each way once a round", ge=1)
    steps: int = option(25, "env steps per round and way", ge=1)


def random_steps(env):
    """A function that steps ``env`` once with random actions (the rollout's tensordict kept between calls)."""
    held = {"td": env.reset()}

    def step():
        held["td"].update(env.full_action_spec.rand())
        _, held["td"] = env.step_and_maybe_reset(held["td"])

    return step


def main(argv=None) -> None:
    a = script_options(Args, argv, __doc__)
    torch.set_num_threads(1)
    gate, always = tb.may_touch, (lambda *args: True)
    print("| task | envs | gated (ms/step) | always tested (ms/step) | speed-up |\n|---|---|---|---|---|")
    for task in a.tasks:
        step = random_steps(volleybots.make_env(task, num_envs=a.num_envs, seed=0))
        times: dict[str, list[float]] = {"gated": [], "always": []}
        for _ in range(a.rounds):
            for name, fn in (("gated", gate), ("always", always)):
                tb.may_touch = fn
                try:
                    times[name].append(cpu_ms(step, a.steps))
                finally:
                    tb.may_touch = gate
        g, w = (sorted(times[k])[: max(1, a.rounds // 2)] for k in ("gated", "always"))
        g, w = sum(g) / len(g), sum(w) / len(w)
        print(f"| {task} | {a.num_envs} | {g:.2f} | {w:.2f} | {w / g:.2f}x |", flush=True)


if __name__ == "__main__":
    main()
