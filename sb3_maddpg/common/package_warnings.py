"""The package's own warning classes: one base, so that a user (or a test suite) can filter, or turn into errors,
every warning sb3-maddpg gives and nothing else (``warnings.filterwarnings("error", category=SB3MADDPGWarning)``)."""


class SB3MADDPGWarning(UserWarning):
    """A warning of sb3-maddpg: a setting or an input that runs, but probably not as intended (it says why)."""


class SB3MADDPGDeprecationWarning(SB3MADDPGWarning, FutureWarning):
    """A name or an argument of sb3-maddpg that will go: shown to users by default, as ``FutureWarning`` is."""
