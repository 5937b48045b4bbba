"""A learned high level for the hierarchical 3 vs 3 team (the HCSP route; docs/hierarchical.md).

The rule-based high level (``volleybots.scripted.hierarchical``) hands three choices to a chooser:
who receives an opponent's ball, who sets, and who attacks on which side. ``HighLevelNet`` makes them
from the same 30 features the rules could see (the ball, where and when it comes down, every
drone's position, who touched), one small categorical head per choice with illegal options masked,
and a value head per choice that training uses as a baseline. ``LearnedChooser`` plugs it into the
high level: it samples its choices (a mixed strategy, as the rules draw the attack's side) or takes
the likeliest, and can record every choice it made for training (volleybots/train/high_level.py).

A high level is saved as a plain dict of tensors and numbers (``save_high_level``), read back with
``torch.load(..., weights_only=True)``; a team file names it beside its drills (``high_level: FILE``).
"""

from __future__ import annotations

import io
from pathlib import Path

import torch
from torch import nn

from volleybots.errors import ConfigError
from volleybots.files import read_bytes, write_atomic
from volleybots.scripted.hierarchical import CHOICES, FEATURES

FORMAT = "volleybots-high-level/1"
MAX_BYTES = 16 * 2**20  # a high level is a few hundred KB: a larger file is not one


def _mlp(sizes: list[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [nn.Linear(a, b), nn.Tanh()]
    return nn.Sequential(*layers[:-1])


class HighLevelNet(nn.Module):
    """Per choice (``CHOICES``): logits over its options and a value, from ``FEATURES`` features."""

    def __init__(self, hidden: tuple[int, ...] = (64, 64)):
        super().__init__()
        self.hidden = tuple(int(h) for h in hidden)
        self.heads = nn.ModuleDict({k: _mlp([FEATURES, *self.hidden, n]) for k, n in CHOICES.items()})
        self.values = nn.ModuleDict({k: _mlp([FEATURES, *self.hidden, 1]) for k in CHOICES})
        for head in self.heads.values():  # start near uniform: every option is tried before any is preferred
            nn.init.zeros_(head[-1].weight)
            nn.init.zeros_(head[-1].bias)

    def logits(self, kind: str, feats: torch.Tensor, legal: torch.Tensor) -> torch.Tensor:
        return self.heads[kind](feats).masked_fill(~legal, float("-inf"))

    def value(self, kind: str, feats: torch.Tensor) -> torch.Tensor:
        return self.values[kind](feats).squeeze(-1)


class LearnedChooser:
    """A chooser (``HighLevel``'s ``chooser``) backed by a ``HighLevelNet``.

    ``greedy`` takes the likeliest option; otherwise options are drawn from ``generator`` (torch's
    global one if None). With ``record`` on, every choice is kept as (kind, env, step, features,
    legal, option) for training; ``step`` counts the calls of ``tick`` (one per control step)."""

    def __init__(self, net: HighLevelNet, greedy: bool = False, generator: torch.Generator | None = None, record: bool = False,
                 receive_coming: bool = False, receive_attack: bool = False):
        self.net = net
        self.receive_coming = receive_coming  # call a receiver only for balls that come down in the own half
        self.receive_attack = receive_attack  # a front drone called to receive returns the ball at once (Attack)
        self.greedy = greedy
        self.generator = generator
        self.record = record
        self.step = 0
        self.memory: list[tuple[str, torch.Tensor, int, torch.Tensor, torch.Tensor, torch.Tensor]] = []

    def tick(self) -> None:
        self.step += 1

    @torch.no_grad()
    def __call__(self, kind: str, feats: torch.Tensor, legal: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        out = torch.zeros(feats.shape[0], dtype=torch.long, device=feats.device)
        if not bool(mask.any()):
            return out
        f, ok = feats[mask], legal[mask]
        logits = self.net.logits(kind, f, ok)
        if self.greedy:
            pick = logits.argmax(-1)
        else:
            pick = torch.multinomial(logits.softmax(-1), 1, generator=self.generator).squeeze(-1)
        out[mask] = pick
        if self.record:
            self.memory.append((kind, mask.nonzero().squeeze(-1), self.step, f.clone(), ok.clone(), pick))
        return out


def save_high_level(net: HighLevelNet, path, info: dict | None = None) -> None:
    """Write ``net`` to ``path`` as a weights-only checkpoint (with ``info``: frames, games, seed ...)."""
    state = {"format": FORMAT, "hidden": list(net.hidden), "state_dict": net.state_dict(), "info": dict(info or {})}
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, lambda f: torch.save(state, f), "high level")


def _read(path) -> dict:
    """The file's checkpoint dict, read with a size bound and ``weights_only=True``."""
    data = read_bytes(path, "high level", MAX_BYTES)
    try:
        return torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - any unreadable file is the same user error
        raise ConfigError(f"{str(path)!r} is damaged or no learned high level ({type(e).__name__})") from None


def load_high_level(path) -> HighLevelNet:
    """The ``HighLevelNet`` saved at ``path``; anything else is one ``ConfigError`` line."""
    return read_high_level(path)[0]


def read_high_level(path) -> tuple[HighLevelNet, dict]:
    """The ``HighLevelNet`` saved at ``path`` and its ``info`` (what ``save_high_level`` was given)."""
    state = _read(path)
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise ConfigError(f"{str(path)!r} is no learned high level (expected a file written by save_high_level, format {FORMAT})")
    hidden = state.get("hidden")
    if not isinstance(hidden, list) or not all(isinstance(h, int) and 0 < h <= 4096 for h in hidden):
        raise ConfigError(f"{str(path)!r}: its 'hidden' sizes {hidden!r} are not a list of ints in 1..4096")
    net = HighLevelNet(tuple(hidden))
    try:
        net.load_state_dict(state["state_dict"])
    except (RuntimeError, KeyError, TypeError) as e:
        raise ConfigError(f"{str(path)!r}: its weights do not fit a high level ({' '.join(str(e).split())[:160]})") from None
    bad = next((k for k, v in net.state_dict().items() if not bool(torch.isfinite(v).all())), None)
    if bad is not None:  # a NaN logit draws nothing sensible, and the team would play on without a word
        raise ConfigError(f"{str(path)!r}: its weights hold a NaN or an infinity ({bad}); restore the file or train it again")
    net.eval()
    info = state.get("info")
    info = info if isinstance(info, dict) else {}
    for key in EVENT_SETTINGS:
        if not isinstance(info.get(key, False), bool):  # bool("false") is True: a text would turn the setting on
            raise ConfigError(f"{str(path)!r}: its info {key!r} is {info[key]!r}, not true or false")
    return net, info


EVENT_SETTINGS = ("receive_coming", "receive_attack")  # the chooser's switches a file carries in its info


def chooser_from_file(path, generator: torch.Generator | None = None) -> LearnedChooser:
    """A sampling ``LearnedChooser`` of the high level at ``path``, with the event setting it was trained with."""
    net, info = read_high_level(path)
    return LearnedChooser(net, generator=generator, **{k: info.get(k, False) for k in EVENT_SETTINGS})


__all__ = ["FORMAT", "HighLevelNet", "LearnedChooser", "chooser_from_file", "load_high_level", "read_high_level", "save_high_level"]
