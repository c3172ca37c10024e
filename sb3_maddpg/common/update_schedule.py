"""When MADDPG takes gradient steps, and how many: the paper's per-transition rule, or SB3's ``train_freq``."""

import dataclasses

from stable_baselines3.common.type_aliases import TrainFreq, TrainFrequencyUnit


@dataclasses.dataclass
class UpdateSchedule:
    """
    The per-transition update rule (Lowe et al.'s "one update per 100 transitions", whatever the number of envs) and
    its state.

    SB3's ``train_freq`` counts vectorised steps, ``n_envs`` transitions each: with ``n_envs`` envs, a fixed
    ``train_freq=100`` would give one update per ``100 * n_envs`` transitions. Instead, when ``train_freq`` is not
    given, the model updates every ``max(1, transitions_per_update // n_envs)`` vectorised steps; when neither
    ``train_freq`` nor ``gradient_steps`` is given, each update takes the gradient steps that the transitions
    collected since the last one have earned, one per ``transitions_per_update`` transitions past
    ``learning_starts``, a remainder (the credit) carrying over. Either argument given keeps SB3's meaning of both.

    :param transitions_per_update: Transitions (all envs counted) per gradient step.
    :param derives_train_freq: Whether ``train_freq`` comes from the number of envs (it was not given).
    :param earns_gradient_steps: Whether each update takes the gradient steps earned (neither ``train_freq`` nor
        ``gradient_steps`` was given).
    :param credit: Transitions past ``learning_starts`` not yet spent on a gradient step.
    :param counted_at: The model's ``num_timesteps`` when the credit was last counted.
    """

    transitions_per_update: int = 100
    derives_train_freq: bool = True
    earns_gradient_steps: bool = True
    credit: int = 0
    counted_at: int = 0

    @classmethod
    def from_arguments(
        cls, transitions_per_update: int, train_freq: int | tuple[int, str] | None, gradient_steps: int | None
    ) -> "UpdateSchedule":
        """
        The schedule of MADDPG's arguments.

        :param transitions_per_update: Transitions per gradient step (a positive integer).
        :param train_freq: MADDPG's ``train_freq`` (None: derived from the number of envs).
        :param gradient_steps: MADDPG's ``gradient_steps`` (None with ``train_freq`` None: earned).
        :return: The schedule, with no credit.
        """
        if (
            isinstance(transitions_per_update, bool)
            or not isinstance(transitions_per_update, int)
            or transitions_per_update < 1
        ):
            raise ValueError(
                f"transitions_per_update must be a positive integer (transitions per gradient step), got "
                f"{transitions_per_update!r}: the paper's is 100."
            )
        return cls(transitions_per_update, train_freq is None, train_freq is None and gradient_steps is None)

    def train_freq(self, n_envs: int) -> TrainFreq | None:
        """
        :param n_envs: The number of envs.
        :return: Every ``max(1, transitions_per_update // n_envs)`` vectorised steps, or None when ``train_freq`` was
            given (SB3's own stands).
        """
        if not self.derives_train_freq:
            return None
        return TrainFreq(max(1, self.transitions_per_update // n_envs), TrainFrequencyUnit.STEP)

    def earned(self, num_timesteps: int, learning_starts: int) -> int:
        """
        Count the transitions collected since the last call, past ``learning_starts``, into the credit, and spend it.

        :param num_timesteps: The model's env steps so far (all envs counted).
        :param learning_starts: Env steps before learning starts.
        :return: The gradient steps earned: one per ``transitions_per_update`` transitions of credit.
        """
        counted_from = max(self.counted_at, learning_starts)
        self.credit += max(0, num_timesteps - counted_from)
        self.counted_at = num_timesteps
        steps, self.credit = divmod(self.credit, self.transitions_per_update)
        return steps

    def reset(self) -> None:
        """Forget the credit: timesteps count from 0 again (``learn(reset_num_timesteps=True)``)."""
        self.credit = 0
        self.counted_at = 0

    def describe(self, train_freq: TrainFreq, n_envs: int, gradient_steps: int, batch_size: int, learning_starts: int) -> str:
        """
        :param train_freq: The model's (converted) ``train_freq``.
        :param n_envs: The number of envs.
        :param gradient_steps: The model's ``gradient_steps`` (read only under SB3's semantics).
        :param batch_size: The minibatch size.
        :param learning_starts: Env steps before learning starts.
        :return: The rule in words, e.g. ``"one gradient step (batch 1024) per 100 transitions after step 25,600, taken
            every 1 step(s) of 100 env(s)"``.
        """
        every = f"every {train_freq.frequency} {train_freq.unit.value}(s) of {n_envs} env(s)"
        if self.earns_gradient_steps:
            return (
                f"one gradient step (batch {batch_size}) per {self.transitions_per_update} transitions after "
                f"step {learning_starts:,}, taken {every}"
            )
        steps = f"{gradient_steps} gradient step(s)" if gradient_steps >= 0 else "a gradient step per transition"
        return f"{steps} (batch {batch_size}) {every}, after step {learning_starts:,} (SB3's train_freq semantics)"
