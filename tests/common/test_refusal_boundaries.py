"""Every refusal of the networks, the sharing schemes, the selectors and the exploration noise at its boundary: the
last value accepted and the first one refused, each refusal by its error type and a fragment naming the cause.

Boundaries that other files already test on both sides are not repeated here: the features size of an extractor
(test_sharing), a selector's ``k >= 1`` (test_selection), the number and the sign of ``noise_std`` values (test_noise),
the mapping from agent ids to schemes (test_per_agent_sharing) and a FixedGraph's number of neighbour lists
(test_selection).
"""

import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from gymnasium import spaces
from pettingzoo import ParallelEnv
from stable_baselines3.common.noise import ActionNoise

from sb3_maddpg import MADDPG
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.networks import AgentEnsembleMLP
from sb3_maddpg.common.noise import draw_noise
from sb3_maddpg.common.selection import CallableSelector, FixedGraph, NearestAgents, Selector, resolve_selector
from sb3_maddpg.envs import PettingZooToGym, make_simple_spread
from sb3_maddpg.sharing import (
    ActionsCriticFeatures,
    AttentionCriticFeatures,
    CriticFeaturesExtractor,
    FullCriticFeatures,
    IndependentCriticFeatures,
    LearnedSelectionCriticFeatures,
    ObservationsCriticFeatures,
    SelectedCriticFeatures,
    validate_critic_sharing,
)
from tests.settings import NEVER_UPDATES


def team(n_agents: int, obs_size: int = 6) -> AgentLayout:
    """A team of ``n_agents`` equal agents: observations of ``obs_size`` (MPE-like, the position declared at 2:4), actions
    of 2."""
    positions = (slice(2, 4),) * n_agents if obs_size >= 4 else None
    return AgentLayout(tuple("abcdefgh"[:n_agents]), (obs_size,) * n_agents, (2,) * n_agents, position_slices=positions)


def check(build: Callable[[], object], refusal: str | None, error: type[Exception] = ValueError) -> None:
    """
    :param build: What is checked.
    :param refusal: None when ``build`` must succeed; else a regular expression its error's message must match.
    :param error: The type of that error.
    """
    if refusal is None:
        build()
        return
    with pytest.raises(error, match=refusal):
        build()


# ---------------------------------------------------------------------------------------------- networks.py

SIZES_PER_AGENT = "Need one input and one output size per agent"


@pytest.mark.parametrize(
    ("in_dims", "out_dims", "refusal"),
    [
        ([3], [2], None),  # one agent: the smallest team
        ([], [], SIZES_PER_AGENT),  # none
        ([3, 3], [2, 2], None),
        ([3, 3], [2], SIZES_PER_AGENT),  # one output size short
        ([3], [2, 2], SIZES_PER_AGENT),  # one output size over
    ],
)
def test_ensemble_needs_one_input_and_one_output_size_per_agent(
    in_dims: list[int], out_dims: list[int], refusal: str | None
) -> None:
    """One input and one output size per agent, for at least one agent."""
    check(lambda: AgentEnsembleMLP(in_dims, out_dims, [4]), refusal)


EQUAL_SIZES = r"share_parameters=True needs agents with equal network sizes, got inputs \[{}\] and outputs \[{}\]"


@pytest.mark.parametrize(
    ("in_dims", "out_dims", "refusal"),
    [
        ([4, 4, 4], [2, 2, 2], None),
        ([4, 4, 5], [2, 2, 2], EQUAL_SIZES.format("4, 4, 5", "2, 2, 2")),  # exactly two input sizes
        ([4, 4, 4], [2, 3, 2], EQUAL_SIZES.format("4, 4, 4", "2, 3, 2")),  # exactly two output sizes
        ([4, 5], [2, 3], EQUAL_SIZES.format("4, 5", "2, 3")),  # two of each
    ],
)
def test_shared_parameters_refuse_two_distinct_sizes(in_dims: list[int], out_dims: list[int], refusal: str | None) -> None:
    """One network for all agents needs equal sizes: two distinct sizes (of inputs or of outputs) are refused, and
    the same team is accepted with a network per agent."""
    check(lambda: AgentEnsembleMLP(in_dims, out_dims, [4], share_parameters=True), refusal)
    assert AgentEnsembleMLP(in_dims, out_dims, [4], share_parameters=False).n_members == len(in_dims)


