"""The run group (sb3_maddpg.run_group): R runs trained together equal R runs trained alone, and never touch each other.

- One update of a group of one equals MADDPG.train's (weights, targets, optimiser state), for every fixed scheme.
- Perturbing one run's batch, weights or seed leaves every other run bit-identical; a huge gradient in one run does not
  shrink another's step (clipping per run and agent).
- A run alone and the same seed inside a group of 8 agree; the group's data follow the numpy env's distribution.
- Weights written back into a model save and load as any MADDPG model's; a group rebuilt from them continues exactly.
- What a group cannot train is refused with the cause first.
"""

import copy
from typing import Any

import numpy as np
import pytest
import torch as th
from scipy import stats
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import VecNormalize

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.selection import FixedGraph, NearestAgents
from sb3_maddpg.common.update_step import clip_per_agent
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.run_group import RunGroup, RunReplayBuffers, RunStreams, SpreadTask
from sb3_maddpg.run_group.buffer import replay_nbytes
from sb3_maddpg.run_group.selection import select_on_device
from tests.settings import RESUMES_WITHOUT_ITS_BUFFER

N_AGENTS = 3
SMALL = {"net_arch": [16, 16]}


def make_model(
    seed: int | None = 0, n_agents: int = N_AGENTS, n_envs: int = 2, algorithm: type[MADDPG] = MADDPG, **kwargs: Any
) -> MADDPG:
    settings: dict[str, Any] = {
        "learning_starts": 100,
        "batch_size": 32,
        "buffer_size": 2_000,
        "policy_kwargs": SMALL,
        "device": "cpu",  # the groups and batches here are on the CPU, also on a machine with a GPU
        **kwargs,
    }
    return algorithm("MlpPolicy", SimpleSpreadVecEnv(n_envs, n_agents=n_agents), seed=seed, **settings)


def random_batch(model: MADDPG, batch_size: int, generator: th.Generator) -> MultiAgentReplayBufferSamples:
    """A batch of one team, ``[batch, ...]`` each field (float32; selections that never select the agent itself)."""
    layout = model.agent_layout
    assert layout is not None
    n = layout.n_agents

    def normal(*shape: int) -> th.Tensor:
        return th.randn(*shape, generator=generator)

    selections = None
    k = model.policy.selection_size
    if k:
        others = th.stack([th.randperm(n - 1, generator=generator) for _ in range(batch_size * n)]).view(batch_size, n, -1)
        own = th.arange(n).view(1, n, 1)
        selections = (others + (others >= own).long())[..., :k]  # others' indices, skipping the agent itself
    dones = (th.rand(batch_size, n, generator=generator) < 0.2).float()
    return MultiAgentReplayBufferSamples(
        normal(batch_size, layout.obs_dim),
        normal(batch_size, layout.action_dim).clamp(-1, 1),
        normal(batch_size, layout.obs_dim),
        dones,
        normal(batch_size, n),
        selections,
    )


def stack_batches(batches: list[MultiAgentReplayBufferSamples]) -> MultiAgentReplayBufferSamples:
    """Runs' batches stacked along the run dimension."""
    fields = [None if field[0] is None else th.stack(field) for field in zip(*batches)]
    return MultiAgentReplayBufferSamples(*fields)  # type: ignore[arg-type]


def run_state(group: RunGroup, run: int) -> list[th.Tensor]:
    """Run ``run``'s weights, targets and optimiser state, in a fixed order."""
    teams = group.teams
    tensors = [
        stacked.params[name][run]
        for stacked in (teams.actor, teams.critic, teams.actor_target, teams.critic_target)
        for name in stacked.names
    ]
    for optimizer in (group.actor_optimizer, group.critic_optimizer):
        tensors += [moment[run] for moment in (*optimizer.exp_avgs, *optimizer.exp_avg_sqs)]
    return [tensor.detach() for tensor in tensors]


def model_state(model: MADDPG) -> dict[str, th.Tensor]:
    """A model's weights, targets and optimiser state, by name."""
    state = {f"policy.{name}": value for name, value in model.policy.state_dict().items()}
    for label, optimizer in (("actor", model.actor.optimizer), ("critic", model.critic.optimizer)):
        for index, entry in optimizer.state_dict()["state"].items():
            for key, value in entry.items():
                state[f"{label}.{index}.{key}"] = th.as_tensor(value)
    return state


