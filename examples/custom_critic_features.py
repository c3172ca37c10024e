"""A custom critic features extractor: your own answer to "what does critic i see?".

``DistanceMaskedCriticFeatures`` lets critic i see every agent's observation, but the actions of only
the agents within ``radius`` of agent i (the others' action slots are zeros). It is a middle ground
between sharing observations only (MADDPG-fo) and sharing everything (MADDPG), chosen from the
current state instead of from a selection stored in the buffer.

    python examples/custom_critic_features.py          # 3 agents, 300k steps
    python examples/custom_critic_features.py --fast   # seconds: checks that everything runs (CI)

``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``.
"""

import argparse
import os
import tempfile
from pathlib import Path

import torch as th

from sb3_maddpg import MADDPG, AgentLayout
from sb3_maddpg.envs import make_simple_spread
from sb3_maddpg.evaluation import evaluate_team
from sb3_maddpg.sharing import CriticFeaturesExtractor


class DistanceMaskedCriticFeatures(CriticFeaturesExtractor):
    """
    Critic i sees ``[o_i, o_others..., a_i, m_j * a_j for the others]`` where ``m_j = 1`` when agent j is
    within ``radius`` of agent i, else 0. Others are in ascending index, as in the built-in schemes.

    :param layout: The team's agent layout (agents of equal sizes: positions are read at the same place).
    :param agent_index: Whose critic this extractor feeds.
    :param selection_size: Unused (this extractor needs no stored selection).
    :param radius: Distance within which another agent's action is seen.
    :param position_slice: Where an agent's position lies in its own observation (MPE: 2:4).
    """

    def __init__(
        self,
        layout: AgentLayout,
        agent_index: int,
        selection_size: int = 0,
        radius: float = 0.5,
        position_slice: slice = slice(2, 4),
    ) -> None:
        if not layout.is_homogeneous:
            raise ValueError("DistanceMaskedCriticFeatures needs agents of equal observation and action sizes.")
        super().__init__(layout, agent_index, features_dim=layout.obs_dim + layout.action_dim, selection_size=selection_size)
        self.radius = radius
        self.position_slice = position_slice
        self.order = [agent_index] + [j for j in range(layout.n_agents) if j != agent_index]

    def forward(self, observations: th.Tensor, actions: th.Tensor, selection: th.Tensor | None = None) -> th.Tensor:
        own_position = self.agent_observation(observations, self.agent_index)[:, self.position_slice]
        seen_obs = [self.agent_observation(observations, j) for j in self.order]
        seen_actions = [self.agent_action(actions, self.agent_index)]
        for j in self.order[1:]:
            position = self.agent_observation(observations, j)[:, self.position_slice]
            near = (th.linalg.vector_norm(position - own_position, dim=1, keepdim=True) < self.radius).to(actions.dtype)
            # A multiplication, not an indexing trick: gradients still flow through a_i (the actor learns through it).
            seen_actions.append(near * self.agent_action(actions, j))
        return th.cat(seen_obs + seen_actions, dim=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    parser.add_argument("--steps", type=int, default=300_000)
    args = parser.parse_args()

    eval_episodes, overrides = 100, {}
    if args.fast:
        args.steps, eval_episodes = 400, 3
        overrides = {"learning_starts": 200, "batch_size": 32, "train_freq": 50, "buffer_size": 5_000}

    env = make_simple_spread(n_agents=3)
    # Pass the class as critic_sharing and its own arguments as critic_sharing_kwargs.
    model = MADDPG(
        "MlpPolicy",
        env,
        critic_sharing=DistanceMaskedCriticFeatures,
        critic_sharing_kwargs={"radius": 0.5},
        seed=0,
        **overrides,
    )
    extractor = model.policy.critics[0].features_extractor
    print(f"critic 0: {type(extractor).__name__}, input of {extractor.features_dim} numbers")

    # Check that the actor of agent 0 can learn through its critic: d Q_0 / d a_0 must not be zero.
    obs = th.as_tensor(env.reset(seed=0)[0]).unsqueeze(0)
    actions = th.zeros(1, env.agent_layout.action_dim, requires_grad=True)
    model.policy.critics[0](obs, actions).sum().backward()
    own = env.agent_layout.action_slices[0]
    assert actions.grad is not None and actions.grad[0, own].abs().sum() > 0, "the critic must pass gradients to a_0"

    model.learn(total_timesteps=args.steps)
    result = evaluate_team(model, make_simple_spread(n_agents=3), n_episodes=eval_episodes, seed=10_000)
    print(f"success {100 * result['success_rate']:.1f}%, coverage {100 * result['coverage']:.1f}%")

    # The extractor class is saved with the model (pickled), so loading needs nothing else.
    path = Path(tempfile.mkdtemp()) / "maddpg_custom_features"
    model.save(path)
    loaded = MADDPG.load(path)
    print("loaded; critic 0's extractor is", type(loaded.policy.critics[0].features_extractor).__name__)


if __name__ == "__main__":
    main()