# ---------------------------------------------------------------------------------------------- sharing/

EXTRACTORS: list[tuple[type[CriticFeaturesExtractor], dict[str, Any]]] = [
    (CriticFeaturesExtractor, {"features_dim": 1}),
    (IndependentCriticFeatures, {}),
    (FullCriticFeatures, {}),
    (ObservationsCriticFeatures, {}),
    (ActionsCriticFeatures, {}),
    (SelectedCriticFeatures, {"selection_size": 1}),
    (AttentionCriticFeatures, {"embed_dim": 4, "n_heads": 1}),
    (LearnedSelectionCriticFeatures, {"k": 1, "embed_dim": 4}),
]


@pytest.mark.parametrize(("extractor", "kwargs"), EXTRACTORS, ids=[cls.__name__ for cls, _ in EXTRACTORS])
@pytest.mark.parametrize(
    ("agent_index", "refusal"),
    [
        (-1, "agent_index -1 is out of range for a team of 3 agents"),  # would silently be the last agent
        (0, None),
        (2, None),
        (3, "agent_index 3 is out of range for a team of 3 agents"),
    ],
)
def test_every_scheme_refuses_an_agent_index_outside_the_team(
    extractor: type[CriticFeaturesExtractor], kwargs: dict[str, Any], agent_index: int, refusal: str | None
) -> None:
    """Agent indices 0 to n - 1, in every scheme (the base class and the fixed ones check before indexing)."""
    check(lambda: extractor(team(3), agent_index, **kwargs), refusal)


@pytest.mark.parametrize(
    ("n_agents", "refusal"),
    [(1, "critic_sharing='selected' needs at least 2 agents, got 1"), (2, None)],
)
def test_selected_sharing_needs_another_agent_to_select(n_agents: int, refusal: str | None) -> None:
    """A team of one has no agent to select: refused by the scheme's layout check and by its constructor."""
    check(lambda: SelectedCriticFeatures.check_layout(team(n_agents)), refusal)
    check(lambda: SelectedCriticFeatures(team(n_agents), 0, selection_size=1), refusal)


class Solo(ParallelEnv):
    """A team of one agent: observations of 4, actions of 2, episodes of 5 steps."""

    metadata = {"name": "solo_v0"}

    def __init__(self) -> None:
        self.possible_agents = ["solo"]
        self.agents: list[str] = []

    def observation_space(self, agent: str) -> spaces.Box:
        return spaces.Box(-10.0, 10.0, (4,), np.float32)

    def action_space(self, agent: str) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (2,), np.float32)

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        self.agents, self.t = list(self.possible_agents), 0
        return {"solo": np.zeros(4, np.float32)}, {"solo": {}}

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        self.t += 1
        return {"solo": np.zeros(4, np.float32)}, {"solo": 0.0}, {"solo": False}, {"solo": self.t >= 5}, {"solo": {}}


@pytest.mark.parametrize("selector", [None, 1])
def test_maddpg_names_a_team_of_one_as_the_cause_for_selected_sharing(selector: int | None) -> None:
    """MADDPG says the team is too small for 'selected', not what the selector (whatever its k) fails at later."""
    with pytest.raises(ValueError, match="critic_sharing='selected' needs at least 2 agents, got 1"):
        MADDPG("MlpPolicy", PettingZooToGym(Solo()), critic_sharing="selected", selector=selector, **NEVER_UPDATES)
    # The warning's advice fits the team: a team of 2 cannot select fewer than its one other agent.
    with pytest.warns(UserWarning, match="selects every other agent of this 2-agent team.*A team of 2 has one other"):
        model = MADDPG("MlpPolicy", make_simple_spread(n_agents=2), critic_sharing="selected", selector=1, **NEVER_UPDATES)
    assert model.critic.extractors[0].selection_size == 1  # two agents: accepted