# ----- 1. a group of one is MADDPG.train -----


def as_group_of_one(batch: MultiAgentReplayBufferSamples) -> MultiAgentReplayBufferSamples:
    """:return: A team's replay batch with the run dimension of a group of one in front."""
    fields = (None if field is None else field.unsqueeze(0) for field in batch)
    return MultiAgentReplayBufferSamples(*fields)  # type: ignore[arg-type]


def train_alike(
    reference: MADDPG, group: RunGroup, model: MADDPG, steps: int, monkeypatch: pytest.MonkeyPatch
) -> tuple[dict[str, th.Tensor], dict[str, th.Tensor]]:
    """``steps`` updates of ``reference.train`` and of a group of one on the same batches; the group's run is written
    back into ``model``. :return: Both states (:func:`model_state`), the reference's first."""
    generator = th.Generator().manual_seed(1)
    for _ in range(steps):
        batch = random_batch(reference, 32, generator)
        monkeypatch.setattr(reference.replay_buffer, "sample", lambda *args, _batch=batch, **kwargs: _batch)
        reference.train(gradient_steps=1, batch_size=32)
        group.update(as_group_of_one(batch))
    group.write_back(0, model)
    return model_state(reference), model_state(model)


@pytest.mark.parametrize(
    ("scheme", "extra"),
    [
        ("full", {}),
        ("independent", {}),
        ("observations", {}),
        ("actions", {}),
        ("selected", {"selector": 1}),
        ("full", {"policy_kwargs": {**SMALL, "share_parameters": True}}),
        ("full", {"policy_kwargs": {**SMALL, "layer_norm": True}}),
    ],
)
def test_one_update_of_a_group_of_one_equals_maddpg_train(
    scheme: str, extra: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    # A small max_grad_norm, so that the clipping acts; a learning rate that moves the weights visibly.
    settings: dict[str, Any] = {"critic_sharing": scheme, "max_grad_norm": 0.05, "learning_rate": 3e-3, **extra}
    reference, model = make_model(**settings), make_model(**settings)
    reference.set_logger(Logger(folder=None, output_formats=[]))  # train() records its losses
    group = RunGroup([model])
    expected, actual = train_alike(reference, group, model, 3, monkeypatch)  # three: Adam's moments and step count
    assert expected.keys() == actual.keys()
    moved = model.actor.mlp.weights[0] - make_model(**settings).actor.mlp.weights[0]
    assert moved.abs().max() > 1e-3  # the updates did something
    # Layer normalisation leaves some gradient components at rounding-noise size, which Adam's first steps scale up
    # to a good part of the learning rate: there the two orders of float operations differ by ~5e-6 (1e-7 without).
    atol = 1e-5 if settings.get("policy_kwargs", {}).get("layer_norm") else 1e-6
    for name, value in expected.items():
        th.testing.assert_close(actual[name], value, atol=atol, rtol=1e-5, msg=name)
    assert model._n_updates == reference._n_updates == 3


def fixed_noise() -> Any:
    """Standard normal noise, the n-th call's from seed n: what two trainers draw alike."""
    calls = iter(range(1_000))
    return lambda tensor: th.randn(tensor.shape, generator=th.Generator().manual_seed(next(calls)), dtype=tensor.dtype)


@pytest.mark.parametrize(("scheme", "extra"), [("full", {}), ("selected", {"selector": 1})])
def test_updates_of_a_matd3_group_of_one_equal_matd3_train(
    scheme: str, extra: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Four steps (the actors at steps 2 and 4, policy_delay 2), the target smoothing noise the same in both: the
    group runs MATD3's own step (twins, min target, smoothing, delay), not MADDPG's."""
    settings: dict[str, Any] = {"critic_sharing": scheme, "max_grad_norm": 0.05, "learning_rate": 3e-3, **extra}
    settings.update(algorithm=MATD3, target_policy_noise=0.3)
    reference, model = make_model(**settings), make_model(**settings)
    reference.set_logger(Logger(folder=None, output_formats=[]))
    group = RunGroup([model])
    monkeypatch.setattr(th, "randn_like", fixed_noise())  # the reference's smoothing noise (its only randn_like)
    monkeypatch.setattr(group.teams, "normal_like", fixed_noise())
    expected, actual = train_alike(reference, group, model, 4, monkeypatch)
    assert expected.keys() == actual.keys() and any("twin" in name for name in expected)
    for name, value in expected.items():
        th.testing.assert_close(actual[name], value, atol=1e-6, rtol=1e-5, msg=name)
    assert model._n_updates == reference._n_updates == 4


# ----- 2, 3. runs never touch each other -----


def three_runs(**kwargs: Any) -> list[MADDPG]:
    return [make_model(seed, **kwargs) for seed in (0, 1, 2)]


@pytest.mark.parametrize(("scheme", "algorithm"), [("full", MADDPG), ("selected", MADDPG), ("full", MATD3)])
@pytest.mark.parametrize("perturb", ["batch", "weights"])
def test_perturbing_one_run_leaves_the_others_bit_identical(scheme: str, algorithm: type[MADDPG], perturb: str) -> None:
    extra: dict[str, Any] = {"critic_sharing": scheme, "max_grad_norm": 0.05, "algorithm": algorithm}
    if scheme == "selected":
        extra["selector"] = 1
    models = three_runs(**extra)
    generator = th.Generator().manual_seed(3)
    batches = [stack_batches([random_batch(models[0], 32, generator) for _ in models]) for _ in range(2)]
    plain, perturbed = RunGroup(models), RunGroup(models)
    if perturb == "weights":
        with th.no_grad():
            perturbed.teams.critic.params["mlp.weight_0"][1] += 0.5
            perturbed.teams.actor.params["mlp.weight_1"][1] *= 2.0
    for batch in batches:
        plain.update(batch)
        if perturb == "batch":
            batch = batch._replace(rewards=batch.rewards.clone(), observations=batch.observations.clone())
            batch.rewards[1] += 10.0
            batch.observations[1] *= -1.0
        perturbed.update(batch)
    for run in (0, 2):
        assert all(th.equal(a, b) for a, b in zip(run_state(plain, run), run_state(perturbed, run)))
    assert not all(th.equal(a, b) for a, b in zip(run_state(plain, 1), run_state(perturbed, 1)))


def test_a_huge_gradient_in_one_run_does_not_shrink_another_runs_step() -> None:
    models = three_runs(max_grad_norm=0.5)
    generator = th.Generator().manual_seed(4)
    batch = stack_batches([random_batch(models[0], 32, generator) for _ in models])
    huge = batch._replace(rewards=batch.rewards.clone())
    huge.rewards[0] *= 1e6  # run 0's critic gradients: far over max_grad_norm
    plain, with_huge = RunGroup(models), RunGroup(models)
    plain.update(batch)
    with_huge.update(huge)
    for run in (1, 2):
        assert all(th.equal(a, b) for a, b in zip(run_state(plain, run), run_state(with_huge, run)))


def test_clipping_is_per_run_and_agent() -> None:
    """Under vmap over the runs (as a group's step clips), each run's each agent's slice is clipped on its own."""
    generator = th.Generator().manual_seed(5)
    grads = [th.randn(3, 2, 4, 5, generator=generator) * 0.01, th.randn(3, 2, 1, 5, generator=generator) * 0.01]
    grads[0][1, 0] *= 1e4  # run 1, agent 0 only
    clipped = th.func.vmap(lambda run_grads: clip_per_agent(run_grads, 1.0))(grads)
    norms = th.stack([grad.pow(2).sum(dim=(2, 3)) for grad in clipped]).sum(0).sqrt()
    assert norms[1, 0] == pytest.approx(1.0, rel=1e-4)
    for run, agent in [(0, 0), (0, 1), (1, 1), (2, 0), (2, 1)]:  # every other slice untouched
        assert all(th.equal(new[run, agent], old[run, agent]) for new, old in zip(clipped, grads))


def test_changing_one_runs_seed_leaves_the_others_learning_bit_identical() -> None:
    plain = RunGroup([make_model(seed) for seed in (0, 1, 2)]).learn(400)
    changed = RunGroup([make_model(seed) for seed in (0, 7, 2)]).learn(400)
    assert plain.n_updates == 3  # (400 - 100) / 100 gradient steps: the paper's ratio
    stats_plain, stats_changed = plain.episode_stats(), changed.episode_stats()
    for run in (0, 2):
        assert all(th.equal(a, b) for a, b in zip(run_state(plain, run), run_state(changed, run)))
        assert np.array_equal(stats_plain["reward"][:, run], stats_changed["reward"][:, run])
    assert not np.array_equal(stats_plain["reward"][:, 1], stats_changed["reward"][:, 1])


# ----- 4. alone and in a group -----


def test_a_run_alone_and_in_a_group_of_8_agree() -> None:
    seeds = list(range(8))
    grouped = RunGroup([make_model(seed) for seed in seeds]).learn(500)
    alone = [RunGroup([make_model(seed)]).learn(500) for seed in seeds]
    rewards = grouped.episode_stats()["reward"]
    for run, single in enumerate(alone):
        assert single.n_updates == grouped.n_updates == 4
        # The same seed draws the same episodes, noise and batches; the arithmetic of a batch of 8 networks may round
        # differently from one network's, so the weights agree to float tolerance, and so does what they did.
        for a, b in zip(run_state(grouped, run), run_state(single, 0)):
            th.testing.assert_close(a, b, atol=1e-5, rtol=1e-4)
        np.testing.assert_allclose(single.episode_stats()["reward"][:, 0], rewards[:, run], rtol=1e-4)


def test_the_groups_worlds_and_exploration_follow_the_numpy_envs_distribution() -> None:
    """Warm-up episodes (uniform actions plus the noise) of 8 runs against MADDPG's own warm-up on the numpy env: the
    worlds' mean min_dist_sum at the episodes' end, 64 rounds of 8 worlds each way."""
    group = RunGroup([make_model(seed, learning_starts=10_000) for seed in range(8)], worlds_per_run=8).learn(1600)
    grouped = group.episode_stats()["min_dist_sum"].ravel()
    model = make_model(0, n_envs=8, learning_starts=10_000)
    env = model.env
    assert env is not None
    model._last_obs = env.reset()  # type: ignore[assignment]
    numpy_env = []
    for step in range(64 * 25):
        actions, _ = model._sample_action(model.learning_starts, model.action_noise, env.num_envs)
        model._last_obs, _, _, infos = env.step(actions)  # type: ignore[assignment]
        if step % 25 == 24:
            numpy_env.append(np.mean([info["min_dist_sum"] for info in infos]))
    assert grouped.shape == (64,) and len(numpy_env) == 64
    assert stats.mannwhitneyu(grouped, numpy_env).pvalue > 0.01
    assert stats.ks_2samp(grouped, numpy_env).pvalue > 0.01


def test_each_stored_transition_is_the_numpy_envs_step_of_the_stored_action() -> None:
    """An episode of the group's worlds (float64, as the numpy env's), step by step from the same state, the actor
    acting without noise: the stored observations, actions, rewards and next observations are the numpy env's."""
    model = make_model(0, learning_starts=0, noise_std=0.0)
    group = RunGroup([model], worlds_per_run=2, world_dtype=th.float64)
    env = SimpleSpreadVecEnv(2, n_agents=N_AGENTS)
    env.reset()
    for step in range(25):  # the last step ends the episode: its next observations are the last ones, not the reset's
        worlds = group._worlds().worlds
        env.worlds.agent_pos[:] = worlds.agent_pos.numpy()
        env.worlds.agent_vel[:] = worlds.agent_vel.numpy()
        env.worlds.landmark_pos[:] = worlds.landmark_pos.numpy()
        observations = env.worlds.observations(env.worlds.distances()).reshape(2, -1)
        group.collect_step()
        stored = group.buffers.get(th.tensor([[2 * step, 2 * step + 1]]))
        np.testing.assert_allclose(stored.observations[0].numpy(), observations, atol=1e-6)
        actions, _ = model.predict(observations, deterministic=True)
        np.testing.assert_allclose(model.policy.unscale_action(stored.actions[0].numpy()), actions, atol=1e-6)
        env._steps = step  # the episode's step count, for the truncation
        next_observations, _, dones, infos = env.step(actions)
        if dones[0]:
            next_observations = np.stack([info["terminal_observation"] for info in infos])
        np.testing.assert_allclose(stored.next_observations[0].numpy(), next_observations, atol=1e-5)
        np.testing.assert_allclose(stored.rewards[0].numpy(), np.stack([i["agent_rewards"] for i in infos]), atol=1e-5)
    assert dones.all() and len(group.worlds.episodes) == 1  # type: ignore[union-attr]


# ----- back into models -----


def test_weights_written_back_save_and_load_and_act_the_same(tmp_path: Any) -> None:
    models = three_runs()
    group = RunGroup(models).learn(300)
    observations = th.randn(3, 5, models[0].agent_layout.obs_dim)  # type: ignore[union-attr]
    with th.no_grad():
        group_actions = group.networks.actions(observations)
    for run, model in enumerate(models):
        group.write_back(run, model)
        assert model.num_timesteps == 300 and model._n_updates == 2
        model.save(tmp_path / f"run_{run}")
        loaded = MADDPG.load(tmp_path / f"run_{run}")
        actions, _ = loaded.predict(observations[run].numpy(), deterministic=True)
        expected = loaded.policy.unscale_action(group_actions[run].numpy())
        np.testing.assert_allclose(actions, expected, atol=1e-6)
        assert loaded.num_timesteps == 300


def test_a_group_rebuilt_from_written_back_models_continues_exactly() -> None:
    models = three_runs()
    group = RunGroup(models)
    generator = th.Generator().manual_seed(6)
    batches = [stack_batches([random_batch(models[0], 32, generator) for _ in models]) for _ in range(3)]
    for batch in batches[:2]:
        group.update(batch)
    for run, model in enumerate(models):
        group.write_back(run, model)
    rebuilt = RunGroup(models)
    group.update(batches[2])
    rebuilt.update(batches[2])
    for run in range(3):
        for a, b in zip(run_state(group, run), run_state(rebuilt, run)):
            assert th.equal(a, b)


@RESUMES_WITHOUT_ITS_BUFFER
def test_written_back_models_go_on_learning_with_the_groups_update_rule() -> None:
    models = three_runs()
    group = RunGroup(models).learn(300)  # 200 transitions past learning_starts: 2 steps, counted at 300
    for run, model in enumerate(models):
        group.write_back(run, model)
    assert (models[0].update_rule.credit, models[0].update_rule.counted_at) == (0, 300)
    # A group rebuilt from them, and one model's own learn(), take the steps the group would: one per 100 more.
    rebuilt = RunGroup(models).learn(100)
    assert rebuilt.n_updates == group.learn(100).n_updates == 3
    before = models[0]._n_updates
    models[0].learn(100, reset_num_timesteps=False)
    assert models[0]._n_updates - before == 1


def test_a_state_for_saving_holds_full_buffers_without_a_copy_by_default() -> None:
    group = RunGroup(three_runs(buffer_size=200)).learn(100)  # 100 of 200 rows: partly filled
    partial = group.state_dict()["buffers"]["observations"]
    assert partial.shape[1] == 100 and partial.untyped_storage().nbytes() == partial.nbytes  # the rows alone
    assert th.equal(partial, group.buffers.observations[:, :100])
    group.learn(200)
    full = group.state_dict()["buffers"]  # the default: groups are sized to fill the device, a copy would not fit
    copied = group.state_dict(copy_buffers=True)["buffers"]
    for name in ("observations", "rewards"):
        assert full[name].data_ptr() == getattr(group.buffers, name).data_ptr()  # no second copy on the device
        assert th.equal(copied[name], full[name]) and copied[name].data_ptr() != full[name].data_ptr()


# ----- the parts -----


def test_each_run_samples_its_own_rows_from_its_own_stream() -> None:
    buffers = RunReplayBuffers(2, capacity=6, obs_dim=1, action_dim=1, n_agents=1, rows_per_step=2, episode_length=3)
    for step in range(4):  # 8 rows into 6: the first two are overwritten
        values = th.tensor([[[step * 2.0], [step * 2.0 + 1]], [[-step * 2.0], [-step * 2.0 - 1]]])
        buffers.add(values, values, values, values, values)
    assert buffers.size == 6 and buffers.observations[0, :, 0].tolist() == [6, 7, 2, 3, 4, 5]
    rows = buffers.sample_rows(400, RunStreams([11, 12]))
    assert th.equal(rows[1], RunStreams([12]).integers(th.tensor(6), (400,))[0])  # run 1's stream alone
    assert set(rows[0].tolist()) == set(range(6)) and not th.equal(rows[0], rows[1])  # every held row, its own draws
    batch = buffers.get(rows)
    assert th.equal(batch.observations[0, :, 0], buffers.observations[0, rows[0], 0])


CUDA = pytest.mark.skipif(not th.cuda.is_available(), reason="needs a CUDA device")


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=CUDA)])
@pytest.mark.parametrize("capacity_steps", [7, 9])  # 7: wraps mid-episode; 9: a multiple of the episode's 3 steps
def test_next_observations_are_those_stored_with_each_transition(capacity_steps: int, device: str) -> None:
    """The buffers keep next observations as the following step's rows, episode ends apart: every held row's next
    observations are the ones added with it (a plain store of every row beside them is the reference), while
    filling, once full and wrapping, the newest step included; and so do buffers loaded from a state saved on the
    way (copied, or not), which go on being written."""
    n_runs, worlds, obs_dim, episode_length = 2, 2, 3, 3

    def new_buffers() -> RunReplayBuffers:
        return RunReplayBuffers(
            n_runs, capacity_steps * worlds, obs_dim, 1, 1, device=device, rows_per_step=worlds, episode_length=3
        )

    buffers = new_buffers()
    generator = th.Generator().manual_seed(3)
    reference: dict[int, th.Tensor] = {}  # row -> the next observations added with it, [R, obs_dim]
    observations = th.randn(n_runs, worlds, obs_dim, generator=generator)
    zeros = th.zeros(n_runs, worlds, 1)
    for step in range(4 * capacity_steps):
        end = step % episode_length == episode_length - 1
        next_observations = th.randn(n_runs, worlds, obs_dim, generator=generator)
        row = buffers.pos
        on_device = (observations.to(device), next_observations.to(device), zeros.to(device))
        buffers.add(on_device[0], on_device[0][..., :1], on_device[1], on_device[2], on_device[2], episode_end=end)
        for world in range(worlds):
            reference[row + world] = next_observations[:, world]
        observations = th.randn(n_runs, worlds, obs_dim, generator=generator) if end else next_observations
        rows = th.arange(buffers.size, device=device).expand(n_runs, -1)
        expected = th.stack([reference[int(r)] for r in rows[0]], dim=1)
        assert th.equal(buffers.get(rows).next_observations.cpu(), expected), f"step {step}"
        if step in (capacity_steps + 1, 2 * capacity_steps + 2):  # full and wrapped; saved, then loaded afresh
            copy = step == capacity_steps + 1
            loaded = new_buffers()
            loaded.load_state_dict(buffers.state_dict(copy=copy))
            assert th.equal(loaded.get(rows).next_observations, buffers.get(rows).next_observations)
            buffers = loaded


