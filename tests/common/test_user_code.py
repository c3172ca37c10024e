"""The package's warnings point at the user's line, whichever algorithm and however many of the package's frames."""

import warnings

import pytest

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.common.package_warnings import SB3MADDPGWarning
from sb3_maddpg.envs import make_simple_spread
from tests.settings import NEVER_UPDATES


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_warnings_point_at_the_line_that_called_the_package(algorithm: type[MADDPG]) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        # k=2 of 3 selects everyone: a warning from the constructor
        model = algorithm("MlpPolicy", make_simple_spread(n_agents=3), critic_sharing="selected", selector=2, **NEVER_UPDATES)
        model.learn(50)  # ends before learning_starts: the never-updated warning
    messages = {
        # The package's own class (what a suite filters), still a UserWarning for everyone else.
        "selects every other agent": SB3MADDPGWarning,
        "without a single gradient update": SB3MADDPGWarning,
    }
    for text, category in messages.items():
        (warning,) = [w for w in caught if text in str(w.message)]
        assert warning.category is category and warning.filename == __file__, (text, warning.filename)
        assert issubclass(category, UserWarning)
