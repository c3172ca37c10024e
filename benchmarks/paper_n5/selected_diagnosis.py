"""
Why does ``selected`` trail at N=5? Train the sweep's ``selected`` run of one seed with another selection and compare.

The sweep's ``selected`` runs (exp1: each agent's critic sees its two nearest agents, chosen when a transition is
stored and kept for its target) were the worst of the five schemes on seeds 0 and 1, and seed 1 went astray between
100k and 200k steps with a critic loss three times the others'. This trains the same run (same config, seed and
shared networks) with the selection given here, for a shorter budget, and writes its ``progress.csv`` (critic loss,
rollout return) and a final evaluation, to set beside the sweep's run at the same steps:

- ``nearest``: the sweep's own selection (the two nearest agents, stored with the transition);
- ``ring``: a fixed graph, agent i selects agents i+1 and i+2 (mod N): the same input size and network, but the
  selection never changes, so the critic's slots always hold the same agents and the target's input is never one
  the critic is not trained on;
- ``nearest-next``: the two nearest agents, but the target's selected again from the next observation
  (``NearestAgents(2, target="next")``), so that its input is laid out as the critic's inputs are.

If ``ring`` learns where ``nearest`` goes astray, the selection's changes are the cause, not the selected critic's
input path (which ``ring`` shares); if ``nearest-next`` learns too, the cause is the target's stored selection.

    python benchmarks/paper_n5/selected_diagnosis.py --selection ring --seed 1 --steps 300000 \
        --out benchmarks/paper_n5/diagnosis
"""

import argparse
import dataclasses
import json
import time
from pathlib import Path

from stable_baselines3.common.logger import configure

from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.common.selection import FixedGraph, NearestAgents, Selector
from sb3_maddpg.common.torch_threads import use_torch_threads
from sb3_maddpg.experiments.config import load_experiment
from sb3_maddpg.experiments.runner import build_model, log_interval
from sb3_maddpg.experiments.tasks import run_task

HERE = Path(__file__).resolve().parent


def selector_for(name: str, n_agents: int, k: int = 2) -> Selector:
    """
    :param name: ``nearest``, ``nearest-next`` or ``ring``.
    :param n_agents: The team's size.
    :param k: Agents selected per agent.
    :return: The selection rule.
    """
    if name == "nearest":
        return NearestAgents(k)
    if name == "nearest-next":
        return NearestAgents(k, target="next")
    if name == "ring":
        return FixedGraph([[(i + step) % n_agents for step in range(1, k + 1)] for i in range(n_agents)])
    raise ValueError(f"Unknown selection {name!r}: use 'nearest', 'nearest-next' or 'ring'.")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--experiment", default=str(HERE / "exp1.json"), help="the sweep's experiment file")
    parser.add_argument("--selection", choices=("nearest", "nearest-next", "ring"), required=True)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--steps", type=int, default=300_000, help="env steps to train")
    parser.add_argument("--eval-episodes", type=int, default=100)
    parser.add_argument("--out", type=Path, default=HERE / "diagnosis")
    args = parser.parse_args()
    use_torch_threads(1)

    experiment = load_experiment(args.experiment)
    (config,) = [run for run in experiment.runs() if run.scheme == "selected" and run.seed == args.seed] or [None]
    if config is None:
        raise SystemExit(f"{args.experiment} has no selected run of seed {args.seed}: pick one of {list(experiment.seeds)}.")
    # The sweep's selector (an int k) is replaced by the rule asked for; everything else is the sweep's run.
    model_kwargs = {key: value for key, value in config.model_kwargs.items() if key != "selector"}
    config = dataclasses.replace(config, model_kwargs=model_kwargs)
    directory = args.out / f"{config.experiment}_selected_{args.selection}_seed_{args.seed:03d}"
    directory.mkdir(parents=True, exist_ok=True)
    model = build_model(run_task(config), selector=selector_for(args.selection, config.n_agents))
    model.set_logger(configure(str(directory), ["csv"]))
    started = time.perf_counter()
    model.learn(args.steps, log_interval=log_interval(config), progress_bar=False)
    train_time = time.perf_counter() - started
    env = run_task(config).make_eval_env(args.eval_episodes)
    result = evaluate_team(
        model, env, n_episodes=args.eval_episodes, seed=config.eval_seed, task_metrics=run_task(config).metrics
    )
    summary = {
        "experiment": config.experiment,
        "selection": args.selection,
        "seed": args.seed,
        "steps": args.steps,
        "train_time_s": round(train_time, 1),
        "eval_episodes": args.eval_episodes,
        "min_dist_sum": result["min_dist_sum"],
        "success_rate_r0.3": result["success_rate_r0.3"],
        "return_mean": result["return_mean"],
    }
    (directory / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