def test_a_state_of_other_buffers_is_refused_with_what_differs() -> None:
    saved = RunReplayBuffers(1, capacity=6, obs_dim=2, action_dim=1, n_agents=1, rows_per_step=2, episode_length=3)
    other = RunReplayBuffers(1, capacity=6, obs_dim=2, action_dim=1, n_agents=1, rows_per_step=3, episode_length=3)
    with pytest.raises(ValueError, match=r"has final_observations of shape \(1, 3, 2, 2\), these buffers \(1, 2, 3, 2\)"):
        other.load_state_dict(saved.state_dict())


def test_episodes_shorter_than_declared_are_refused() -> None:
    # Sized for an episode end every 3 steps: one every step outgrows the store of the episodes' last observations.
    buffers = RunReplayBuffers(1, capacity=6, obs_dim=1, action_dim=1, n_agents=1, rows_per_step=1, episode_length=3)
    zeros = th.zeros(1, 1, 1)
    with pytest.raises(ValueError, match="Episodes end more often than every 3 steps"):
        for step in range(6):
            before = (buffers.pos, buffers.size, buffers.observations.clone())
            buffers.add(zeros + step, zeros, zeros, zeros, zeros, episode_end=True)
    # The refused step wrote nothing: the buffers are as they were before it.
    assert (buffers.pos, buffers.size) == before[:2] and th.equal(buffers.observations, before[2])


