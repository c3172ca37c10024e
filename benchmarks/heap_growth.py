"""A training process's memory beyond its replay buffer, with and without releasing freed heap memory
(:mod:`sb3_maddpg.common.memory_release`), each in a process of its own.

Trains the ``multiwalker`` preset's ``full`` run (needs the sisl extra) for ``--steps`` env steps, its first 2,000
random, and reads the process's resident memory (``/proc``: Linux) every 2,000 steps; the growth from step 4,000 on
is training's, the replay buffer's rows (0.8 KB per env step) included. The same run once with ``malloc_trim`` every
40 gradient steps (the package's default) and once without it (the release switched off), interleaved. Expected:
with the release, at most about the buffer's rows; without it, several times that.

    python benchmarks/heap_growth.py --steps 14000
"""

import argparse
import dataclasses
import os
import subprocess
import sys
import time

RESULT = "growth"


def resident_mb() -> float:
    """:return: This process's resident memory, MB."""
    with open(f"/proc/{os.getpid()}/statm") as file:
        return int(file.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def train(steps: int, release: bool) -> None:
    """Train in this process and print its memory growth per env step from step 4,000 on."""
    from stable_baselines3.common.callbacks import BaseCallback

    from sb3_maddpg.common import memory_release
    from sb3_maddpg.experiments.presets import package_presets
    from sb3_maddpg.experiments.runner import build_model
    from sb3_maddpg.experiments.tasks import run_task

    if not release:
        memory_release.MALLOC_TRIM = None
    config = package_presets()["multiwalker"].replace(seeds=(0,), schemes=("full",)).runs()[0]
    config = dataclasses.replace(config, model_kwargs={**config.model_kwargs, "learning_starts": 2_000})
    model = build_model(run_task(config), device="cpu")
    readings: dict[int, float] = {}

    class Reader(BaseCallback):
        def _on_step(self) -> bool:
            mark = self.num_timesteps // 2_000 * 2_000
            if mark >= 4_000 and mark not in readings:
                readings[mark] = resident_mb()
            return True

    started = time.perf_counter()
    model.learn(steps, callback=Reader())
    seconds = time.perf_counter() - started
    first, last = min(readings), max(readings)
    per_step_kb = (readings[last] - readings[first]) * 1024 / (last - first)
    print(f"{RESULT} {per_step_kb:.2f} {readings[last] - readings[first]:.1f} {last - first} {seconds:.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=14_000, help="env steps per run (at least 8,000)")
    parser.add_argument("--repeats", type=int, default=1, help="runs of each, interleaved")
    parser.add_argument("--child", choices=["release", "keep"], help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        train(args.steps, args.child == "release")
        return
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy"}
    for _ in range(args.repeats):
        for mode in ("release", "keep"):
            command = [sys.executable, __file__, "--steps", str(args.steps), "--child", mode]
            output = subprocess.run(command, capture_output=True, text=True, env=env, check=True).stdout
            _, per_step, grown, steps, seconds = next(line for line in output.splitlines() if line.startswith(RESULT)).split()
            print(f"{mode:>7}: +{grown} MB over {steps} env steps of training ({per_step} KB per step), {seconds} s")


if __name__ == "__main__":
    main()