@pytest.mark.parametrize(
    ("selection_size", "refusal"),
    [
        (0, "selection_size must be between 1 and 2, got 0"),
        (1, None),
        (2, None),
        (3, "selection_size must be between 1 and 2, got 3"),
    ],
)
def test_selected_sharing_selects_1_to_n_minus_1_agents(selection_size: int, refusal: str | None) -> None:
    """A selection of 1 to n - 1 other agents."""
    check(lambda: SelectedCriticFeatures(team(3), 0, selection_size=selection_size), refusal)


LISTENING = [AttentionCriticFeatures, LearnedSelectionCriticFeatures]


@pytest.mark.parametrize("extractor", LISTENING, ids=lambda cls: cls.scheme_name)
@pytest.mark.parametrize(("embed_dim", "refusal"), [(0, "embed_dim must be positive, got 0"), (1, None)])
def test_listening_schemes_need_a_positive_embedding(
    extractor: type[AttentionCriticFeatures | LearnedSelectionCriticFeatures], embed_dim: int, refusal: str | None
) -> None:
    """Encodings of at least one component."""
    kwargs: dict[str, Any] = {"n_heads": 1} if extractor is AttentionCriticFeatures else {"k": 1}
    check(lambda: extractor(team(3), 0, embed_dim=embed_dim, **kwargs), refusal)


@pytest.mark.parametrize("extractor", LISTENING, ids=lambda cls: cls.scheme_name)
@pytest.mark.parametrize(("n_agents", "refusal"), [(1, "needs at least 2 agents, got 1"), (2, None)])
def test_listening_schemes_need_another_agent(
    extractor: type[AttentionCriticFeatures | LearnedSelectionCriticFeatures], n_agents: int, refusal: str | None
) -> None:
    """A team of two is the smallest with another agent to listen to."""
    check(lambda: extractor(team(n_agents), 0, embed_dim=4), refusal)


HEADS = "must be a positive multiple of n_heads"


@pytest.mark.parametrize(
    ("n_heads", "refusal"),
    [(0, HEADS), (1, None), (3, HEADS), (4, None), (8, HEADS)],  # embed_dim 4: 1, 2 and 4 heads divide it
)
def test_attention_heads_divide_the_embedding(n_heads: int, refusal: str | None) -> None:
    """At least one head, and ``embed_dim`` a multiple of their number (up to one head per component)."""
    check(lambda: AttentionCriticFeatures(team(3), 0, embed_dim=4, n_heads=n_heads), refusal)


@pytest.mark.parametrize(
    ("kwargs", "refusal"),
    [
        ({"k": 0}, "chooses k of the 3 other agents, got k=0"),
        ({"k": 1}, None),
        ({"k": 3}, None),
        ({"k": 4}, "chooses k of the 3 other agents, got k=4"),
        ({"selection_size": 3}, None),  # k taken from selection_size when not given
        ({"selection_size": 4}, "chooses k of the 3 other agents, got k=4"),
    ],
)
def test_learned_selection_chooses_1_to_n_minus_1_agents(kwargs: dict[str, Any], refusal: str | None) -> None:
    """A learned choice of 1 to n - 1 other agents, however k is given."""
    check(lambda: LearnedSelectionCriticFeatures(team(4), 0, embed_dim=4, **kwargs), refusal)


