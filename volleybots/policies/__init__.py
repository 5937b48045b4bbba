"""What plays: the policy store (a checkpoint becomes a policy in one place), the built-in players,
competitors (one side of a match, populations included) and targets (one policy for a whole env).

Floor: above ``algos`` and ``runs`` (it builds learners from checkpoints), below ``play``, ``train``,
``population`` and ``eval``, which all name what plays through ``store.parse_spec``'s grammar.
"""

from volleybots.policies.builtin import BUILTIN, PLAYERS, Player, hierarchical_policy, random_policy, read_drills_file, scripted_policy
from volleybots.policies.competitors import (
    Competitor,
    Member,
    MixturePolicy,
    builtin_member,
    callable_competitor,
    checkpoint_member,
    hierarchical_member,
    import_competitor,
    member_path,
    population_members,
    read_meta,
    resolve_competitor,
    single_policy,
    torchscript_competitor,
)
from volleybots.policies.store import load_learner, load_policy, parse_spec, policy_checkpoint, sha256
from volleybots.policies.targets import EVAL_KEYS, Target, check_references, resolve_target

__all__ = [
    "BUILTIN", "EVAL_KEYS", "PLAYERS", "Competitor", "Member", "MixturePolicy", "Player", "Target", "builtin_member",
    "callable_competitor", "check_references", "checkpoint_member", "hierarchical_member", "hierarchical_policy",
    "import_competitor", "load_learner", "load_policy", "member_path", "parse_spec", "policy_checkpoint", "population_members",
    "random_policy", "read_drills_file", "read_meta", "resolve_competitor", "resolve_target", "scripted_policy", "sha256",
    "single_policy", "torchscript_competitor",
]
