"""A custom critic features extractor: your own answer to "what does critic i see?".

``DistanceMaskedCriticFeatures`` lets critic i see every agent's observation, but the actions of only
the agents within ``radius`` of agent i (the others' action slots are zeros). It is a middle ground
between sharing observations only (MADDPG-fo) and sharing everything (MADDPG), chosen from the
current state instead of from a selection stored in the buffer.

    python examples/custom_critic_features.py          # 3 agents, 1M steps on 100 batched worlds
    python examples/custom_critic_features.py --fast   # seconds: checks that everything runs (CI)
    python examples/custom_critic_features.py --mpe2   # step mpe2 itself: the same MDP, several times slower

``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``.
"""

import argparse
import os
import tempfile
from pathlib import Path

import torch as th
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg import MADDPG, AgentLayout
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.common.progress import ctrl_c_ends_quietly
from sb3_maddpg.common.torch_threads import add_threads_argument, use_torch_threads
from sb3_maddpg.envs import make_simple_spread_vec_env
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

    def forward(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        own_position = self.agent_observation(observations, self.agent_index)[:, self.position_slice]
        seen_obs = [self.agent_observation(observations, j) for j in self.order]
        seen_actions = [self.agent_action(actions, self.agent_index)]
        for j in self.order[1:]:
            position = self.agent_observation(observations, j)[:, self.position_slice]
            near = (th.linalg.vector_norm(position - own_position, dim=1, keepdim=True) < self.radius).to(actions.dtype)
            # A multiplication, not an indexing trick: gradients still flow through a_i (the actor learns through it).
            seen_actions.append(near * self.agent_action(actions, j))
        return th.cat(seen_obs + seen_actions, dim=1)


def make_env(n_envs: int, n_agents: int, mpe2: bool) -> VecEnv:
    """``n_envs`` simple_spread worlds: batched arrays, or mpe2 itself behind the adapter."""
    return make_simple_spread_vec_env(n_envs, "mpe2" if mpe2 else "batched", n_agents=n_agents)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    parser.add_argument("--steps", type=int, default=1_000_000, help="training steps (all worlds counted)")
    parser.add_argument("--n-envs", type=int, default=100, help="worlds stepped together in training")
    parser.add_argument("--mpe2", action="store_true", help="step mpe2 itself instead of the batched env")
    add_threads_argument(parser)
    args = parser.parse_args()
    use_torch_threads(args.threads)

    eval_episodes, overrides = 100, {}
    if args.fast:
        args.steps, eval_episodes, args.n_envs = 400, 3, 4
        overrides = {"learning_starts": 200, "batch_size": 32, "transitions_per_update": 50, "buffer_size": 5_000}

    env = make_env(args.n_envs, 3, args.mpe2)
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
    layout = model.agent_layout
    env.seed(0)
    obs = th.as_tensor(env.reset()[:1], device=model.device)  # world 0's joint observation, a batch of one
    actions = th.zeros(1, layout.action_dim, device=model.device, requires_grad=True)
    model.policy.critics[0](obs, actions).sum().backward()
    own = layout.action_slices[0]
    assert actions.grad is not None and actions.grad[0, own].abs().sum() > 0, "the critic must pass gradients to a_0"

    with ctrl_c_ends_quietly(model):
        model.learn(total_timesteps=args.steps)
    # One world per evaluation episode: they run side by side (mpe2: one env, episode after episode).
    eval_env = make_env(1 if args.mpe2 else eval_episodes, 3, args.mpe2)
    result = evaluate_team(model, eval_env, n_episodes=eval_episodes, seed=10_000)
    print(f"success {100 * result['success_rate']:.1f}%, coverage {100 * result['coverage']:.1f}%")

    # The extractor class is saved with the model (pickled), so loading needs nothing else.
    path = Path(tempfile.mkdtemp()) / "maddpg_custom_features"
    model.save(path)
    loaded = MADDPG.load(path)
    print("loaded; critic 0's extractor is", type(loaded.policy.critics[0].features_extractor).__name__)


if __name__ == "__main__":
    with ctrl_c_ends_quietly():  # Ctrl-C: one line, no traceback
        main()