def test_buffers_hold_about_half_of_storing_next_observations_beside() -> None:
    # The paper's N=5 buffers: 1M transitions in steps of 100 worlds, episodes of 25 steps.
    obs_dim, action_dim, n_agents = 150, 25, 5
    stored_beside = 4 * (2 * obs_dim + action_dim + 2 * n_agents) * 1_000_000
    held = replay_nbytes(1, 1_000_000, obs_dim, action_dim, n_agents, rows_per_step=100, episode_length=25)
    assert 0.5 < held / stored_beside < 0.6
    small = RunReplayBuffers(3, 60, 7, 2, 2, selection_size=1, rows_per_step=4, episode_length=5)
    assert small.nbytes() == replay_nbytes(3, 60, 7, 2, 2, rows_per_step=4, episode_length=5, selection_size=1)


@pytest.mark.parametrize("selector", [NearestAgents(k=2), NearestAgents(k=1), FixedGraph([[1, 2], [2, 0], [0, 1]])])
def test_selections_on_the_device_are_the_selectors(selector: Any) -> None:
    layout = make_model().agent_layout
    assert layout is not None
    observations = th.randn(4, 6, layout.obs_dim, generator=th.Generator().manual_seed(7))
    expected = selector.select(observations.reshape(-1, layout.obs_dim).numpy(), layout).reshape(4, 6, N_AGENTS, -1)
    assert np.array_equal(select_on_device(selector, observations, layout).numpy(), expected)


