"""Which modules one ``learn`` runs code of: the package's and SB3's (issue 44's readability measure).

    python benchmarks/modules_touched.py [--algo maddpg|matd3] [--sharing selected]

Builds ``MADDPG("MlpPolicy", make_simple_spread(n_agents=3), critic_sharing=...)`` with small settings, then records,
with ``sys.setprofile``, every Python function called during ``learn`` past ``learning_starts`` (collection and
gradient steps), and prints the modules they belong to: the count a reader following one ``learn`` has to open.
"""

import argparse
import sys
from collections import defaultdict
from types import FrameType
from typing import Any

import stable_baselines3

import sb3_maddpg
from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import make_simple_spread

ROOTS = {"sb3_maddpg": sb3_maddpg.__path__[0], "stable_baselines3": stable_baselines3.__path__[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algo", choices=("maddpg", "matd3"), default="maddpg")
    parser.add_argument("--sharing", default="selected")
    args = parser.parse_args()
    algorithm = MATD3 if args.algo == "matd3" else MADDPG
    model = algorithm(
        "MlpPolicy",
        make_simple_spread(n_agents=3),
        critic_sharing=args.sharing,
        selector=1 if args.sharing == "selected" else None,
        learning_starts=100,
        batch_size=32,
        buffer_size=1_000,
        transitions_per_update=10,
        policy_kwargs={"net_arch": [8]},
        seed=0,
    )
    model.learn(100)  # past learning_starts: what follows collects and trains
    touched: dict[str, set[str]] = defaultdict(set)

    def profile(frame: FrameType, event: str, _: Any) -> None:
        if event != "call":
            return
        path = frame.f_code.co_filename
        for package, root in ROOTS.items():
            if path.startswith(root):
                touched[package].add(path[len(root) + 1 :])

    sys.setprofile(profile)
    try:
        model.learn(200, reset_num_timesteps=False)
    finally:
        sys.setprofile(None)
    assert model._n_updates > 0
    for package, files in touched.items():
        print(f"{package}: {len(files)} modules")
        for name in sorted(files):
            print(f"  {name}")


if __name__ == "__main__":
    main()
