"""The entry points' torch threads (one unless the user asked), progress lines over a recent window, and Ctrl-C
ending in one line with exit status 130."""

import contextlib
import io
import os
import signal
import subprocess
import sys
import time
from collections import deque
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.callbacks import BaseCallback

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.common.progress import INTERRUPTED_EXIT_CODE, ProgressLogCallback, ctrl_c_ends_quietly, interrupted_line
from sb3_maddpg.common.torch_threads import THREAD_VARIABLES, threads_set_by_user, use_torch_threads
from sb3_maddpg.envs import MPE_TASK_SIDES, make_mpe_env, make_simple_spread
from tests.settings import FILLS_THE_BUFFER_ONLY

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def restore_threads(monkeypatch: pytest.MonkeyPatch):
    for variable in THREAD_VARIABLES:
        monkeypatch.delenv(variable, raising=False)
    before = th.get_num_threads()
    use_torch_threads(before)  # the package's record starts from the count in force
    yield
    th.set_num_threads(before)
    use_torch_threads(before)


def test_one_thread_by_default(restore_threads) -> None:
    th.set_num_threads(2)
    use_torch_threads(2)  # as if torch had started with 2
    assert use_torch_threads() == 1
    assert th.get_num_threads() == 1


def test_an_explicit_count_wins(restore_threads) -> None:
    assert use_torch_threads(2) == 2
    assert th.get_num_threads() == 2


@pytest.mark.parametrize("variable", THREAD_VARIABLES)
def test_thread_variables_are_honoured(restore_threads, monkeypatch: pytest.MonkeyPatch, variable: str) -> None:
    th.set_num_threads(2)
    use_torch_threads(2)
    monkeypatch.setenv(variable, "2")
    assert threads_set_by_user() == f"{variable}=2"
    assert use_torch_threads() == 2  # left as torch set it from the variable


def test_a_users_set_num_threads_is_honoured(restore_threads) -> None:
    use_torch_threads(1)
    th.set_num_threads(2)  # the user's call, after the package's
    assert threads_set_by_user() == "torch.set_num_threads(2)"
    assert use_torch_threads() == 2