@pytest.mark.parametrize(
    ("temperature", "refusal"),
    [(-0.5, "temperature must be positive"), (1e-6, None), (float("nan"), "temperature must be positive, got nan")],
)
def test_learned_selection_temperature_is_positive(temperature: float, refusal: str | None) -> None:
    """Any positive temperature, however small (0 itself: test_attention); not a NaN, which compares false."""
    check(lambda: LearnedSelectionCriticFeatures(team(3), 0, k=1, embed_dim=4, temperature=temperature), refusal)


@pytest.mark.parametrize(
    ("critic_sharing", "refusal"),
    [({}, "critic_sharing is an empty mapping"), ({"agent_0": "full"}, None), ("full", None)],
)
def test_a_mapping_of_schemes_names_at_least_one_agent(critic_sharing: Any, refusal: str | None) -> None:
    """An empty mapping is refused before any env is known; a mapping of one agent passes this early check."""
    check(lambda: validate_critic_sharing(critic_sharing), refusal)


# ---------------------------------------------------------------------------------------------- selection.py


def ring(observations: np.ndarray, layout: AgentLayout) -> np.ndarray:
    """Agent i selects agent i + 1."""
    return np.broadcast_to(
        (np.arange(layout.n_agents)[:, None] + 1) % layout.n_agents, (observations.shape[0], layout.n_agents, 1)
    )


@pytest.mark.parametrize(
    "make", [NearestAgents, lambda k: CallableSelector(ring, k=k)], ids=["NearestAgents", "CallableSelector"]
)
@pytest.mark.parametrize(
    ("k", "refusal"), [(3, None), (4, re.escape("k=4 other agents, but the team has only 3 other agents per agent"))]
)
def test_a_selector_selects_at_most_the_other_agents(make: Callable[[int], Selector], k: int, refusal: str | None) -> None:
    """k up to n - 1 in a team of 4."""
    check(lambda: make(k).validate(team(4)), refusal)


def does_not_fit(position_slice: slice, agent: str = "a", size: int = 6) -> str:
    return re.escape(f"position_slice={position_slice} does not fit agent {agent!r}'s observation of size {size}")


@pytest.mark.parametrize(
    ("position_slice", "refusal"),
    [
        (slice(4, 6), None),  # ends exactly at the observation's end
        (slice(5, 7), does_not_fit(slice(5, 7))),  # one past it
        (slice(5, 6), None),  # the last component alone (a position on a line)
        (slice(6, None), does_not_fit(slice(6, None))),  # starts at the end: empty
        (slice(4, None), None),
        (slice(-2, None), None),
        (slice(3, 3), does_not_fit(slice(3, 3))),  # empty
    ],
)
def test_nearest_agents_position_slice_fits_the_observation(position_slice: slice, refusal: str | None) -> None:
    """A non-empty slice within each agent's observation (of 6 here)."""
    check(lambda: NearestAgents(k=1, position_slice=position_slice).validate(team(4)), refusal)


def test_nearest_agents_position_slice_fits_every_agent() -> None:
    """On agents of unequal observations the slice must fit the smallest: the message names that agent."""
    layout = AgentLayout(("big", "small"), (8, 6), (2, 2))
    NearestAgents(k=1, position_slice=slice(4, 6)).validate(layout)
    with pytest.raises(ValueError, match=does_not_fit(slice(5, 7), "small")):
        NearestAgents(k=1, position_slice=slice(5, 7)).validate(layout)
    # Open-ended, it fits both but cuts positions of 4 and 2 values: refused before select() fails in numpy.
    with pytest.raises(ValueError, match=r"cuts positions of different lengths \[2, 4\]"):
        NearestAgents(k=1, position_slice=slice(4, None)).validate(layout)
    NearestAgents(k=1, position_slice=slice(4, None)).validate(AgentLayout(("a", "b"), (6, 6), (2, 2)))  # equal: fine


