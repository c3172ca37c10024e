"""
Give the N=5 tuning study's trials that were pruned before its warm-up ended another run (once each): until
2026-12-02 the default pruner could stop a trial at its first evaluation (50k steps, about 1,000 gradient steps, where
every sample still scores near the random warm-up; an off-by-one in its warm-up), and the study spared only that one;
``run.sh`` now prunes no trial before its 4th evaluation (200k steps). Those samples were never judged: each is
enqueued again with its parameters unless a later trial already ran or waits with them. Usage::

    python benchmarks/n5_tuning/requeue_early_pruned.py [storage]
"""

import sys

import optuna
from enqueue_baseline import STUDY

WARMUP_END = 150_000
"""The env step of the last evaluation at which ``run.sh``'s study prunes no trial (its 3rd of 8 over 400k steps)."""


def requeue(storage: str) -> list[int]:
    """
    :param storage: The study's storage URL.
    :return: The numbers of the trials pruned by the warm-up's end whose parameters were enqueued again.
    """
    study = optuna.load_study(study_name=STUDY, storage=storage)
    trials = study.get_trials(deepcopy=False)
    requeued = []
    for trial in trials:
        pruned_early = trial.state == optuna.trial.TrialState.PRUNED and max(trial.intermediate_values) <= WARMUP_END
        if not pruned_early:
            continue
        again = [
            later
            for later in trials
            if later.number > trial.number and later.params == trial.params and later.state != optuna.trial.TrialState.FAIL
        ]
        waiting = [later for later in trials if later.state == optuna.trial.TrialState.WAITING]
        if again or any(trial.params.items() <= later.system_attrs.get("fixed_params", {}).items() for later in waiting):
            continue
        study.enqueue_trial(trial.params, skip_if_exists=False)
        requeued.append(trial.number)
    return requeued


if __name__ == "__main__":
    url = sys.argv[1] if len(sys.argv) > 1 else "sqlite:///benchmarks/n5_tuning/results/tune.db"
    print(f"enqueued again the samples of trials pruned before the warm-up's end: {requeue(url)}")