class ThreadsSeen(BaseCallback):
    """Records torch's thread count at every step of learn()."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: set[int] = set()

    def _on_step(self) -> bool:
        self.seen.add(th.get_num_threads())
        return True


def tiny_model() -> MADDPG:
    return MADDPG(
        "MlpPolicy", make_simple_spread(n_agents=2), learning_starts=20, batch_size=8, policy_kwargs={"net_arch": [8]}
    )


@FILLS_THE_BUFFER_ONLY
def test_learn_and_evaluate_run_on_one_thread_and_give_the_callers_back(restore_threads) -> None:
    """What makes every snippet fast without a line of its own: learn() and evaluate_team set one thread for their
    work and restore the count torch had (here 2, as if torch had started with it)."""
    th.set_num_threads(2)
    use_torch_threads(2)
    model, seen = tiny_model(), ThreadsSeen()
    model.learn(50, callback=seen)
    assert seen.seen == {1} and th.get_num_threads() == 2
    counts: list[int] = []
    predict = model.predict
    model.predict = lambda *args, **kwargs: (counts.append(th.get_num_threads()), predict(*args, **kwargs))[1]  # type: ignore[method-assign]
    evaluate_team(model, make_simple_spread(n_agents=2), n_episodes=1)
    assert set(counts) == {1} and th.get_num_threads() == 2


@FILLS_THE_BUFFER_ONLY
def test_learn_keeps_the_users_thread_count(restore_threads, monkeypatch: pytest.MonkeyPatch) -> None:
    use_torch_threads(1)
    th.set_num_threads(2)  # the user's call, after importing sb3_maddpg
    seen = ThreadsSeen()
    tiny_model().learn(50, callback=seen)
    assert seen.seen == {2}
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    use_torch_threads(2)
    seen = ThreadsSeen()
    tiny_model().learn(50, callback=seen)
    assert seen.seen == {2}


@pytest.mark.parametrize("threads", [0, -1, 1.5, True])
def test_bad_thread_counts_say_what_to_do(threads) -> None:
    with pytest.raises(ValueError, match=r"threads must be a positive integer.*use 1"):
        use_torch_threads(threads)


class _Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_progress_rate_is_over_the_recent_window(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    clock = _Clock()
    monkeypatch.setattr("sb3_maddpg.common.progress.time.perf_counter", clock)
    progress = ProgressLogCallback("run", total_timesteps=1_000_000, every=1.0, every_seconds=10.0, window_seconds=30.0)
    progress.model, progress.num_timesteps = None, 0  # no model: no team return in the lines
    progress._on_training_start()
    # 60 s at 1,000 steps/s, then the machine gets busy: 100 steps/s.
    for second in range(1, 121):
        clock.now = float(second)
        progress.num_timesteps += 1_000 if second <= 60 else 100
        progress._on_step()
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 12
    assert "1,000 steps/s" in lines[5]  # at 60 s
    # 60 s into the slow phase the window holds only slow steps: 100 steps/s, where the average since the start
    # (66,000 steps in 120 s) would say 550.
    assert "100 steps/s (last 0m30s)" in lines[-1], lines[-1]
    assert "2h35m40s left" in lines[-1]  # at the recent rate: 934,000 steps at 100 steps/s


TAG_IDS = ["adversary_0", "adversary_1", "agent_0"]
TAG_EPISODES = [  # the env's return sums every agent's: the adversaries' catches and the prey's penalty cancel out
    {"r": 0.0, "l": 25, "agent_returns": [10.0, 20.0, -30.0]},
    {"r": 0.0, "l": 25, "agent_returns": [30.0, 40.0, -70.0]},
]


def _line(progress: ProgressLogCallback, episodes: list[dict], agent_ids: list[str] | None = None) -> str:
    """The progress line of a model whose recent episodes are ``episodes``."""
    layout = None if agent_ids is None else SimpleNamespace(agent_ids=agent_ids)
    progress.model = SimpleNamespace(num_timesteps=0, ep_info_buffer=deque(episodes), agent_layout=layout)  # type: ignore[assignment]
    progress.num_timesteps = 0
    progress._on_training_start()
    progress.num_timesteps = progress.total_timesteps
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        progress._on_step()
    return buffer.getvalue()


def test_a_competitive_task_s_progress_says_each_side_s_return_not_a_team_return() -> None:
    """simple_tag's adversaries and prey are not one team: their summed return (0 here) is no team's. Each side's
    return is the mean over its agents of their episode returns, as evaluate_team scores return_<side>."""
    sides = MPE_TASK_SIDES["simple_tag"]  # by name: adversary -> adversary_0, adversary_1
    line = _line(ProgressLogCallback("tag", 100, every=1.0, sides=sides), TAG_EPISODES, TAG_IDS)
    assert line.rstrip().endswith(", adversaries' return 25.0, good agents' return -50.0 (last 2 episodes)"), line
    assert "team return" not in line
    # Sides by agent id, in any order: the same returns, in the sides' order.
    by_id = {"good agents": ["agent_0"], "adversaries": ["adversary_1", "adversary_0"]}
    line = _line(ProgressLogCallback("tag", 100, every=1.0, sides=by_id), TAG_EPISODES, TAG_IDS)
    assert ", good agents' return -50.0, adversaries' return 25.0 (last 2 episodes)" in line, line
    # Without per-agent returns (a model without an agent layout): the combined return, said to be that.
    line = _line(ProgressLogCallback("tag", 100, every=1.0, sides=sides), [{"r": 4.0, "l": 25}], None)
    assert ", return of all agents combined 4.0 (opponents included; last 1 episodes)" in line, line
    assert "team return" not in line
    # A cooperative task (no sides): the team return, as before.
    line = _line(ProgressLogCallback("spread", 100, every=1.0), [{"r": -12.0, "l": 25}, {"r": -14.0, "l": 25}], TAG_IDS)
    assert line.rstrip().endswith(", team return -13.0 (last 2 episodes)"), line
    # Sides that do not match the team are refused when training starts, not at the first line.
    with pytest.raises(ValueError, match="names no agent of the team"):
        _line(ProgressLogCallback("tag", 100, every=1.0, sides={"wolves": ["wolf"], **sides}), TAG_EPISODES, TAG_IDS)


def test_a_competitive_task_s_training_reports_each_side(capsys: pytest.CaptureFixture) -> None:
    """The same with a model training on simple_tag: its episodes carry the per-agent returns the sides are read from."""

    class Recorded(ProgressLogCallback):
        def log(self, line: str) -> None:
            self.episodes = list(self.model.ep_info_buffer)  # type: ignore[arg-type]  # those the line was made from
            super().log(line)

    env = make_mpe_env("simple_tag", max_cycles=10, num_good=1, num_adversaries=2, num_obstacles=0)
    model = MADDPG("MlpPolicy", env, learning_starts=0, batch_size=8, seed=0)
    progress = Recorded("tag", 100, every=1.0, sides=MPE_TASK_SIDES["simple_tag"])
    model.learn(total_timesteps=100, callback=progress)  # episodes of 10 steps
    (line,) = capsys.readouterr().out.strip().splitlines()
    assert line.startswith("tag: 100/100 steps") and "team return" not in line, line
    returns = np.mean([episode["agent_returns"] for episode in progress.episodes], axis=0)  # adversary_0, _1, agent_0
    expected = f", adversaries' return {returns[:2].mean():.1f}, good agents' return {returns[2]:.1f} "
    assert expected + f"(last {len(progress.episodes)} episodes)" in line, line
    assert len(progress.episodes) >= 9


def test_ctrl_c_in_learn_is_one_line_and_status_130(capsys: pytest.CaptureFixture) -> None:
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=2), learning_starts=0, batch_size=8)

    class CtrlCAt(ProgressLogCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps >= 30:
                raise KeyboardInterrupt
            return True

    with pytest.raises(SystemExit) as stopped, ctrl_c_ends_quietly(model):
        model.learn(total_timesteps=1_000, callback=CtrlCAt("run", 1_000))
    assert stopped.value.code == INTERRUPTED_EXIT_CODE
    out = capsys.readouterr().out
    assert out == "Stopped by Ctrl-C at 30 of 1,000 training steps (3%). " + out.split("(3%). ", 1)[1]
    assert "the model trained so far is usable" in out and out.count("\n") == 1
    model.predict(model.env.reset(), deterministic=True)  # and it is


def test_ctrl_c_outside_training_says_so() -> None:
    assert interrupted_line() == "Stopped by Ctrl-C."


@pytest.mark.slow
def test_the_main_job_ends_on_ctrl_c_with_one_line() -> None:
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "PYTHONUNBUFFERED": "1"}
    env.pop("SB3_MADDPG_FAST", None)
    args = [sys.executable, str(ROOT / "examples" / "train_simple_spread.py"), "--agents", "2", "--n-envs", "8"]
    process = subprocess.Popen(args, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert process.stdout is not None
    deadline = time.monotonic() + 240
    seen = []
    for line in process.stdout:  # the first progress line comes 5 s into training
        seen.append(line)
        if line.startswith("training:") or time.monotonic() > deadline:
            break
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=60)
    assert seen and seen[-1].startswith("training:"), "".join(seen) + err
    assert process.returncode == INTERRUPTED_EXIT_CODE, err
    assert out.strip().splitlines()[-1].startswith("Stopped by Ctrl-C at "), out
    assert "of 2,000,000 training steps" in out
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
