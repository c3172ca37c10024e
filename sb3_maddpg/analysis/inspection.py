"""Looking inside a trained model: what each critic that learns whom to listen to attends to."""

from typing import Any

import numpy as np
import torch as th

from sb3_maddpg.sharing.learned import _ListeningExtractor


def critic_listening(model: Any, observations: Any, actions: Any = None) -> dict[str, Any]:
    """
    What each critic of a model with ``attention`` or ``learned_selection`` critics listens to, for a batch.

    :param model: A trained :class:`~sb3_maddpg.MADDPG`.
    :param observations: Joint observations ``[batch, obs_dim]`` (numpy, or torch on any device).
    :param actions: Joint actions in the env's units, ``[batch, action_dim]`` (numpy or torch); default: the model's
        deterministic actions.
    :return: ``weights``: ``[batch, n_agents, n_agents]`` numpy, row i the weights critic i gives the others (0 on the
        diagonal; for ``attention``, the heads' mean); ``chosen``: ``[batch, n_agents, k]`` agent indices (highest
        score first) when some critic is a learned selection (``k`` its largest), row i critic i's, ``-1`` where it
        chooses no agent (an ``attention`` critic, or a smaller ``k``); else ``None``.
    """
    policy = model.policy
    extractors = list(policy.critic.extractors)
    others = [type(extractor).__name__ for extractor in extractors if not isinstance(extractor, _ListeningExtractor)]
    if others:
        raise TypeError(
            f"critic_listening needs critics that learn whom to listen to (critic_sharing='attention' or "
            f"'learned_selection'), got {', '.join(others)}."
        )
    observations = np.asarray(_to_numpy(observations), dtype=np.float32).reshape(-1, model.observation_space.shape[0])
    if actions is None:
        actions, _ = model.predict(observations, deterministic=True)
    scaled = policy.scale_action(np.asarray(_to_numpy(actions), dtype=np.float32).reshape(observations.shape[0], -1))
    obs_tensor = th.as_tensor(observations, device=policy.device)
    act_tensor = th.as_tensor(scaled, dtype=th.float32, device=policy.device)
    n_agents = len(extractors)
    weights = np.zeros((observations.shape[0], n_agents, n_agents), dtype=np.float32)
    chosen: dict[int, np.ndarray] = {}
    with th.no_grad():
        for i, extractor in enumerate(extractors):
            weights[:, i, extractor.encoder.others] = extractor.listening_weights(obs_tensor, act_tensor).cpu().numpy()
            choice = extractor.chosen_agents(obs_tensor, act_tensor)
            if choice is not None:
                chosen[i] = choice.cpu().numpy()
    if not chosen:
        return {"weights": weights, "chosen": None}
    # Row i is critic i's, whichever critics choose (a per-agent mapping may mix attention and learned selection).
    table = np.full((observations.shape[0], n_agents, max(c.shape[1] for c in chosen.values())), -1, dtype=np.int64)
    for i, choice in chosen.items():
        table[:, i, : choice.shape[1]] = choice
    return {"weights": weights, "chosen": table}


def _to_numpy(array: Any) -> Any:
    """:return: A torch tensor as a numpy array (detached, on the CPU); anything else as it is."""
    return array.detach().cpu().numpy() if isinstance(array, th.Tensor) else array
