"""TL-AC's settings: :class:`TLACConfig` (every setting of the paper's Tables 5, 8 and 10, and
the graduate variant's), the two variants' defaults, and the translations from a domain's
preset and from SB3's ``policy_kwargs``.

>>> TLACConfig(variant="paper").kl_rows, TLACConfig().distill_coef
('all', 1.0)
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from tlac.algorithms.advice import ASK_RULES
from tlac.algorithms.encoding import ENCODINGS
from tlac.domains import domain_names, get_domain
from tlac.errors import ConfigError, UnknownNameError
from tlac.presets import (
    DEFAULT_VARIANT,
    availability_problem,
    load_preset,
    settle_variant_values,
    validate_schedule,
)
from tlac.selectors import SELECTOR_NAMES
from tlac.validation import Checks, from_mapping

Schedule = float | dict | Callable[[float], float]
"""A number, ``{linear: [start, end]}`` or (from Python) SB3's ``Schedule``, a function of the
progress remaining (1 -> 0); a model file keeps a function's value at save time
(:meth:`tlac.two_level.model.TLAC.save`)."""

SCHEDULES = ("learning_rate", "clip_range", "target_kl", "distill_coef")
"""The settings that take a schedule."""

VARIANT_DEFAULTS: dict[str, dict[str, Any]] = {
    "graduate": {
        "distill_coef": 1.0,
        # the low level learns from the imitation term, and from its own returns only in the
        # states where every teacher is silent (uniform) ("agent" was measured worse on
        # DoorKey; docs/graduation.md)
        "low_level_data": "silent",
        "solo_budget": 0.05,
        "kl_rows": "high",
        "obs_encoding": "auto",
        # a capped entropy bonus on the high level: without it, partial teachers (L + R)
        # collapse the high level onto one teacher (docs/graduation.md)
        "ent_coef_high": 0.03,
        "ent_cap_high": 0.5,
        "update_rule": "joint",
    },
    "paper": {
        "distill_coef": 0.0,
        "low_level_data": "all",
        "solo_budget": 0.0,
        # the low level's KL over ALL rows, as an implementation on SB3's PPO computes it (the
        # paper's tables are SB3's settings); "agent" was the default until issue 9 measured
        # that it lets pi_low's entropy collapse with imperfect teachers (docs/reproduction.md)
        "kl_rows": "all",
        "obs_encoding": "raw",
        "ent_cap_high": 0.0,  # no cap (ent_coef_high stays the preset's, ent_coef)
        # each level as its own SB3 policy: its own gradient clip and target-KL stop (the
        # paper's tables give each level's settings apart); "joint" was the rule until
        # 2026-11-26 (docs/reproduction.md, "One update per level")
        "update_rule": "per_level",
    },
}
"""What each TL-AC variant sets when the corresponding setting is left at None."""


@dataclass(frozen=True)
class AdviceSettings:
    """Advice that costs (issue 66; tlac.algorithms.advice, docs/advice.md): TLACConfig's
    ``advice``. Its fields are TL-AC settings by their own names (``TLAC(...,
    advice_budget=1000)``, ``--set ask=importance``); the defaults leave the run as it was
    before budgets existed, byte for byte (answers are only counted)."""

    advice_budget: float | None = None
    """The run's advice budget, in cost units (with every teacher's cost 1: answers). An answer
    is one teacher consulted in one collected state, counted once whether it is used to act,
    stored as an imitation label, or both; once no teacher's answer fits in what is left, no
    teacher is asked again and the student acts alone (tlac.algorithms.advice,
    docs/advice.md). None: no limit (answers are still counted)."""
    teacher_cost: dict[str, float] = field(default_factory=dict)
    """Each teacher's cost per answer, by name (a name shared by several teachers, ``random``
    for ``random_1`` and ``random_2``, sets them all); a teacher left out costs 1. Only the
    budget reads it."""
    availability: dict[str, Any] = field(default_factory=dict)
    """Each teacher's chance, by name, to be present in an episode (drawn per episode and
    environment, at its start, from a random stream of its own); a teacher left out is always
    present. A number in (0, 1]; or a chance that changes over the run, in [0, 1] (0: absent
    from then on): ``{linear: [start, end]}`` over the ``learn`` call's progress (as
    learning_rate's), ``{steps: [[0, 1.0], [20000, 0.0]]}`` piecewise constant in the
    environment step (``num_timesteps``), or, from Python, a function of that step
    (``lambda step: 1.0 if step < 20_000 else 0.0``; a model file keeps its value at save
    time). An absent teacher can neither be chosen by the high level nor give a label."""
    ask: str | None = None
    """In which states the student asks its teachers (tlac.algorithms.advice.ask_gate): always
    (every state; the paper's), early (every state while the budget lasts:
    Torrey & Taylor 2013's early advising), importance (where the spread of the student's own
    action logits is at least ask_threshold: Amir et al. 2016's ask-important) or uncertainty
    (where its policy's normalised entropy is at least ask_threshold: their ask-uncertain),
    learned (the high level's choice of a teacher is the ask; on a budget its price, paced
    over the run, is charged in the high level's logits, and no episode is teacher-led) or
    mistake (in the states importance flags, the teacher checks the student's action: a label
    only where it disagrees; Torrey & Taylor 2013's mistake correcting). importance,
    uncertainty and mistake need discrete actions. Where the student does not ask, it acts and
    no label is stored; a teacher-led episode's teacher is asked in every state. None (the
    default): learned on a budget with the learned high level (it paces its answers over the
    run: issue 66's measurements in docs/advice.md), else always (without a budget every
    state is asked, as before budgets existed; a random or UCB1 selector has no logits to
    price)."""
    ask_threshold: float | None = None
    """The threshold of ask importance and mistake (nats of logit spread; None: 1.0) or
    uncertainty (a share of the largest entropy, in [0, 1]; None: 0.5). Under ask learned the
    high level may ask only where importance flags the state; None: 1.0 where answers are
    scarce (a budget of fewer than 1 answer per 100 steps) and actions discrete, else every
    state (tlac.algorithms.advice.learned_threshold); 0: every state."""

    def __post_init__(self) -> None:
        check = Checks("TL-AC")
        if self.advice_budget is not None:
            check.number("advice_budget", self.advice_budget, 0.0)
        for name, cost in self.teacher_cost.items():
            check.number(f"teacher_cost[{name!r}]", cost, 0.0)
        for name, chance in self.availability.items():
            if is_constant(chance):
                # (0: never present, never judged by the graduate variant's audition: leave
                # it out; a schedule may reach 0, the teacher then leaves)
                check.number(f"availability[{name!r}]", chance, 0.0, 1.0, open_low=True)
            elif (expected := availability_problem(chance)) is not None:
                raise check.error(f"availability[{name!r}]", expected, chance)
        if self.ask is not None:
            check.one_of("ask", self.ask, ASK_RULES)
        if self.ask_threshold is not None:
            high = 1.0 if self.ask == "uncertainty" else math.inf
            check.number("ask_threshold", self.ask_threshold, 0.0, high)

    @classmethod
    def from_settings(cls, settings: dict[str, Any]) -> AdviceSettings:
        """Built and checked from its fields by name (an unknown one: a ConfigError naming it)."""
        if not isinstance(settings, dict):
            raise ConfigError(f"TL-AC setting advice must be a mapping, got {settings!r:.60}")
        return from_mapping(cls, "TL-AC advice", settings)

    @property
    def limits(self) -> bool:
        """Whether advice is limited: a budget, a teacher not always present (a schedule or a
        function counts, whatever its values), or an asking rule other than always. Without,
        the run is the one before budgets existed, byte for byte (answers are only counted)."""
        return (
            self.advice_budget is not None
            or any(not is_constant(p) or p < 1 for p in self.availability.values())
            or self.ask not in (None, "always")
        )


def default_ask(advice_budget: float | None, selector: str) -> str:
    """The asking rule a run gets when it names none: ``learned`` on a budget with the learned
    high level, which paces its answers over the run (the budget is not spent in the first
    episodes), else ``always``.

    >>> default_ask(None, "learned"), default_ask(1000, "learned"), default_ask(1000, "ucb1")
    ('always', 'learned', 'always')
    """
    return "learned" if advice_budget is not None and selector == "learned" else "always"


def is_constant(availability: Any) -> bool:
    """Whether an availability is a number (not a schedule nor a function)."""
    return isinstance(availability, numbers.Real) and not isinstance(availability, bool)


ADVICE_SETTINGS = tuple(AdviceSettings.__dataclass_fields__)
"""The settings :class:`AdviceSettings` holds, each also a TL-AC setting by its own name."""


def fold_advice_settings(settings: dict[str, Any]) -> dict[str, Any]:
    """``settings`` with the advice settings given by name (``advice_budget``...) moved into
    ``advice``, where those given as a mapping already are (one given both ways: the name wins).

    >>> fold_advice_settings({"n_steps": 8, "advice_budget": 100})
    {'n_steps': 8, 'advice': {'advice_budget': 100}}
    """
    named = {k: v for k, v in settings.items() if k in ADVICE_SETTINGS}
    if not named:
        return settings
    given = settings.get("advice", {})
    if isinstance(given, AdviceSettings):
        given = {k: getattr(given, k) for k in ADVICE_SETTINGS}
    if not isinstance(given, dict):
        raise ConfigError(f"TL-AC setting advice must be a mapping, got {given!r:.60}")
    rest = {k: v for k, v in settings.items() if k not in ADVICE_SETTINGS and k != "advice"}
    return {**rest, "advice": {**given, **named}}


@dataclass(frozen=True)
class TLACConfig:
    """TL-AC's settings. Defaults are the paper's DoorKey preset (Table 5). Frozen and checked
    when made (``__post_init__``: the variant's defaults, then :meth:`validate`), as every
    tlac config (:mod:`tlac.validation`)."""

    n_steps: int = 16
    """Steps collected per environment before each update (Algorithm 1's minibatch M)."""
    batch_size: int = 16
    """Minibatch size of the gradient steps; at most n_steps * n_envs."""
    n_epochs: int = 5
    """Passes over each rollout (Algorithm 1, line 5)."""
    learning_rate: Schedule = 7e-4
    """Number, {linear: [start, end]} (the end may be 0) or, from Python, a function of the
    progress remaining (SB3's ``Schedule``, e.g. ``lambda p: 3e-4 * p``)."""
    clip_range: Schedule = 0.2
    """PPO clip range of both levels' ratios; a schedule as learning_rate."""
    target_kl: Schedule | None = 0.02
    """Stop before a gradient step once a level's approximate KL exceeds 1.5x this (SB3's
    rule): with update_rule joint, the larger of the two levels' KL stops the whole update;
    with per_level, each level stops on its own KL."""
    ent_coef: float = 0.0
    """Entropy bonus of the low level, and of the high level unless ent_coef_high is given."""
    ent_coef_high: float | None = None
    """Entropy bonus of the high level. None: ent_coef."""
    ent_cap_high: float | None = None
    """With a high-level entropy bonus: each state's entropy counts only up to this many nats,
    so the bonus keeps the high level from collapsing without pushing it towards uniform
    choices (0: no cap). None: the variant's (graduate 0.5, paper 0). The graduate variant
    also sets ent_coef_high to 0.03 when the preset leaves it unset (docs/graduation.md)."""
    vf_coef: float = 0.5
    """Weight of the critic's loss in the update."""
    max_grad_norm: float = 0.5
    """Gradient-norm clipping: of all three networks' gradient together (update_rule joint),
    or of each network's own (per_level)."""
    update_rule: str | None = None
    """How one minibatch's gradient step treats the three networks. joint: one loss, one
    global gradient-norm clip, and one target-KL stop (the larger level KL) for everything.
    per_level: as two SB3 policies sharing a critic would run: each network's gradient is
    clipped to max_grad_norm on its own, a level whose KL exceeds 1.5x target_kl takes no
    more steps in this update (its weights and optimiser statistics stay as they were), and
    the critic steps while either level still does. None: the variant's (graduate joint,
    paper per_level; docs/reproduction.md, "One update per level")."""
    gamma: float = 0.99
    """Discount."""
    gae_lambda: float = 0.85
    """GAE(lambda); 0 gives the paper's one-step advantage (Eq. 2) exactly."""
    normalize_advantage: bool = True
    """Normalise each minibatch's advantages (as SB3's PPO)."""
    optimizer: str = "rmsprop_tf"
    """rmsprop_tf (SB3's RMSpropTFLike, the paper's) or adam."""
    optimizer_eps: float = 1e-5
    """Epsilon of the optimizer (rmsprop_tf or adam)."""
    use_sde: bool = False
    """Generalized state-dependent exploration for Box actions (Tables 8, 10)."""
    sde_sample_freq: int = -1
    """Resample the gSDE noise every this many steps (-1: once per rollout)."""
    log_std_init: float = 0.0
    """Initial log std of the low level's Gaussian (Box actions)."""
    ortho_init_high: bool = True
    """Orthogonal initialisation of the high level (SB3's ortho_init)."""
    ortho_init_low: bool = True
    """Orthogonal initialisation of the low level and of the critic (which estimates
    V_pi_low, Eq. 1)."""
    net_arch_high: list[int] = field(default_factory=lambda: [64, 64])
    """Hidden layers of the high-level actor (all three networks have the same depth)."""
    net_arch_low: list[int] = field(default_factory=lambda: [64, 64])
    """Hidden layers of the low-level actor (the student)."""
    net_arch_critic: list[int] = field(default_factory=lambda: [64, 64])
    """Hidden layers of the shared critic."""
    variant: str = DEFAULT_VARIANT
    """graduate (the default): the paper's TL-AC plus what makes the student act well ALONE
    (imitation of the teachers the high level trusts, solo episodes, on-policy low-level
    gradients, one-hot integer observations; docs/graduation.md). paper: Algorithm 1 exactly,
    for reproductions. The variant only sets the settings listed in VARIANT_DEFAULTS that are
    left at None; any of them can still be set by hand."""
    distill_coef: Schedule | None = None
    """Weight of the low level's imitation of the teachers, each weighted per state by the high
    level's probability of choosing it among the teachers, and by how much its advice says there
    (discrete actions: its whole distribution over actions as the label, and its trust times
    ``1 - entropy / log n_actions``, so that a random teacher's advice weighs nothing:
    losses.informative_trust; Box actions: a Gaussian of standard deviation 0.1 action-box
    half-widths around the low level's mean, losses.scaled_squared_error); number or
    {linear: [start, end]}. None: the variant's (graduate 1.0, paper 0; docs/graduation.md)."""
    imitation_buffer_size: int = 50_000
    """States (with every teacher's advice) kept for the imitation term (DAgger's data set)."""
    imitation_batch_size: int = 64
    """Replayed states in each gradient step's imitation term."""
    solo_budget: float | None = None
    """Graduation by solo episodes: an episode is played by the student alone with probability
    min(1, solo_budget / (1 - competence)), competence measured from recent solo and assisted
    returns (tlac.two_level.graduation), so solo play costs the training return about
    solo_budget of the teachers' margin. ``predict`` (the student a user deploys) uses a
    kept student, renewed when its window of 20 solo returns, and that window's latest 5, are
    not clearly below the best such window so far (tlac.two_level.graduation.worth_deploying),
    as the student that collected the last rollout (one update behind the live weights), rather
    than whatever the last update left. None: the variant's (graduate 0.05, paper 0: no solo
    episodes, and ``predict`` uses the live weights)."""
    normalize_obs: bool | str = False
    """Normalise the networks' observations by their running mean and std (SB3's VecNormalize,
    clipped to +-10), inside TL-AC: teachers still see raw observations. true: refused where
    observations are one-hot encoded or images (categories and pixels have no scale); auto:
    on where the networks read the observations raw, except a Box whose bounds declare every
    coordinate's half-range between 1 and 10 (Pendulum's; ``declares_unit_scale``), off
    elsewhere (presets/default.yaml)."""
    normalize_reward: bool = False
    """Divide training rewards by the running std of the discounted return (SB3's
    VecNormalize); logged returns stay raw."""
    wean_imitation: bool = False
    """With solo episodes: multiply the imitation weight by ``1 - competence``, competence
    measured against the best teacher alone (its teacher-led episodes; the assisted returns
    until one is led: SoloEpisodes.weaning), so that the student stops copying its teachers as
    its solo episodes match the best of them, and copies again if it falls back
    (Kickstarting's annealing, Schmitt et al. 2018, driven by the student's measured
    competence rather than by time). On in the preset of a user's environment
    (presets/default.yaml), with low_level_data agent: there the student's own policy gradient
    takes over as the imitation fades, so it can learn past a weak teacher
    (docs/graduation.md). With discrete actions the low level's entropy bonus then grows by
    0.05 x that competence (graduation.handover_entropy_coef): a copy of one deterministic
    teacher leaves that policy gradient almost nothing to sample. Off in both variants: with the
    imitation term alone RMSprop normalises a slowly varying scale away."""
    teacher_episodes: float = 0.0
    """With solo episodes: the share of the other episodes that one teacher plays alone from
    start to end ("teacher-led"), the teacher picked by UCB1 over the returns of its earlier
    led episodes (tlac.two_level.graduation.SoloEpisodes). They show what each teacher reaches
    on its own (weaned imitation measures the student against the best of them), and their
    rows train the high level like its own choices, so it learns whom to follow where per-step
    mixing never completes a task (MountainCar). The first episodes audition: the student
    alone until its floor is measured, then each teacher leads 3, and under wean_imitation
    nothing is copied until then (SoloEpisodes.auditioning). 0: none (both variants);
    presets/default.yaml sets it (docs/graduation.md)."""
    kl_rows: str | None = None
    """Which rows give the low level's approximate KL for the target-KL stop: agent (where the
    agent acted: pi_low's own samples), all (every row, as a PPO built on SB3 computes it) or
    high (none: only the high level's KL stops the epochs, since the imitation term moves
    pi_low on purpose; without an imitation term it acts as agent). None: the variant's
    (graduate high, paper all)."""
    obs_encoding: str | None = None
    """raw, onehot (each integer observation dimension as indicators) or auto (onehot for an
    integer-dtype Box with small ranges, else raw; tlac.algorithms.encoding). None: the
    variant's (graduate auto, paper raw)."""
    low_level_data: str | None = None
    """Which transitions train the low level's policy gradient: all (the paper, Eq. 3 on every
    executed action), agent (only where it acted, so every ratio is an importance weight of
    pi_low's own samples; the preset of a user's environment) or silent (the agent's rows in the
    states where every teacher's advice is uniform, losses.silent_states: a random teacher, a
    partial one outside its region, so the student learns from its own returns where no teacher
    knows the way; elsewhere the imitation term alone trains the low level. Before the imitation
    term holds advice, and without teachers, the agent's rows; with Box actions no state is
    silent). None: the variant's (graduate silent, paper all)."""
    advice: AdviceSettings = field(default_factory=AdviceSettings)
    """Advice that costs (:class:`AdviceSettings`; docs/advice.md): given by the names of its
    fields, as every other setting (``advice_budget=1000``, ``--set ask=importance``), or as a
    mapping of them (``advice: {advice_budget: 1000}``)."""
    selector: str = "learned"
    """High level: learned (TL-AC), random or ucb1 (per episode) -- the Figure 11 ablations."""
    n_envs: int = 1
    """Parallel environments, used only when TLAC makes the environments from a name (a domain
    or a Gymnasium id); given by name with an environment already made, it must match it."""
    vec_env: str = "dummy"
    """How TLAC steps those environments: dummy (in this process, SB3's DummyVecEnv; needed for
    an exact resume) or subproc (one process each, SB3's SubprocVecEnv; for slow
    environments). Used only when TLAC makes the environments from a name (a domain or a
    Gymnasium id); subproc given by name with an environment already made is refused, unless
    that is a SubprocVecEnv."""

    def __post_init__(self) -> None:
        if isinstance(self.advice, dict):  # from a file or a saved model: its fields by name
            object.__setattr__(self, "advice", AdviceSettings.from_settings(self.advice))
        elif not isinstance(self.advice, AdviceSettings):
            raise ConfigError(
                f"TL-AC setting advice must be a mapping of {', '.join(ADVICE_SETTINGS)}, "
                f"got {self.advice!r:.60}"
            )
        if self.variant not in VARIANT_DEFAULTS:
            raise UnknownNameError("variant", self.variant, list(VARIANT_DEFAULTS))
        for name, value in VARIANT_DEFAULTS[self.variant].items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)  # frozen: only while it is being made
        if self.advice.ask is None:
            ask = default_ask(self.advice.advice_budget, self.selector)
            object.__setattr__(self, "advice", dataclasses.replace(self.advice, ask=ask))
        self.validate()

    @classmethod
    def from_settings(cls, settings: dict[str, Any]) -> TLACConfig:
        """Build and validate a config; unknown keys or bad values raise ConfigError."""
        settings = settle_variant_values(settings)
        return from_mapping(cls, "TL-AC", fold_advice_settings(settings))

    @property
    def entropy_coefs(self) -> tuple[float, float]:
        """The entropy bonus of (the low level, the high level): ``ent_coef``, and
        ``ent_coef_high`` for the high level where set."""
        return (self.ent_coef, self.ent_coef if self.ent_coef_high is None else self.ent_coef_high)

    def validate(self) -> None:
        """Raise ConfigError naming the first setting out of its range (run when the config
        is made; a frozen config stays valid)."""
        check = Checks("TL-AC")
        for name in (
            "n_steps",
            "batch_size",
            "n_epochs",
            "n_envs",
            "imitation_buffer_size",
            "imitation_batch_size",
        ):
            check.positive_int(name, getattr(self, name))
        for name in ("learning_rate", "clip_range", "distill_coef"):
            validate_schedule(name, getattr(self, name))
        if self.target_kl is not None:
            validate_schedule("target_kl", self.target_kl)
        for name in ("gamma", "gae_lambda"):
            check.number(name, getattr(self, name), 0.0, 1.0)
        for name in (
            "vf_coef",
            "max_grad_norm",
            "ent_coef",
            "optimizer_eps",
            "ent_cap_high",
            "solo_budget",
        ):
            check.number(name, getattr(self, name), 0.0)
        check.number("teacher_episodes", self.teacher_episodes, 0.0, 1.0)

        if self.normalize_obs not in (True, False, "auto"):
            raise ConfigError(
                "TL-AC setting normalize_obs must be true, false or 'auto', "
                f"got {self.normalize_obs!r}"
            )
        if self.teacher_episodes > 0 and not self.solo_budget:
            raise ConfigError(
                "TL-AC setting teacher_episodes needs solo episodes (solo_budget > 0), "
                f"got teacher_episodes {self.teacher_episodes} with solo_budget {self.solo_budget}"
            )
        if self.advice.ask_threshold is not None and self.advice.ask in ("always", "early"):
            raise ConfigError(
                f"TL-AC setting ask_threshold gates the asks of importance, uncertainty, mistake "
                f"and learned; ask {self.advice.ask!r} asks in every state (the default where no "
                "ask is named, but with a budget and the learned selector): expected one of "
                "those rules, or no ask_threshold"
            )
        if self.advice.ask == "learned" and self.selector != "learned":
            raise ConfigError(
                f"TL-AC setting ask 'learned' prices the learned high level's choices; selector "
                f"{self.selector!r} reads no logits, so nothing would pace the answers: expected "
                "selector learned, or another ask (always, early, importance, uncertainty, mistake)"
            )
        for name, accepted in (
            ("optimizer", ["rmsprop_tf", "adam"]),
            ("update_rule", ["joint", "per_level"]),
            ("kl_rows", ["agent", "all", "high"]),
            ("obs_encoding", list(ENCODINGS)),
            ("low_level_data", ["all", "agent", "silent"]),
            ("vec_env", ["dummy", "subproc"]),
            ("selector", list(SELECTOR_NAMES)),
        ):
            check.one_of(name, getattr(self, name), accepted)
        depths = {len(self.net_arch_high), len(self.net_arch_low), len(self.net_arch_critic)}
        if len(depths) != 1 or 0 in depths:
            raise ConfigError(
                "net_arch_high, net_arch_low and net_arch_critic must have the same, non-zero "
                "number of layers (widths may differ), got "
                f"{self.net_arch_high}, {self.net_arch_low}, {self.net_arch_critic}"
            )


def domain_preset(name: str) -> dict[str, Any]:
    """The TL-AC settings of a named domain's preset (paper Tables 5, 8, 10)."""
    domain = get_domain(name)
    return load_preset(domain.presets["tlac"], "tlac") if "tlac" in domain.presets else {}


def resolve_settings(env: Any, preset: str | None, settings: dict[str, Any]) -> dict[str, Any]:
    """``TLAC(env, preset=..., **settings)``'s settings before validation: the preset (``"auto"``:
    a domain name's own, as ``tlac train`` uses it, else ``presets/default.yaml``, which is the
    graduate variant's: ``variant="paper"`` on a user's environment takes none, i.e. Algorithm 1
    with Table 5's settings; a preset name; None: none), then SB3's ``policy_kwargs``, then the
    settings given by name."""
    if preset == "auto":
        if isinstance(env, str) and env in domain_names():
            base = domain_preset(env)
        elif settings.get("variant") == "paper":
            base = {}  # the default preset's solo episodes, weaning... are not Algorithm 1
        else:
            base = load_preset("default", "tlac")
    else:
        base = {} if preset is None else load_preset(preset, "tlac")
    settings = dict(settings)
    from_policy_kwargs = settings_from_policy_kwargs(settings.pop("policy_kwargs", None))
    return {**base, **from_policy_kwargs, **settings}


def settings_from_policy_kwargs(policy_kwargs: Any) -> dict[str, Any]:
    """SB3's ``policy_kwargs`` as TL-AC settings: ``net_arch`` (a list: every network; or
    ``dict(pi=[...], vf=[...])``: both actors, the critic), ``log_std_init`` and
    ``ortho_init``. Anything else is a ConfigError naming it; settings given directly win.

    >>> settings = settings_from_policy_kwargs(
    ...     {"net_arch": {"pi": [32], "vf": [16]}, "ortho_init": False}
    ... )
    >>> settings["net_arch_high"], settings["net_arch_low"], settings["net_arch_critic"]
    ([32], [32], [16])
    >>> settings["ortho_init_high"], settings["ortho_init_low"]
    (False, False)
    """
    if policy_kwargs is None:
        return {}
    if not isinstance(policy_kwargs, dict):
        raise ConfigError(f"policy_kwargs must be a dict (as in SB3), got {policy_kwargs!r}")
    unknown = set(policy_kwargs) - {"net_arch", "log_std_init", "ortho_init"}
    if unknown:
        raise ConfigError(
            f"policy_kwargs {sorted(unknown)} are not supported by TL-AC; it takes net_arch, "
            "log_std_init and ortho_init (its other networks' settings are TL-AC settings), "
            "and, given to TLAC(...), features_extractor_class, features_extractor_kwargs and "
            "normalize_images (tlac.algorithms.obs_spaces)"
        )
    out: dict[str, Any] = {}
    arch = policy_kwargs.get("net_arch")
    if isinstance(arch, dict):
        if set(arch) - {"pi", "vf"}:
            raise ConfigError(
                f"policy_kwargs net_arch takes the keys pi and vf, got {sorted(arch)}"
            )
        out.update(
            net_arch_high=arch.get("pi"),
            net_arch_low=arch.get("pi"),
            net_arch_critic=arch.get("vf"),
        )
        out = {k: v for k, v in out.items() if v is not None}
    elif arch is not None:
        out.update(net_arch_high=arch, net_arch_low=arch, net_arch_critic=arch)
    if "log_std_init" in policy_kwargs:
        out["log_std_init"] = policy_kwargs["log_std_init"]
    if "ortho_init" in policy_kwargs:
        out.update(
            ortho_init_high=policy_kwargs["ortho_init"], ortho_init_low=policy_kwargs["ortho_init"]
        )
    return out