@pytest.mark.parametrize("target", ["stored", "next"])
def test_a_groups_target_selection_is_made_from_the_next_observations_as_the_buffers(
    target: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    group = RunGroup([make_model(critic_sharing="selected", selector={"k": 1, "target": target})])
    for _ in range(30):
        group.collect_step()
    batches: list[MultiAgentReplayBufferSamples] = []
    step = group._gradient_step  # what train() runs on the batch it draws
    monkeypatch.setattr(group, "_gradient_step", lambda batch, due: batches.append(batch) or step(batch, due))
    group.train(1)
    (batch,) = batches
    if target == "stored":
        assert batch.next_selections is None
        return
    assert batch.next_selections is not None and batch.selections is not None
    layout = group.layout
    expected = NearestAgents(1).select(batch.next_observations[0].numpy(), layout)  # from the raw next observations
    assert np.array_equal(batch.next_selections[0].numpy(), expected)
    assert not th.equal(batch.next_selections, batch.selections)  # the nearest agents changed on some rows


# ----- 5. refusals -----


def test_models_that_differ_in_more_than_their_seed_are_refused() -> None:
    with pytest.raises(ValueError, match=r"^The models differ in gamma: model 0 has 0.95, model 1 has 0.9\..*seed"):
        RunGroup([make_model(0), make_model(1, gamma=0.9)])
    with pytest.raises(ValueError, match=r"^The models differ in agent_layout"):
        RunGroup([make_model(0), make_model(1, n_agents=2)])
    with pytest.raises(ValueError, match=r"^The models differ in critic_sharing"):
        RunGroup([make_model(0), make_model(1, critic_sharing="independent")])
    # The policy's configuration, whichever model has it (a group of models with and without layer norm stacked
    # model 0's parameters only, or failed on a missing one).
    for first, second in ((False, True), (True, False)):
        with pytest.raises(ValueError, match=rf"^The models differ in layer_norm: model 0 has {first}, model 1 has {second}"):
            RunGroup(
                [
                    make_model(0, policy_kwargs={**SMALL, "layer_norm": first}),
                    make_model(1, policy_kwargs={**SMALL, "layer_norm": second}),
                ]
            )
    with pytest.raises(ValueError, match=r"^The models differ in net_arch"):
        RunGroup([make_model(0), make_model(1, policy_kwargs={"net_arch": [16, 8]})])
    with pytest.raises(ValueError, match=r"^The models differ in share_parameters"):
        RunGroup([make_model(0), make_model(1, policy_kwargs={**SMALL, "share_parameters": True})])
    odd = make_model(1)
    odd.actor.register_parameter("extra", th.nn.Parameter(th.zeros(2)))
    with pytest.raises(ValueError, match=r"^The models' networks differ in parameter actor\.extra: model 0's has shape none"):
        RunGroup([make_model(0), odd])
    assert RunGroup([make_model(s, policy_kwargs={**SMALL, "layer_norm": True}) for s in (0, 1)]).learn(200).n_updates == 1


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: make_model(critic_sharing="attention"), r"^Model 0's critics use a learned scheme \(AttentionCritic"),
        (lambda: make_model(seed=None), r"^Model 0 has no seed.*MADDPG\(\.\.\., seed=s\)"),
        (lambda: make_model(train_freq=1), r"^Model 0 was given train_freq or gradient_steps.*transitions_per_update"),
        (
            lambda: MADDPG("MlpPolicy", VecNormalize(SimpleSpreadVecEnv(2, n_agents=N_AGENTS), norm_reward=False), seed=0),
            r"^Model 0's env is wrapped in VecNormalize.*train it with MADDPG\.learn \(a sweep's local backend, "
            r"backend=\"local\"\)",
        ),
        (
            lambda: make_model(policy_kwargs={**SMALL, "optimizer_class": th.optim.SGD}),
            r"^The models' optimiser is SGD, and a run group trains with Adam only",
        ),
    ],
)
def test_what_a_group_cannot_train_is_refused_with_the_cause_first(make: Any, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        RunGroup([make()])


def test_an_empty_group_and_worlds_of_another_team_are_refused() -> None:
    with pytest.raises(ValueError, match=r"^A run group needs at least one model"):
        RunGroup([])
    group = RunGroup([make_model()], task=SpreadTask(n_agents=N_AGENTS, num_agent_neighbors=1))
    with pytest.raises(ValueError, match=r"^The task's worlds have agent layout"):
        group.learn(10)


# ----- 6. CUDA -----


@pytest.mark.skipif(not th.cuda.is_available(), reason="needs a CUDA device")
def test_a_group_on_cuda_updates_as_on_the_cpu_and_runs_learn_on_device() -> None:
    models = three_runs(critic_sharing="selected", **{"selector": 1})
    generator = th.Generator().manual_seed(8)
    batch = stack_batches([random_batch(models[0], 32, generator) for _ in models])
    on_cpu, on_cuda = RunGroup(models), RunGroup(models, device="cuda")
    on_cpu.update(batch)
    on_cuda.update(MultiAgentReplayBufferSamples(*(None if f is None else f.cuda() for f in batch)))
    for run in range(3):
        for a, b in zip(run_state(on_cpu, run), run_state(on_cuda, run)):
            th.testing.assert_close(b.cpu(), a, atol=1e-5, rtol=1e-4)
    on_cuda.learn(300)
    assert on_cuda.n_updates == 3 and on_cuda.buffers.observations.is_cuda
    model = on_cuda.write_back(0, copy.deepcopy(models[0]))
    assert model.num_timesteps == 300


def test_each_agents_episode_returns_are_its_stored_rewards_summed() -> None:
    """The group's per-agent returns (``rollout/<agent_id>/ep_rew_mean`` in its runs' logs), by hand from the rewards
    the buffers stored: per round and run, each agent's rewards summed over the episode's 25 steps, averaged over the
    worlds; the team return is their sum; a saved state holds them."""
    group = RunGroup(three_runs(learning_starts=10_000)).learn(300)  # 150 steps of 2 worlds: 6 rounds, all stored
    agents, team = th.stack(group.worlds.agent_episodes), th.stack(group.worlds.episodes)[:, 0]  # type: ignore[union-attr]
    stored = group.buffers.rewards[:, : group.buffers.size].reshape(3, -1, 25, 2, N_AGENTS)  # [R, rounds, step, E, N]
    expected = stored.sum(dim=2).mean(dim=2).transpose(0, 1)  # [rounds, R, N]
    assert agents.shape == expected.shape == (6, 3, N_AGENTS)
    th.testing.assert_close(agents, expected, rtol=1e-5, atol=1e-4)
    th.testing.assert_close(agents.sum(dim=-1), team, rtol=1e-5, atol=1e-4)
    assert th.equal(group.state_dict()["worlds"]["agent_episodes"], agents)


def test_a_copied_state_does_not_change_as_the_group_trains_on() -> None:
    """``state_dict(copy_buffers=True)`` is a snapshot: the worlds' positions, velocities and episode returns too
    (they change in place as the worlds step)."""
    group = RunGroup([make_model(seed) for seed in (0, 1)]).learn(200)
    kept = group.state_dict(copy_buffers=True)
    expected = copy.deepcopy(kept)
    group.learn(40)
    worlds, before = kept["worlds"], expected["worlds"]
    for name in ("state", "observations", "agent_returns"):
        pairs = zip(worlds[name], before[name]) if name == "state" else [(worlds[name], before[name])]
        assert all(th.equal(a, b) for a, b in pairs), name
