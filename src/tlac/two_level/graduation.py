"""Graduation: how TL-AC's graduate variant hands control to the student (docs/graduation.md).

The paper's TL-AC (Algorithm 1) lets the high level mix teachers and agent step by step, so the
student never acts for a whole episode during training, and at deployment it meets states it
has never seen (covariate shift; Ross et al. 2011). The graduate variant plays some episodes
with the student ALONE ("solo" episodes; JSRL's hand-over, Uchendu et al. 2023, taken to the
whole episode), and the imitation term of the update labels those states with the advice of
the teachers the high level trusts there (DAgger-style relabelling).

How many episodes are solo is set by the student's measured competence: a solo episode costs
the training return ``R_assisted - R_solo`` in expectation, so playing a share

    p = min(1, budget / (1 - competence)),   competence = (R_solo - R_floor) / (R_best - R_floor)

of episodes alone costs at most ``budget * (R_best - R_floor)``: little while the student is
weak, and control passes to it entirely once it is as good as its teachers. ``R_best`` is the
best mean of recent assisted returns seen so far (what the teachers have shown they reach), not
the latest: if assisted episodes get worse, that must not read as a competent student.

>>> solo_probability(0.0, 0.05), round(solo_probability(0.8, 0.05), 9), solo_probability(0.99, 0.05)
(0.05, 0.25, 1.0)
>>> competence(solo=0.5, assisted=0.9, floor=0.1)
0.5
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from tlac.algorithms.nets import tanh_mlp_numpy
from tlac.algorithms.normalization import Normalizer
from tlac.selectors import ucb1_scores

if TYPE_CHECKING:
    from tlac.two_level.config import TLACConfig


def solo_probability(competence: float, budget: float) -> float:
    """The share of episodes the student plays alone: ``min(1, budget / (1 - competence))``,
    so that ``p * (1 - competence)`` (the expected loss of training return, in units of the
    teachers' advantage over the untrained student) never exceeds ``budget``."""
    if budget <= 0:
        return 0.0
    if competence >= 1.0:
        return 1.0
    return float(min(1.0, budget / (1.0 - competence)))


def competence(solo: float, assisted: float, floor: float) -> float:
    """How close the student alone is to the assisted behaviour, in [0, 1]:
    ``(solo - floor) / (assisted - floor)``, clipped; 0 while the assisted episodes have shown
    nothing above the floor: there is no evidence yet of what the student should match, and
    handing it every episode then would starve the high level of the assisted episodes it
    learns from (MountainCar, whose teacher the high level finds only after some thousand
    steps, stayed at -200 with every episode solo)."""
    if assisted <= floor:
        return 0.0
    return float(np.clip((solo - floor) / (assisted - floor), 0.0, 1.0))


HELP_MARGIN = 2.0
"""Standard errors by which a teacher's led episodes must beat the untrained student's level
to count as help (:func:`shows_help`)."""
MIN_LED_EPISODES = 3
"""Led episodes of every teacher before the teachers can be judged to show nothing."""
SAYS_NOTHING = 0.01
"""A teacher whose advice, over every row it was asked, averages at most this information
(``1 - H / log A`` for discrete actions, the information of tlac.teachers.base.advice_actions
for Box ones: 1 for a deterministic teacher) has nothing to copy: a random teacher."""
RECHECK_SHARE = 0.1
"""The share of episodes a teacher still leads when none has shown help, so that one judged on
a few unlucky episodes (a sparse goal reached now and then) can show its help later."""


def shows_help(led_sum: float, led_square_sum: float, led_count: int, floor: float) -> bool:
    """Whether a teacher's led episodes (``led_count`` returns, their sum and sum of squares)
    show a return above ``floor`` (the untrained student's) by more than ``HELP_MARGIN``
    standard errors of their mean: something the student does not reach alone already.

    >>> shows_help(-1500.0, 750_000.0, 3, floor=-500.0)   # three episodes at -500: nothing
    False
    >>> shows_help(-1200.0, 500_000.0, 3, floor=-500.0)   # -500, -400, -300: mean -400, se 47
    True
    >>> shows_help(-2950.0, 1_452_500.0, 6, floor=-500.0)  # five -500s and one -450: se 7.6
    False
    """
    mean, se = led_mean_and_se(led_sum, led_square_sum, led_count)
    return bool(mean - HELP_MARGIN * se > floor)


def shows_harm(
    led_sum: float, led_square_sum: float, led_count: int, floor: float, floor_se: float
) -> bool:
    """Whether a teacher's led episodes (``led_count`` returns, their sum and sum of squares)
    show a return BELOW ``floor`` (the untrained student's, with standard error ``floor_se``)
    by more than ``HELP_MARGIN`` standard errors of the difference: following it does worse
    than a student that has learned nothing (the mirror image of a good policy), where a random
    or idle teacher sits at that level. The untrained level's own error counts here: on
    Acrobot an untrained student that swung up once in its first five episodes (-485.8) is no
    evidence that a teacher at -500 harms.

    >>> shows_harm(-4500.0, 6_750_000.0, 3, floor=-1100.0, floor_se=90.0)   # three at -1500
    True
    >>> shows_harm(-1500.0, 750_000.0, 3, floor=-500.0, floor_se=0.0)   # at the floor: no harm
    False
    >>> shows_harm(-1500.0, 750_000.0, 3, floor=-485.8, floor_se=12.7)   # 14.2 < 2 x 12.7
    False
    """
    mean, se = led_mean_and_se(led_sum, led_square_sum, led_count)
    return bool(mean - floor < -HELP_MARGIN * np.hypot(se, floor_se))


def led_mean_and_se(led_sum: float, led_square_sum: float, led_count: int) -> tuple[float, float]:
    """The mean of ``led_count`` led returns (their sum and sum of squares) and its standard
    error.

    >>> [round(x, 1) for x in led_mean_and_se(-1200.0, 500_000.0, 3)]   # -500, -400, -300
    [-400.0, 47.1]
    """
    mean = led_sum / led_count
    variance = max(led_square_sum / led_count - mean * mean, 0.0)
    return mean, float(np.sqrt(variance / led_count))


HANDOVER_ENTROPY = 0.05
"""The low level's entropy coefficient that weaned imitation adds at full competence."""


def handover_entropy_coef(competence: float) -> float:
    """The entropy bonus that weaned imitation (``wean_imitation``, discrete actions) adds to
    the low level's: ``HANDOVER_ENTROPY * competence``. As the copy's weight falls to
    ``1 - competence``, the student's own policy gradient takes over, and a copy of one
    deterministic teacher leaves it almost nothing to sample (Acrobot: 0.2 of 1.10 nats after
    1e4 steps); the bonus gives it back the exploration it needs to learn past that teacher.
    Box actions are imitated under a fixed variance and keep their noise: no bonus there.

    >>> handover_entropy_coef(0.0), handover_entropy_coef(0.5), handover_entropy_coef(1.0)
    (0.0, 0.025, 0.05)
    """
    return HANDOVER_ENTROPY * competence


def entropy_coefs(
    settings: torch.Tensor, solo: SoloEpisodes | None, handover: bool
) -> torch.Tensor:
    """``[low, high]`` entropy coefficients of a gradient step: the settings' (``settings``),
    plus the hand-over bonus on the low level under weaned imitation (``handover``: discrete
    actions, with solo episodes ``solo``).

    >>> entropy_coefs(torch.tensor([0.0, 0.01]), None, False).tolist()
    [0.0, 0.009999999776482582]
    """
    if not handover:
        return settings
    assert solo is not None
    bonus = handover_entropy_coef(solo.weaning)
    return settings + torch.tensor([bonus, 0.0])


RECENT_SOLO = 5
"""The latest solo episodes that must also be in line with the best window before the student
is deployed (:func:`worth_deploying`)."""


def worth_deploying(
    window: deque[float], best: float, n_windows: float = 1.0, recent: int = RECENT_SOLO
) -> tuple[bool, float]:
    """Whether the student that just played the solo episodes in ``window`` should be the one
    deployed, and the new best window mean. Yes unless the window's mean is clearly below
    the best mean seen so far: below it by more than ``(1 + sqrt(2 ln n_windows))`` standard
    errors of this window. The best of ``n_windows`` noisy window means overshoots the
    student's true level by about ``sqrt(2 ln n_windows)`` standard errors (the expected
    maximum of that many Gaussians), so without that term a student that played many solo
    episodes would be held to a lucky peak; ``n_windows`` counts disjoint windows' worth of
    solo episodes. The ``recent`` latest episodes must pass the same test (their mean, their
    count's standard error, the window's spread): the window's older episodes were played by
    older students, and a student that has just collapsed shows first in a few bad episodes,
    which lower the window's mean little and widen its spread (CartPole, docs/graduation.md).

    >>> worth_deploying(deque([1.0, 0.0, 1.0, 1.0]), best=0.9)   # mean 0.75, se ~0.22
    (True, 0.9)
    >>> worth_deploying(deque([0.0, 0.0, 1.0, 0.0]), best=0.9)   # mean 0.25, se ~0.22
    (False, 0.9)
    >>> worth_deploying(deque([0.0, 0.0, 1.0, 0.0]), best=0.9, n_windows=100)  # slack 4 se
    (True, 0.9)
    >>> collapsing = deque([500.0] * 17 + [100.0] * 3)  # mean 440, slack 3.04 x std 142.8
    >>> worth_deploying(collapsing, best=500.0, n_windows=8, recent=20)  # 440 >= 402.9
    (True, 500.0)
    >>> worth_deploying(collapsing, best=500.0, n_windows=8)  # the latest 5: 260 < 305.9
    (False, 500.0)
    """
    returns = np.asarray(window, dtype=np.float64)
    mean = float(returns.mean())
    best = max(best, mean)
    spread = (1.0 + np.sqrt(2.0 * np.log(max(n_windows, 1.0)))) * float(returns.std())
    latest = returns[-recent:]
    whole_in_line = mean >= best - spread / np.sqrt(len(returns))
    latest_in_line = float(latest.mean()) >= best - spread / np.sqrt(len(latest))
    return bool(whole_in_line and latest_in_line), best


class StudentSnapshot:
    """The student as it was at one moment: a frozen copy of the low level's layers, its Box
    log-std, the observation normaliser's statistics and (an image space) a frozen copy of the
    shared CNN (``encoder``; None: the model's stateless encoder). With solo episodes the model
    deploys (``predict``) the last student whose solo episodes were about as good as its best
    ones (:func:`worth_deploying`), not whatever the last update left: training goes on from
    the live weights, but a late collapse of the live student (measured on CartPole and Acrobot,
    docs/graduation.md) no longer reaches the user. Model selection on the episodes the student
    played alone during training, within the training budget (as SB3's EvalCallback keeps a
    best model, but without extra evaluation episodes)."""

    def __init__(
        self,
        layers: list[tuple[np.ndarray, np.ndarray]],
        log_std: np.ndarray | None,
        normalizer: Normalizer | None,
        num_timesteps: int,
        encoder: Any = None,
    ):
        self.layers, self.log_std, self.normalizer = layers, log_std, normalizer
        self.num_timesteps = num_timesteps
        self.encoder = encoder

    def net_input(self, obs: np.ndarray) -> np.ndarray:
        """Raw ``(n, obs_dim)`` observations, normalised as they were at the snapshot."""
        return obs if self.normalizer is None else self.normalizer.obs_numpy(obs)

    def forward(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The low level's ``(output, last hidden layer)`` on (encoded) inputs ``x``."""
        return tanh_mlp_numpy(self.layers, x)

    def state(self) -> dict[str, Any]:
        """Tensors and numbers only (a checkpoint of it loads with ``weights_only=True``)."""
        return {
            "layers": [[torch.from_numpy(w), torch.from_numpy(b)] for w, b in self.layers],
            "log_std": None if self.log_std is None else torch.from_numpy(self.log_std),
            "normalizer": None if self.normalizer is None else self.normalizer.state(),
            "num_timesteps": self.num_timesteps,
            "encoder": None if self.encoder is None else self.encoder.module.state_dict(),
        }

    @classmethod
    def from_state(
        cls, state: dict[str, Any], normalizer: Normalizer | None, encoder: Any = None
    ) -> StudentSnapshot:
        """Rebuild from :meth:`state`; ``normalizer``: a copy to load the saved statistics into
        (the model's own, copied), or None; ``encoder``: a frozen copy of the model's CNN
        encoder to load the saved CNN into, or None."""
        if normalizer is not None:
            normalizer.set_state(state["normalizer"])
        if state.get("encoder") is not None and encoder is not None:
            encoder.module.load_state_dict(state["encoder"])
        else:
            encoder = None
        log_std = state["log_std"]
        return cls(
            [(w.numpy().copy(), b.numpy().copy()) for w, b in state["layers"]],
            None if log_std is None else log_std.numpy().copy(),
            normalizer,
            int(state["num_timesteps"]),
            encoder,
        )


class SoloEpisodes:
    """Decides, at every episode start, whether the student plays that episode alone, and
    (``teacher_share`` > 0) whether one teacher plays it alone instead of the high level's mix.

    ``window`` recent returns of solo and of assisted episodes (teacher-led ones included) are
    compared; the floor is the lowest mean of ``window`` solo returns seen so far, and
    :attr:`untrained` the mean of the first ``min_episodes`` (the untrained student's level,
    which a teacher's led episodes must beat to show help). Until ``min_episodes`` solo
    episodes have ended, competence counts as 0. A teacher-led episode's teacher is the one
    with the best UCB1 index over the returns of the earlier led episodes (the per-episode
    bandit of the paper's Figure 11 ablation, selectors.ucb1_scores), so the best teacher
    leads most of them.
    """

    def __init__(
        self,
        n_envs: int,
        budget: float,
        seed: int,
        window: int = 20,
        min_episodes: int = 5,
        n_teachers: int = 0,
        teacher_share: float = 0.0,
    ):
        self.budget = float(budget)
        self.teacher_share = float(teacher_share)
        self.leader = np.full(n_envs, -1, dtype=np.int64)  # the leading teacher; -1: none
        self.led_sums = np.zeros(n_teachers)  # per teacher: its led episodes' returns, summed
        self.led_squares = np.zeros(n_teachers)  # ... and their squares, summed
        self.led_counts = np.zeros(n_teachers, dtype=np.int64)
        # per teacher: gone now (its availability, a schedule or a function, is 0 at this
        # step, or the budget left no longer pays for its answers): the audition does not
        # wait for it (collect sets it; tlac.algorithms.advice)
        self.gone = np.zeros(n_teachers, dtype=bool)
        # per teacher: absent now (its availability is 0 at this step): neither awaited nor
        # judged (:attr:`no_teacher_helps`). One the budget no longer pays for is gone but
        # still judged: its answers paid for stay in the buffer, to be copied if it helped
        self.absent = np.zeros(n_teachers, dtype=bool)
        # per teacher: one that leads only when named from outside (a person, who leads by
        # taking an episode over: tlac.human): never awaited nor judged by the audition, never
        # picked to lead an episode here (collect sets it: outside_teachers)
        self.outside = np.zeros(n_teachers, dtype=bool)
        self.led_low, self.led_high = np.inf, -np.inf  # the range of led returns (UCB1's scale)
        self.active = np.zeros(n_envs, dtype=bool)
        self.rng = np.random.default_rng([seed, 0x501])  # its own stream: acting is untouched
        self.solo_returns: deque[float] = deque(maxlen=window)
        self.assisted_returns: deque[float] = deque(maxlen=window)
        self.min_episodes = min_episodes
        self.floor = np.inf
        # the mean of the first min_episodes solo returns: the untrained student's level, the
        # one a teacher's led episodes must beat to show help (_shows_help)
        self.untrained = np.inf
        self.untrained_se = 0.0  # the standard error of that mean (:attr:`shown_harm`)
        self.best_assisted = -np.inf
        self.best_solo = -np.inf  # the best mean of a full window of solo returns so far
        self.solo_episodes = 0  # solo episodes ended so far
        # per teacher: the information of its advice, summed over the rows it was asked, and
        # those rows (record_information)
        self.information_sums = np.zeros(n_teachers)
        self.information_rows = np.zeros(n_teachers)

    def _competence_against(self, reference: float) -> float:
        """The recent solo returns' competence against ``reference`` (0 until ``min_episodes``
        solo episodes have ended, or while the reference is not yet measured)."""
        if len(self.solo_returns) < self.min_episodes or not np.isfinite(reference):
            return 0.0
        return competence(float(np.mean(self.solo_returns)), reference, self.floor)

    @property
    def competence(self) -> float:
        return self._competence_against(self.best_assisted)

    @property
    def auditioning(self) -> bool:
        """With teacher-led episodes: True until the student's floor (``min_episodes`` solo
        episodes) and every teacher's own return (``MIN_LED_EPISODES`` led episodes) are
        measured. These first episodes are played in that order (:meth:`start`) and nothing is
        copied meanwhile (:attr:`weaning` 1): a teacher is copied only once it can be judged.
        A teacher gone now (:attr:`gone`: its availability schedule is at 0, or the budget
        no longer pays for its answers) is not waited for; one that arrives later (its
        schedule rises from 0) reopens the audition. A teacher that leads only when named
        from outside (:attr:`outside`: a person) is never waited for: with nobody at the page,
        the audition would never end.
        Before, the copy began at the first update, and one deterministic teacher that never
        reaches a sparse goal took the student's exploration away before it could be judged
        (Acrobot: the low level's entropy at 0.04 of 1.10 nats after 4k steps; the student
        alone at -500 where PPO alone reaches -83, issue 63)."""
        return (
            self.teacher_share > 0
            and self.budget > 0
            and (
                self.solo_episodes < self.min_episodes
                or bool(((self.led_counts < MIN_LED_EPISODES) & ~self.gone & ~self.outside).any())
            )
        )

    def record_information(self, information: np.ndarray, asked: np.ndarray | None = None) -> None:
        """Record how much each teacher's advice said: ``information`` ``(n_teachers, n)`` on
        the rows it was asked (``asked``, the same shape; None: every row)."""
        information = np.asarray(information, dtype=np.float64)
        rows = np.ones_like(information) if asked is None else np.asarray(asked, np.float64)
        self.information_sums += (information * rows).sum(axis=1)
        self.information_rows += rows.sum(axis=1)

    @property
    def says_nothing(self) -> np.ndarray:
        """``(n_teachers,)`` bools: True for a teacher whose advice, over every row it was
        asked, averaged at most ``SAYS_NOTHING`` information (a random teacher); False where
        it was never asked (not measured)."""
        asked = self.information_rows > 0
        mean = self.information_sums / np.maximum(self.information_rows, 1.0)
        return asked & (mean <= SAYS_NOTHING)

    @property
    def unmeasured_helpers(self) -> np.ndarray:
        """``(n_teachers,)`` bools: teachers whose led episodes show help but whose advice was
        never asked: the update asks them once (tlac.two_level.update), so that a teacher
        with nothing to copy is not trusted for its returns alone."""
        return self._shows_help() & (self.information_rows == 0)

    def _shows_help(self) -> np.ndarray:
        """``(n_teachers,)`` bools: judged (``MIN_LED_EPISODES`` led episodes or more) and led
        episodes above the untrained student's level (:func:`shows_help` against
        :attr:`untrained`, the mean of the first ``min_episodes`` solo returns, which the
        audition plays before any copy). Not against the floor (the lowest window of solo
        returns so far): a student's own returns can dip below where they began, and a useless
        teacher then beat that dip: on Pendulum an adversarial teacher's led episodes (-1505)
        beat a window at -1667 (seed 3), were copied, and held the student near -1600 to the
        end (-1767.5 where PPO alone reaches -1015.8; judged against the untrained student's
        -1390, -989.6)."""
        return self._judged_by(
            lambda total, squares, count: shows_help(total, squares, count, self.untrained)
        )

    @property
    def shown_harm(self) -> np.ndarray:
        """``(n_teachers,)`` bools: judged teachers whose led episodes are below the untrained
        student's level (:func:`shows_harm`); never one that leads only when named from outside
        (:attr:`outside`: a person). The update leaves them out of the copy
        (tlac.two_level.update): a copy that one teacher's help opens takes every teacher by
        the high level's trust, near uniform at first, and beside the near-optimal SAC actor
        (-137.3) its mirror image (led -1525 against the untrained student's -1100) took half
        of it: the student ended at -243.0 over 5 seeds where the actor beside a random
        teacher gave -151.9 (Pendulum, before cbd8f0f0; results/teacher-sweep/NOTES.md).
        Harm, not the absence of help: a random plain function in a discrete space reads as a
        point mass, so its labels are copied, and they are exploration the suites were measured
        with; a random teacher plays about as an untrained student, so it is mostly left in (read as
        harm in 7.9% of CartPole's draws: lab/harm_false_alarms.py)."""
        return (
            self._judged_by(
                lambda total, squares, count: shows_harm(
                    total, squares, count, self.untrained, self.untrained_se
                )
            )
            & ~self.outside
        )

    def _judged_by(self, judge: Callable[[float, float, int], bool]) -> np.ndarray:
        """``(n_teachers,)`` bools: ``judge`` of every teacher's led returns (their sum, sum of
        squares and count), for teachers with ``MIN_LED_EPISODES`` led episodes or more; False
        for the others and before the untrained student's level is measured."""
        out = np.zeros(len(self.led_counts), dtype=bool)
        if not np.isfinite(self.untrained):
            return out
        for k, (total, squares, count) in enumerate(
            zip(self.led_sums, self.led_squares, self.led_counts, strict=True)
        ):
            out[k] = count >= MIN_LED_EPISODES and judge(total, squares, int(count))
        return out

    @property
    def no_teacher_helps(self) -> bool:
        """Every teacher has led ``MIN_LED_EPISODES`` episodes or more, and none of them both
        showed a return above the untrained student's (:meth:`_shows_help`) and has something to
        copy (not :attr:`says_nothing`): what the teachers do alone, the untrained student
        does already, or what they do cannot be copied. A teacher that never reaches a sparse
        goal, or an adversarial one, would otherwise be copied in full (its led episodes at the
        floor read as "no evidence yet"), and the copy takes away the random exploration that
        gives the student its first successes (Acrobot, a teacher that never swings up: -500
        against PPO alone's -82, issue 63). A random teacher's led episodes can beat an
        untrained student (Pendulum), but nothing of it can be copied: judged to help, it took
        the episodes the student would have played alone, and its trust went to the untrained
        actor beside it (seed 1: -1200.8 where PPO alone reaches -911.6). A teacher absent
        now (:attr:`absent`) or one that leads only when named from outside (:attr:`outside`:
        a person) is not judged; one the budget no longer pays for is."""
        here = ~self.absent & ~self.outside
        if (
            self.teacher_share <= 0
            or not np.isfinite(self.untrained)
            or not here.any()
            or (self.led_counts[here] < MIN_LED_EPISODES).any()
        ):
            return False
        return not (self._shows_help() & ~self.says_nothing)[here].any()

    @property
    def weaning(self) -> float:
        """Competence against the best teacher ALONE (the mean return of its led episodes),
        the weight the imitation loses (``wean_imitation``); :attr:`competence` (against the
        assisted episodes) while no teacher has led one (no teacher-led episodes); 1 (nothing
        copied) while :attr:`auditioning` and when :attr:`no_teacher_helps`."""
        if self.auditioning or self.no_teacher_helps:
            return 1.0
        led = (self.led_counts > 0) & ~self.says_nothing  # a teacher with something to copy
        if not led.any():
            return self.competence
        return self._competence_against(float(np.max(self.led_sums[led] / self.led_counts[led])))

    @property
    def probability(self) -> float:
        """The share of episodes the student plays alone: :func:`solo_probability` of its
        competence; when :attr:`no_teacher_helps`, all but ``RECHECK_SHARE`` of them (the others
        led by a teacher: :meth:`start`) until its solo returns beat every teacher's led ones,
        then every one; while :attr:`auditioning`, 1 until the floor is measured, then 0."""
        if self.auditioning:
            return float(self.solo_episodes < self.min_episodes)
        if self.no_teacher_helps:
            return 1.0 if self._solo_beats_every_led_mean() else 1.0 - RECHECK_SHARE
        return solo_probability(self.competence, self.budget)

    def _solo_beats_every_led_mean(self) -> bool:
        """Whether the recent solo returns' mean is above every teacher's led mean: a teacher
        can show nothing the student needs any more (a useless teacher's led episodes, played
        to the time limit, would otherwise cost ever more steps as the student's get shorter)."""
        led_means = self.led_sums / np.maximum(self.led_counts, 1)
        led_means = led_means[~self.outside]  # a person is not judged (:attr:`outside`)
        return (
            bool(self.solo_returns)
            and len(led_means) > 0
            and float(np.mean(self.solo_returns)) > led_means.max()
        )

    def start(self, episode_starts: np.ndarray, can_lead: np.ndarray | None = None) -> np.ndarray:
        """Draw solo or assisted for every environment whose episode starts now; returns the
        per-environment solo flags. ``can_lead`` ``(n_envs, n_teachers)``: the teachers that
        can answer in each environment now (present, within the advice budget;
        tlac.algorithms.advice); only they lead, and where none can, the episode is not led.
        None: every teacher can (the run without advice limits, drawing as before). A teacher
        that leads only when named from outside (:attr:`outside`) is never picked here."""
        starting = np.flatnonzero(episode_starts)
        if self.outside.any():
            can_lead = ~self.outside if can_lead is None else can_lead & ~self.outside
            can_lead = np.broadcast_to(can_lead, (len(self.active), len(self.outside)))
        if len(starting) and self.auditioning:
            for i in starting:  # the student alone until its floor is known, then each teacher
                self.active[i] = self.solo_episodes < self.min_episodes
                can = None if can_lead is None else can_lead[i]
                self.leader[i] = -1 if self.active[i] else self._least_led_teacher(can)
        elif len(starting):
            self.active[starting] = self.rng.random(len(starting)) < self.probability
            if self.teacher_share > 0:  # (no draw otherwise: the same stream as before)
                # where no teacher has shown help, every episode the student does not play is
                # led by one, so that the teachers' evidence keeps coming (RECHECK_SHARE)
                share = 1.0 if self.no_teacher_helps else self.teacher_share
                for i in starting:
                    led = not self.active[i] and self.rng.random() < share
                    can = None if can_lead is None else can_lead[i]
                    self.leader[i] = self._ucb1_teacher(can) if led else -1
        return self.active

    def _least_led_teacher(self, can: np.ndarray | None = None) -> int:
        """The teacher that has led the fewest episodes (ties at random), among those that
        ``can`` lead (None: all; -1 where none can)."""
        if can is not None and not can.any():
            return -1
        counts = self.led_counts if can is None else np.where(can, self.led_counts, np.inf)
        fewest = np.flatnonzero(counts == counts.min())
        return int(self.rng.choice(fewest))

    def _ucb1_teacher(self, can: np.ndarray | None = None) -> int:
        """The teacher to lead an episode: the best UCB1 index, ties (untried ones) at random,
        among those that ``can`` lead (None: all; -1 where none can)."""
        spread = self.led_high - self.led_low if self.led_high > self.led_low else 1.0
        scores = ucb1_scores(self.led_sums, self.led_counts, 1.0, spread)
        if can is not None:
            if not can.any():
                return -1
            scores = np.where(can, scores, -np.inf)
        return int(self.rng.choice(np.flatnonzero(scores == scores.max())))

    def end(self, env_index: int, episode_return: float) -> bool:
        """Record a finished episode's return. True when it was a solo episode after which the
        student is worth deploying (:func:`worth_deploying` on the window of solo returns)."""
        if self.active[env_index]:
            self.solo_episodes += 1
            self.solo_returns.append(float(episode_return))
            if len(self.solo_returns) >= self.min_episodes:
                self.floor = min(self.floor, float(np.mean(self.solo_returns)))
                if not np.isfinite(self.untrained):
                    self.untrained = float(np.mean(self.solo_returns))
                    spread = float(np.std(self.solo_returns))
                    self.untrained_se = spread / float(np.sqrt(len(self.solo_returns)))
            return self.latest_is_worth_deploying()
        else:
            teacher = self.leader[env_index]
            if teacher >= 0:
                self.led_sums[teacher] += episode_return
                self.led_squares[teacher] += episode_return**2
                self.led_counts[teacher] += 1
                self.led_low = min(self.led_low, float(episode_return))
                self.led_high = max(self.led_high, float(episode_return))
            self.assisted_returns.append(float(episode_return))
            if len(self.assisted_returns) >= self.min_episodes:
                self.best_assisted = max(self.best_assisted, float(np.mean(self.assisted_returns)))
        return False

    def latest_is_worth_deploying(self) -> bool:
        """Whether the student that played the recent solo episodes is worth deploying
        (:func:`worth_deploying` on a full window of solo returns; updates the best mean)."""
        if len(self.solo_returns) < self.solo_returns.maxlen:
            return False
        n_windows = self.solo_episodes / len(self.solo_returns)
        deploy, self.best_solo = worth_deploying(self.solo_returns, self.best_solo, n_windows)
        return deploy


class AdviceBuffer:
    """The aggregated data set of DAgger (Ross et al. 2011): every state the student met in
    training, with what each teacher advises there, in a ring of ``capacity`` rows. The
    imitation term samples its minibatches here rather than from the latest rollout alone:
    16 consecutive, strongly correlated states repeated for 5 epochs are a poor data set to
    fit a policy to (docs/graduation.md measures the difference).

    >>> buf = AdviceBuffer(capacity=3, obs_dim=2, advice_shape=(2,), advice_dtype=torch.int64)
    >>> buf.add(torch.ones(2, 2), torch.tensor([[0, 1], [4, 5]]))   # 2 teachers, 2 states
    >>> # the 4th state overwrites the 1st:
    >>> buf.add(torch.ones(2, 2), torch.tensor([[2, 3], [6, 7]]))
    >>> len(buf), buf.advice[:, 0].tolist(), buf.advice[:, 1].tolist()
    (3, [3, 1, 2], [7, 5, 6])
    """

    def __init__(
        self,
        capacity: int,
        obs_dim: int,
        advice_shape: tuple[int, ...],
        advice_dtype: torch.dtype,
        obs_dtype: torch.dtype | None = None,
        track_labels: bool = False,
    ):
        # obs_dtype (a Discrete, Dict or image space's: uint8 for images, 12,288 values a row
        # at 64x64x3) is left unwritten: no page of the ring is touched before a state lands
        # there, and no unwritten row is read; None: float32 zeros, as for a Box
        self.obs = (
            torch.zeros(capacity, obs_dim)
            if obs_dtype is None
            else torch.empty(capacity, obs_dim, dtype=obs_dtype)
        )
        self.advice = torch.zeros(capacity, *advice_shape, dtype=advice_dtype)
        # track_labels (advice limited by a budget, availability or an asking rule): which
        # teachers were asked in each row; the others' advice there is a placeholder that the
        # imitation term weighs 0 (tlac.two_level.fast.replay_plan). None: every teacher
        # labels every row
        self.labelled = (
            torch.zeros(capacity, advice_shape[0], dtype=torch.bool) if track_labels else None
        )
        self.capacity = capacity
        self.size = 0
        self.next = 0

    def __len__(self) -> int:
        return self.size

    def add(
        self, obs: torch.Tensor, advice: torch.Tensor, labelled: torch.Tensor | None = None
    ) -> None:
        """``obs`` ``(n, obs_dim)``; ``advice`` ``(n_teachers, n, ...)`` as the update has it;
        ``labelled`` ``(n, n_teachers)``: the teachers asked in each row (with track_labels)."""
        advice = advice.transpose(0, 1)[-self.capacity :]
        obs = obs[-self.capacity :].to(self.obs.dtype)
        slots = (self.next + torch.arange(len(obs))) % self.capacity
        self.obs[slots] = obs
        self.advice[slots] = advice
        if self.labelled is not None:
            assert labelled is not None, "a buffer that tracks labels needs them"
            self.labelled[slots] = labelled[-self.capacity :]
        self.next = int(slots[-1] + 1) % self.capacity
        self.size = min(self.size + len(obs), self.capacity)

    def sample(self, n: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """``n`` rows drawn uniformly with replacement: ``(obs (n, obs_dim), advice
        (n_teachers, n, ...))``."""
        idx = torch.randint(self.size, (n,), generator=generator)
        return self.obs[idx], self.advice[idx].transpose(0, 1)


def make_solo(cfg: TLACConfig, n_envs: int, seed: int, n_teachers: int) -> SoloEpisodes | None:
    """The graduate variant's solo (and teacher-led) episodes under the settings ``cfg``; None
    without a solo budget or without teachers."""
    if not (cfg.solo_budget and n_teachers):
        return None
    # ask learned on a budget: the high level's choices are the only asks. A teacher-led
    # episode asks in every state whatever the price (on CartPole, 500 answers an episode:
    # the audition's first two would spend a budget of 1e3), so there is none
    teacher_share = cfg.teacher_episodes
    if cfg.advice.ask == "learned" and cfg.advice.advice_budget is not None:
        teacher_share = 0.0
    return SoloEpisodes(
        n_envs, cfg.solo_budget, seed, n_teachers=n_teachers, teacher_share=teacher_share
    )


def plays_solo_greedily(cfg: TLACConfig, discrete: bool) -> bool:
    """Whether the student plays its solo episodes greedily: with Box actions, where the low
    level learns by imitation (low_level_data "silent"). Imitation fits its Gaussian's mean and
    leaves its noise untrained (a fixed-variance likelihood), so a sampled solo episode
    measures that noise rather than the student a user deploys (hopper, seed 0: the live
    student 593 greedy against 100 sampled; the kept student, chosen on sampled solo returns,
    stayed at 190 while the live one reached 2170)."""
    return not discrete and bool(cfg.solo_budget) and cfg.low_level_data == "silent"


def hands_over(cfg: TLACConfig, discrete: bool, solo: SoloEpisodes | None) -> bool:
    """Whether weaned imitation hands a discrete student over to its own policy gradient
    with an entropy bonus that grows with its competence (:func:`handover_entropy_coef`)."""
    return discrete and cfg.wean_imitation and solo is not None
