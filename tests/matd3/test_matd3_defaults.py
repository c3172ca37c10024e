"""MATD3's defaults, as its docstring says: TD3's own parameters have SB3's TD3 defaults, every other parameter is
MADDPG's, with the paper's values (Lowe et al.)."""

import inspect

from stable_baselines3 import TD3

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import make_simple_spread

TD3_OWN = ("policy_delay", "target_policy_noise", "target_noise_clip")
"""The parameters MATD3 adds to MADDPG's."""


def defaults(algorithm: type) -> dict[str, object]:
    """:return: Each constructor parameter's default (``inspect.Parameter.empty`` where there is none)."""
    return {name: parameter.default for name, parameter in inspect.signature(algorithm.__init__).parameters.items()}


def test_matd3_has_maddpgs_defaults_and_td3s_own_from_sb3() -> None:
    matd3, maddpg, td3 = defaults(MATD3), defaults(MADDPG), defaults(TD3)
    assert set(matd3) == set(maddpg) | set(TD3_OWN)
    assert {name: matd3[name] for name in maddpg} == maddpg  # a sweep that swaps the algorithm changes nothing else
    assert (
        {name: matd3[name] for name in TD3_OWN}
        == {name: td3[name] for name in TD3_OWN}
        == {
            "policy_delay": 2,
            "target_policy_noise": 0.2,
            "target_noise_clip": 0.5,
        }
    )
    # The paper's (Lowe et al.'s) discount and target update, not TD3's 0.99 and 0.005; SB3's logging window.
    assert (maddpg["gamma"], maddpg["tau"]) == (0.95, 0.01) != (td3["gamma"], td3["tau"])
    assert maddpg["stats_window_size"] == td3["stats_window_size"] == 100


def test_a_matd3_built_with_the_defaults_holds_them() -> None:
    model = MATD3("MlpPolicy", make_simple_spread(n_agents=2), buffer_size=100, policy_kwargs={"net_arch": [8]})
    assert (model.gamma, model.tau, model._stats_window_size) == (0.95, 0.01, 100)
    assert (model.policy_delay, model.target_policy_noise, model.target_noise_clip) == (2, 0.2, 0.5)
