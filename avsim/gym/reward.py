"""The reward of `avsim/StopSign-v0`: every term and constant in one place.

Each control step's reward is the sum of four terms (`RewardTerms`):

    progress   +PROGRESS_PER_M for every metre the front bumper advanced towards the stop line
               during the step. Metres past the line earn nothing: the sign requires a stop
               there. Rolling back earns negative progress.
    stop_bonus +STOP_BONUS on the step the car comes to a stop (below 0.1 m/s, having moved)
               with its front bumper 0 to STOP_WINDOW_M before the line.
    ran_sign   -RAN_SIGN_PENALTY on the step the front bumper passes the sign post without
               the car having stopped.
    comfort    -JERK_COST_PER_MPS2 for every m/s^2 the longitudinal acceleration changed since
               the previous step: |jerk| * dt, summed over an episode the acceleration's total
               variation. The acceleration is the change of speed over one control step; at
               reset it is taken as 0.

The whole approach from the default 230 m is worth 2.3 in progress, so running the sign (-10)
always costs more than any progress it gained, and a stop in the window (+1) is worth more than
the last metres an early stop forgoes. Nothing here depends on what the car perceives: the
reward is computed from the true state, which the observation does not contain.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

PROGRESS_PER_M = 0.01
STOP_BONUS = 1.0
STOP_WINDOW_M = 3.0  # a stop with the bumper 0 to 3 m before the stop line earns the bonus
RAN_SIGN_PENALTY = 10.0
JERK_COST_PER_MPS2 = 0.01


@dataclass(frozen=True)
class RewardTerms:
    """One step's reward, term by term (see the module docstring); `total` is the reward."""

    progress: float
    stop_bonus: float
    ran_sign: float
    comfort: float

    @property
    def total(self) -> float:
        """The step's reward: the sum of its terms."""
        return self.progress + self.stop_bonus + self.ran_sign + self.comfort

    def to_dict(self) -> dict[str, float]:
        """The terms by name, as `info["reward_terms"]` reports them."""
        return asdict(self)


def reward_terms(*, line_dist_before_m: float, line_dist_after_m: float, accel_before_mps2: float,
                 accel_after_mps2: float, stopped: bool, ran_sign: bool) -> RewardTerms:
    """The reward of one control step.

    line_dist_before_m, line_dist_after_m: front bumper to the stop line at the step's start and
    end [m], positive before the line; accel_*: longitudinal acceleration over the previous and
    this step [m/s^2]; stopped: the step ended with the car stopped; ran_sign: it ended with the
    front bumper past the sign and the car not stopped.
    """
    progress_m = max(line_dist_before_m, 0.0) - max(line_dist_after_m, 0.0)
    in_window = 0.0 <= line_dist_after_m <= STOP_WINDOW_M
    return RewardTerms(
        progress=PROGRESS_PER_M * progress_m,
        stop_bonus=STOP_BONUS if stopped and in_window else 0.0,
        ran_sign=-RAN_SIGN_PENALTY if ran_sign else 0.0,
        comfort=-JERK_COST_PER_MPS2 * abs(accel_after_mps2 - accel_before_mps2),
    )