@pytest.mark.parametrize(
    ("neighbors", "refusal"),
    [([[1], [0], [3], [2]], None), ([[], [], [], []], "one list of k >= 1 neighbour indices per agent")],
)
def test_fixed_graph_needs_at_least_one_neighbour(neighbors: list[list[int]], refusal: str | None) -> None:
    """One neighbour each is the smallest graph; none is refused (not as a k of 0)."""
    check(lambda: FixedGraph(neighbors), refusal)


@pytest.mark.parametrize(
    ("roles", "refusal"),
    [
        (["x", "x", "y", "y"], None),  # two agents per role
        (["x", "y", "z", "w"], re.escape("from_roles needs every role shared by the same number (>= 2) of agents")),
    ],
)
def test_roles_are_shared_by_at_least_two_agents(roles: list[str], refusal: str | None) -> None:
    """A role of one agent leaves it no one to select."""
    check(lambda: FixedGraph.from_roles(roles), refusal)


@pytest.mark.parametrize(
    ("agent", "chosen", "refusal"),
    [
        (1, 0, None),  # the lowest index
        (1, -1, "selected agent index -1, out of range for 4 agents"),
        (0, 3, None),  # the highest
        (0, 4, "selected agent index 4, out of range for 4 agents"),
    ],
)
def test_a_selection_holds_agent_indices_of_the_team(agent: int, chosen: int, refusal: str | None) -> None:
    """A user's selection may name agents 0 to n - 1 only."""
    selection = np.array([[[1], [0], [3], [2]]])
    selection[0, agent, 0] = chosen
    selector = CallableSelector(lambda observations, layout: selection, k=1)
    check(lambda: selector.select(np.zeros((1, 24)), team(4)), refusal)


@pytest.mark.parametrize(
    ("selector", "refusal"),
    [
        (None, None),
        (1, None),
        (True, "selector must be a sb3_maddpg.common.selection.Selector, an int k"),
        (1.0, "an int k"),
    ],
)
def test_a_selector_is_a_selector_or_an_int(selector: Any, refusal: str | None) -> None:
    """An int k is NearestAgents(k); a bool is not taken for one."""
    check(lambda: resolve_selector(selector), refusal, TypeError)


@pytest.mark.parametrize(
    ("selector", "refusal"),
    [
        ({"k": 2, "target": "next"}, None),
        ({"k": 1}, None),
        ({"k": 2, "radius": 1.0}, r"unknown key\(s\) \['radius'\]"),
        ({"k": 2, "target": "later"}, "target='later' is not a target selection: use 'stored'"),
        ({"k": 2.5}, "'k' must be an int"),
        ({"k": True}, "'k' must be an int"),
    ],
)
def test_a_dict_selector_gives_nearest_agents_k_and_target(selector: dict[str, Any], refusal: str | None) -> None:
    """As a JSON experiment file gives a selector: NearestAgents's arguments, anything else named."""
    check(lambda: resolve_selector(selector), refusal, ValueError)


# ---------------------------------------------------------------------------------------------- noise.py


class ShapedNoise(ActionNoise):
    """Zeros of a given shape."""

    def __init__(self, shape: tuple[int, ...]) -> None:
        super().__init__()
        self.shape = shape

    def __call__(self) -> np.ndarray:
        return np.zeros(self.shape)


@pytest.mark.parametrize(
    ("shape", "refusal"),
    [
        ((6,), None),  # one draw for every env
        ((5,), r"noise of shape \(5,\), but the joint actions have shape \(2, 6\)"),
        ((7,), r"noise of shape \(7,\)"),
        ((2, 6), None),  # one draw per env
        ((1, 6), r"noise of shape \(1, 6\)"),
        ((3, 6), r"noise of shape \(3, 6\), but the joint actions have shape \(2, 6\) \(2 env\(s\)"),
    ],
)
def test_noise_fits_the_joint_actions(shape: tuple[int, ...], refusal: str | None) -> None:
    """Noise over the joint action, once or once per env (2 envs, 6 action components here)."""
    check(lambda: draw_noise(ShapedNoise(shape), (2, 6)), refusal)
