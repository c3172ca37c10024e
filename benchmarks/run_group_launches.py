"""
Issue 32's measurement: what a run group would launch on a GPU, counted on a CPU.

For each R: R MADDPG runs at N=5 (100 simple_spread worlds each, the paper's networks and batch, past
``learning_starts``) in one :class:`~sb3_maddpg.run_group.RunGroup` on the ``meta`` device, where every op runs and
nothing is computed; :class:`~sb3_maddpg.run_group.audit.DeviceAudit` counts the kernels one env step and one update
launch (views excluded, the optimiser's multi-tensor step as on CUDA), and the host syncs, host-device transfers and
float64 ops among them (the target: none). A round at the paper's ratio is one env step of 100 worlds (100
transitions) and one update. Prints a markdown table.

    python benchmarks/run_group_launches.py --runs 1 10 31 155
"""

import argparse

import torch as th

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.run_group import RunGroup
from sb3_maddpg.run_group.audit import DeviceAudit

ALGORITHMS: dict[str, type[MADDPG]] = {"maddpg": MADDPG, "matd3": MATD3}


def meta_group(n_runs: int, algorithm: type[MADDPG], scheme: str, n_agents: int, worlds: int) -> RunGroup:
    """:return: A group of ``n_runs`` runs on the meta device, past ``learning_starts``."""
    env = SimpleSpreadVecEnv(worlds, n_agents=n_agents)
    models = [
        algorithm("MlpPolicy", env, critic_sharing=scheme, learning_starts=worlds, buffer_size=100 * worlds, seed=seed)
        for seed in range(n_runs)
    ]
    group = RunGroup(models, device="meta")
    with DeviceAudit():  # the meta device standing for a GPU (its Adam step is the GPU's); these counts are not read
        return group.learn(2 * worlds)


def count(n_runs: int, algorithm: type[MADDPG], scheme: str, n_agents: int, worlds: int) -> tuple[DeviceAudit, DeviceAudit]:
    """:return: The audits of one env step and of one update (MATD3: one with the actors, the second of two)."""
    group = meta_group(n_runs, algorithm, scheme, n_agents, worlds)
    with DeviceAudit() as step:
        group.collect_step()
    with DeviceAudit():  # MATD3 updates its actors at every second update: audit that one (this one's not read)
        group.train(1)
    with DeviceAudit() as update:
        group.train(1)
    return step, update


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, nargs="+", default=[1, 10, 31, 155])
    parser.add_argument("--algo", choices=sorted(ALGORITHMS), default="maddpg")
    parser.add_argument("--scheme", default="full")
    parser.add_argument("--n-agents", type=int, default=5)
    parser.add_argument("--worlds", type=int, default=100, help="simple_spread worlds per run")
    args = parser.parse_args()
    th.set_num_threads(1)
    algorithm = ALGORITHMS[args.algo]
    print(f"{algorithm.__name__}, critic_sharing={args.scheme!r}, N={args.n_agents}, {args.worlds} worlds per run")
    print("| R | launches per env step | per update | syncs, transfers, float64 ops |")
    print("|---|---|---|---|")
    for n_runs in args.runs:
        step, update = count(n_runs, algorithm, args.scheme, args.n_agents, args.worlds)
        problems = len(step.problems()) + len(update.problems())
        print(f"| {n_runs} | {step.n_launches} | {update.n_launches} | {problems} |", flush=True)


if __name__ == "__main__":
    main()
