"""Small helpers of MADDPG's set-up: the selection (the env's checks are in :mod:`sb3_maddpg.env_checks`, the
exploration noise in :mod:`sb3_maddpg.noise`)."""

import warnings

from sb3_maddpg.layout import AgentLayout
from sb3_maddpg.selection import NearestAgents, Selector


def resolve_selection(selection: Selector | int | None) -> Selector:
    """The selector of ``selected`` sharing: the default ``NearestAgents(k=2)``, or an int ``k`` for ``NearestAgents(k)``."""
    if selection is None:
        return NearestAgents(k=2)
    if isinstance(selection, int) and not isinstance(selection, bool):
        return NearestAgents(k=selection)
    if not isinstance(selection, Selector):
        raise TypeError(
            f"selection must be a sb3_maddpg.selection.Selector or an int k (the k nearest agents), got "
            f"{type(selection).__name__}: wrap a function as CallableSelector(fn, k=...)."
        )
    return selection


def warn_if_selecting_everyone(selection: Selector, layout: AgentLayout) -> None:
    """Selecting all n - 1 other agents is full sharing in another order: say so, since it compares nothing."""
    if selection.k == layout.n_agents - 1:
        warnings.warn(
            f"critic_sharing='selected' with k={selection.k} selects every other agent of this {layout.n_agents}-agent "
            f"team: each critic sees what 'full' sees, in another order. Select fewer (e.g. selection=1, the nearest "
            "agent) for a critic that selects.",
            UserWarning,
            stacklevel=3,
        )
