"""What a setting may declare as its ``reference_policies`` (:mod:`~sb3_maddpg.experiments.references` evaluates and
reports them): the kinds, the keys each takes, and the check of a declaration. It imports nothing of the package, so
that the config model can check a setting without the modules that evaluate it."""

import re
from collections.abc import Mapping
from typing import Any

REFERENCE_KINDS = {
    "random": "uniformly random actions: each agent's uniform over its action space (a discrete agent's moves alike)",
    "no_op": "doing nothing: a zero action for each continuous agent (clipped into its space), the no-op `action` "
    "for each discrete agent",
}
"""The kinds of reference policy a setting may declare, and what each does."""

REFERENCE_KEYS = {"random": ("kind",), "no_op": ("kind", "action")}
"""The keys each kind takes."""

REFERENCE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
"""What a reference policy's name may be (it names it in the results and the report)."""


def check_reference_policies(policies: Any) -> None:
    """
    Refuse a setting's ``reference_policies`` that cannot be evaluated, naming the cause and what to give.

    :param policies: The setting's ``reference_policies``: name -> ``{"kind": <a kind of REFERENCE_KINDS>, ...}``.
    """
    example = "{random: {kind: random}, nothing: {kind: no_op, action: 4}}"
    if not isinstance(policies, Mapping):
        raise ValueError(f"reference_policies must map names to policies, e.g. {example}, got {policies!r}.")
    for name, spec in policies.items():
        if not isinstance(name, str) or not REFERENCE_NAME.match(name):
            raise ValueError(
                f"reference_policies: name {name!r} cannot name a reference policy: use letters, digits, '_', '-' and "
                "'.', starting with a letter or digit (e.g. 'random')."
            )
        kind = spec.get("kind") if isinstance(spec, Mapping) else None
        if kind not in REFERENCE_KINDS:
            raise ValueError(
                f"reference_policies: {name!r} is {spec!r}, no policy: give a mapping with a kind of "
                f"{list(REFERENCE_KINDS)}, e.g. {example}."
            )
        unknown = sorted(set(spec) - set(REFERENCE_KEYS[kind]))
        if unknown:
            raise ValueError(
                f"reference_policies: {name!r} ({kind}) has unknown key(s) {unknown}: a {kind} policy takes "
                f"{list(REFERENCE_KEYS[kind])}."
            )
        action = spec.get("action")
        if action is not None and (not isinstance(action, int) or isinstance(action, bool) or action < 0):
            raise ValueError(
                f"reference_policies: {name!r} has action={action!r}: give the discrete agents' no-op action as an "
                "index of their moves (an integer of at least 0, e.g. pursuit's 4), or leave it out for continuous ones."
            )
