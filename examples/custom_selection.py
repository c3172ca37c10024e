"""A custom agent selection for selected sharing (MADDPG-soa): your own rule for S_i.

The rule here: each agent selects the k agents closest to *its own nearest landmark*, i.e. the
agents most likely to compete with it for that landmark. It is a plain function of the joint
observation, wrapped in ``CallableSelector``; the selection is made when each transition is stored
and kept in the replay buffer with it.

    python examples/custom_selection.py          # 4 agents, 1M steps on 100 batched worlds
    python examples/custom_selection.py --fast   # seconds: checks that everything runs (CI)
    python examples/custom_selection.py --mpe2   # step mpe2 itself: the same MDP, several times slower

``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``.
"""

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg import MADDPG, AgentLayout
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.common.progress import ctrl_c_ends_quietly
from sb3_maddpg.common.selection import CallableSelector, FixedGraph
from sb3_maddpg.common.torch_threads import add_threads_argument, use_torch_threads
from sb3_maddpg.envs import make_simple_spread_vec_env

K = 2


def rivals_for_my_landmark(observations: np.ndarray, layout: AgentLayout) -> np.ndarray:
    """
    For every agent i, the K other agents closest to the landmark nearest to agent i.

    In simple_spread an agent's observation is ``[velocity (2), position (2), landmark offsets (2 per
    landmark), ...]``; landmark offsets are relative to the agent.

    :param observations: Joint observations ``[n_envs, obs_dim]``.
    :param layout: The team's layout (which slice of the joint observation is whose).
    :return: Selected agents ``[n_envs, n_agents, K]``, never the agent itself.
    """
    n_envs, n_agents = observations.shape[0], layout.n_agents
    own = np.stack([observations[:, sl] for sl in layout.obs_slices], axis=1)  # [n_envs, n_agents, obs_size]
    positions = own[:, :, 2:4]
    offsets = own[:, :, 4 : 4 + 2 * n_agents].reshape(n_envs, n_agents, n_agents, 2)  # [env, agent, landmark, xy]
    nearest = np.linalg.norm(offsets, axis=-1).argmin(axis=-1)  # [env, agent]
    target = positions + np.take_along_axis(offsets, nearest[:, :, None, None], axis=2)[:, :, 0]  # landmark position
    # distance from agent i's target landmark to every agent j: [env, i, j]
    distance = np.linalg.norm(target[:, :, None, :] - positions[:, None, :, :], axis=-1)
    distance[:, np.arange(n_agents), np.arange(n_agents)] = np.inf  # never select yourself
    return np.argsort(distance, axis=-1, kind="stable")[:, :, :K]


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

    n_agents, eval_episodes, overrides = 4, 100, {}
    if args.fast:
        args.steps, eval_episodes, args.n_envs = 400, 3, 4
        overrides = {"learning_starts": 200, "batch_size": 32, "transitions_per_update": 50, "buffer_size": 5_000}

    env = make_env(args.n_envs, n_agents, args.mpe2)
    layout = env.get_attr("agent_layout")[0]
    selector = CallableSelector(rivals_for_my_landmark, k=K)

    # What the rule selects at the start of an episode (the library checks shape, range and self-selection).
    env.seed(0)
    obs = env.reset()  # [n_envs, joint observation]
    print("selection at reset in world 0 (row i: the agents critic i sees):\n", selector.select(obs, layout)[0])

    model = MADDPG("MlpPolicy", env, critic_sharing="selected", selector=selector, seed=0, **overrides)
    with ctrl_c_ends_quietly(model):
        model.learn(total_timesteps=args.steps)

    # The stored selections: one [n_agents, k] row per transition, [buffer rows, n_envs, n_agents, k] in all.
    buffer = model.replay_buffer
    print("selections stored with world 0's first two transitions:\n", buffer.selections[:2, 0])

    # One world per evaluation episode: they run side by side (mpe2: one env, episode after episode).
    eval_env = make_env(1 if args.mpe2 else eval_episodes, n_agents, args.mpe2)
    result = evaluate_team(model, eval_env, n_episodes=eval_episodes, seed=10_000)
    print(f"success {100 * result['success_rate']:.1f}%, coverage {100 * result['coverage']:.1f}%")

    # A model with a custom selector saves and loads like any other (the function is pickled with it).
    path = Path(tempfile.mkdtemp()) / "maddpg_custom_selection"
    model.save(path)
    loaded = MADDPG.load(path, env=eval_env)
    print("loaded; its selector is", type(loaded.selector).__name__)

    # The other built-in selectors: a fixed graph, or roles (agents select the others with their role).
    ring = FixedGraph([[(i - 1) % n_agents, (i + 1) % n_agents] for i in range(n_agents)])
    pairs = FixedGraph.from_roles(["red", "red", "blue", "blue"])
    print("ring:", ring.neighbors.tolist(), " roles:", pairs.neighbors.tolist())


if __name__ == "__main__":
    with ctrl_c_ends_quietly():  # Ctrl-C: one line, no traceback
        main()
