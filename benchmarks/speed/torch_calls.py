"""What a small eager batch costs: torch calls per physics sub-step, env step and scripted step.

    python benchmarks/speed/torch_calls.py                 # 32 envs, the default tasks
    python benchmarks/speed/torch_calls.py num_envs=8 scripted=[bump_and_pass,set_and_spike_easy]

At the tests' and the lookahead's batch sizes an eager step is bound by the number of torch calls,
not by the arithmetic, so the counts here (from ``torch.profiler``: every aten call, nested ones
included) are the figure to compare between commits; they do not depend on the machine's load. The
timings beside them (CPU ms per call, the minimum over repeats, one torch thread) do.

The first line shows why numbers are 0-d tensors in the hot paths (``physics.math.num``): with
torch 2.13 on a CPU, ``tensor * 0.5`` wraps the number in a double tensor and converts it on every
call (``aten::to``, ``_to_copy``, ``empty_strided``, ``copy_``).
"""

from __future__ import annotations

import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import torch
from torch.profiler import profile

import volleybots
from volleybots.config.args import option, script_options

sys.path.insert(0, str(Path(__file__).parent))
from profile_step import cpu_ms as cpu_ms_once  # noqa: E402  (the other benchmarks' helpers)


def calls(fn, reps: int = 3) -> float:
    """aten calls per ``fn()`` (the mean over ``reps`` profiled calls)."""
    with profile() as prof:
        for _ in range(reps):
            fn()
    return sum(1 for e in prof.events() if e.name.startswith("aten::")) / reps


def cpu_ms(fn, reps: int, rounds: int = 5) -> float:
    """CPU ms per ``fn()``: the fastest of ``rounds`` rounds of ``reps`` calls (a shared machine's
    load only ever adds time)."""
    return min(cpu_ms_once(fn, reps) for _ in range(rounds))


def scalar_line() -> str:
    x = torch.rand(32, 2)
    k = torch.tensor(0.5)
    with torch.inference_mode():
        n_num, n_ten = calls(lambda: x * 0.5, 10), calls(lambda: x * k, 10)
        t_num, t_ten = cpu_ms(lambda: x * 0.5, 5000), cpu_ms(lambda: x * k, 5000)
    kinds = Counter()
    with profile() as prof:
        _ = x * 0.5
    kinds.update(e.name for e in prof.events())
    return (f"x * 0.5: {n_num:.0f} aten calls, {t_num * 1e3:.2f} us ({', '.join(sorted(kinds))}); "
            f"x * k (0-d tensor): {n_ten:.0f} call, {t_ten * 1e3:.2f} us")


def env_rows(task: str, space: str, num_envs: int, reps: int) -> list[str]:
    env = volleybots.make_env(task, num_envs=num_envs, action_space=space, seed=0)
    state = {"td": env.reset()}
    action = env.full_action_spec.rand()
    command = env.actions.command_fn(action.get(("agents", "action")))

    def physics():
        env.physics.step(command)

    def step():
        state["td"].update(action)
        _, state["td"] = env.step_and_maybe_reset(state["td"])

    return [f"| {task} {name} | {space} | {num_envs} | {calls(fn):.0f} | {cpu_ms(fn, reps):.2f} |"
            for name, fn in (("physics (4 sub-steps)", physics), ("env step", step))]


def scripted_row(task: str, num_envs: int) -> str:
    from volleybots.scripted import make_scripted_policy

    env = volleybots.make_env(task, num_envs=num_envs, action_space="prt", seed=2)
    policy = make_scripted_policy(env)
    td = env.reset()
    for _ in range(15):  # into the rally, where the players search their touches
        td.update(policy(td))
        _, td = env.step_and_maybe_reset(td)

    def act():
        return policy(td.clone())

    return f"| {task} scripted players, one action (lookahead) | prt | {num_envs} | {calls(act, 2):.0f} | {cpu_ms(act, 2, 3):.1f} |"


@dataclass
class Args:
    tasks: list[str] = option(help="env steps under random actions", factory=lambda: ["hover", "1v1", "3v3"])
    scripted: list[str] = option(help="steps of the task's scripted players", factory=lambda: ["bump_and_pass"])
    num_envs: int = option(32, "worlds stepped together", ge=1)
    reps: int = option(20, "timed calls per row", ge=1)


def main(argv=None) -> None:
    args = script_options(Args, argv, __doc__)
    torch.set_num_threads(1)
    print(scalar_line())
    print()
    print("| what | action space | envs | aten calls | CPU ms |")
    print("|---|---|---|---|---|")
    for task in args.tasks:
        for space in ("prt", "ctbr"):
            print("\n".join(env_rows(task, space, args.num_envs, args.reps)))
    for task in args.scripted:
        print(scripted_row(task, args.num_envs))


if __name__ == "__main__":
    main()
