"""TL-AC's settings: :class:`TLACConfig` (every setting of the paper's Tables 5, 8 and 10, and
the graduate variant's), the two variants' defaults, and the translations from a domain's
preset and from SB3's ``policy_kwargs``.

>>> TLACConfig(variant="paper").kl_rows, TLACConfig().distill_coef
('all', 1.0)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from tlac.algorithms import losses
from tlac.algorithms.encoding import ENCODINGS
from tlac.domains import domain_names, get_domain
from tlac.errors import ConfigError, UnknownNameError
from tlac.presets import load_preset, validate_schedule
from tlac.selectors import SELECTOR_NAMES
from tlac.validation import Checks, from_mapping

Schedule = float | dict

VARIANT_DEFAULTS: dict[str, dict[str, Any]] = {
    "graduate": {
        "distill_coef": 1.0,
        "advice_cost": 0.0,
        # the low level learns from the imitation term, and from its own returns only in the
        # states where every teacher is silent (uniform): since 2026-11-24 (afternoon); before,
        # imitation alone ("none"), which trains bit for bit the same wherever a teacher speaks
        # ("agent" was measured worse; docs/graduation.md, "Where no teacher knows the way")
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
        "advice_cost": 0.0,
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
    """Number or {linear: [start, end]}."""
    clip_range: Schedule = 0.2
    """PPO clip range of both levels' ratios; number or {linear: [start, end]}."""
    target_kl: Schedule | None = 0.02
    """Stop before a gradient step once a level's approximate KL exceeds 1.5x this (SB3's
    rule): with update_rule joint, the larger of the two levels' KL stops the whole update;
    with per_level, each level stops on its own KL."""
    ent_coef: float = 0.0
    """Entropy bonus of both levels, unless ent_coef_high / ent_coef_low are given."""
    ent_coef_high: float | None = None
    """None: ent_coef."""
    ent_coef_low: float | None = None
    """None: ent_coef."""
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
    rmsprop_alpha: float = 0.99
    """Smoothing constant of rmsprop_tf."""
    use_sde: bool = False
    """Generalized state-dependent exploration for Box actions (Tables 8, 10)."""
    sde_sample_freq: int = -1
    """Resample the gSDE noise every this many steps (-1: once per rollout)."""
    log_std_init: float = 0.0
    """Initial log std of the low level's Gaussian (Box actions)."""
    ortho_init_high: bool = True
    """Orthogonal initialisation of the high level (SB3's ortho_init)."""
    ortho_init_low: bool = True
    """Orthogonal initialisation of the low level."""
    ortho_init_critic: bool | None = None
    """None: the same as ortho_init_low (the critic estimates V_pi_low, Eq. 1)."""
    net_arch_high: list[int] = field(default_factory=lambda: [64, 64])
    """Hidden layers of the high-level actor (all three networks have the same depth)."""
    net_arch_low: list[int] = field(default_factory=lambda: [64, 64])
    """Hidden layers of the low-level actor (the student)."""
    net_arch_critic: list[int] = field(default_factory=lambda: [64, 64])
    """Hidden layers of the shared critic."""
    variant: str = "graduate"
    """graduate (the default): the paper's TL-AC plus what makes the student act well ALONE
    (imitation of the teachers the high level trusts, solo episodes, on-policy low-level
    gradients, one-hot integer observations; docs/graduation.md). paper: Algorithm 1 exactly,
    for reproductions. The variant only sets the settings listed in VARIANT_DEFAULTS that are
    left at None; any of them can still be set by hand."""
    distill_coef: Schedule | None = None
    """Weight of the low level's imitation of the teachers, each weighted per state by the high
    level's probability of choosing it (docs/graduation.md); number or {linear: [start, end]}.
    None: the variant's (graduate 1.0, paper 0)."""
    awr_coef: float = 0.0
    """Advantage-weighted imitation of the EXECUTED teacher actions (AWR, Peng et al. 2019):
    adds ``awr_coef * mean over teacher rows of -exp(min(A / awr_beta, log 20)) log
    pi_low(a|s)`` (normalised advantages, no gradient through the weight), so that a noisy
    teacher's better actions count more than its random ones. 0 (off) in both variants: a
    candidate for noisy teachers (docs/graduation.md)."""
    awr_beta: float = 1.0
    """Temperature of awr_coef's weights (in units of the normalised advantage)."""
    advice_cost: float | None = None
    """Subtracted from the high level's (normalised) advantage wherever a teacher acted, so that
    control passes to the agent once its actions are about as good. None: the variant's
    (0 in both: measured, it cost training return without helping the student alone,
    docs/graduation.md)."""
    imitation_buffer_size: int = 50_000
    """States (with every teacher's advice) kept for the imitation term (DAgger's data set)."""
    imitation_batch_size: int = 64
    """Replayed states in each gradient step's imitation term."""
    solo_budget: float | None = None
    """Graduation by solo episodes: an episode is played by the student alone with probability
    min(1, solo_budget / (1 - competence)), competence measured from recent solo and assisted
    returns (tlac.algorithms.graduation), so solo play costs the training return about
    solo_budget of the teachers' margin. None: the variant's (graduate 0.05, paper 0)."""
    normalize_obs: bool = False
    """Normalise the networks' observations by their running mean and std (SB3's VecNormalize,
    clipped to +-norm_clip), inside TL-AC: teachers still see raw observations. Not with a
    one-hot obs_encoding (categories have no scale)."""
    normalize_reward: bool = False
    """Divide training rewards by the running std of the discounted return (SB3's
    VecNormalize); logged returns stay raw."""
    norm_clip: float = 10.0
    """Clip of the normalised observations and rewards."""
    imitation_std: float = 0.1
    """Box actions: the imitation term is the negative log-likelihood of the teachers' actions
    under a Gaussian around the low level's mean with this fixed standard deviation, in units
    of the action box's half-width (imitation does not touch the exploration noise). 1.0 was
    the first choice and left hopper's student alone at ~150: its imitation gradient was 100x
    weaker than at 0.1, far below the policy gradient's (docs/graduation.md)."""
    trust: str = "soft"
    """How the imitation term weighs the teachers in a state: soft (the high level's
    probabilities among the teachers), max (the teacher the high level prefers there, alone:
    DAgger's relabelling with the preferred teacher) or share (the teachers' probabilities
    among all choices, the agent included, so that the student copies little where the high
    level prefers it; meant with low_level_data agent). max and share are candidates,
    docs/graduation.md."""
    advice_labels: str = "informative"
    """Discrete actions: what the imitation term copies from each teacher in a replayed state.
    sampled: the action the teacher gave when asked (one sample); distribution: the teacher's
    whole distribution over actions where it can tell it (``action_probabilities``: the random,
    good / noisy and partial teachers of tlac.teachers.wrappers; a one-hot of its action
    otherwise). The expected loss is the same; a distribution removes the sampling noise, so
    that a random teacher's advice cannot move the student's most likely action. informative:
    distributions, and each teacher's trust in a state weighted by how much its advice says
    there (``1 - entropy / log n_actions``: nothing for a uniform one; losses.informative_trust),
    so that the student copies the teacher that knows, wherever the high level's trust is
    wrong. informative is the default since 2026-11-24: it lifts the PPO-derived L + R greedy
    student from 0.61 to 0.89 and 3 noisy from 0.00 to 0.35, holds on the other study sets,
    and costs 1 optimal + 2 random at 1e5 (0.896 against sampled's 0.945; Teacher L alone
    now trains to 0.817 with a student still at 0.00); with a user's plain functions (point masses)
    it trains bit for bit as sampled (docs/graduation.md, "The teachers' whole advice").
    filtered: as informative, but a teacher's lost trust is not moved to the others, so a
    state whose trusted teachers say little is imitated less (measured no better than
    informative on 1 optimal + 2 random: 0.906). On a Box action space a teacher's advice is
    its action vector, and every value trains as sampled."""
    keep_best_student: bool = True
    """With solo episodes: ``predict`` (the student a user deploys) uses the last snapshot of
    the low level taken when its window of 20 solo returns was not clearly below the best
    such window so far (checked after every solo episode and at the end of ``learn``;
    tlac.algorithms.graduation.worth_deploying), rather than whatever the last update left;
    training itself is unchanged. False: the live weights. Without solo episodes (the paper
    variant) ``predict`` always uses the live weights."""
    solo_critic: bool = True
    """Whether the shared critic also learns from solo episodes. False: it fits the returns of
    assisted episodes only, the behaviour the high level's advantages are about (a candidate,
    docs/graduation.md)."""
    imitate_after_stop: bool = False
    """When the target-KL stop ends an update early, spend its remaining gradient steps on the
    imitation term alone (the high level, the low level's policy gradient and the critic stop as
    in the paper). Meant with kl_rows: agent; a candidate, docs/graduation.md."""
    wean_imitation: bool = False
    """With solo episodes: multiply the imitation weight by ``1 - competence``, so that the
    student stops copying its teachers as its solo episodes match their assisted returns, and
    copies again if it falls back (Kickstarting's annealing, Schmitt et al. 2018, driven by
    the student's measured competence rather than by time). On in the opt-in preset
    ``past-teachers`` (presets/past-teachers.yaml), with low_level_data agent: there the
    student's own policy gradient takes over as the imitation fades, so it can learn past a
    weak teacher (docs/graduation.md, "Learning past the teachers"). Off in both variants:
    with the imitation term alone RMSprop normalises a slowly varying scale away."""
    solo_greedy: bool = False
    """With solo episodes: the student acts greedily in them (its most likely action; the Box
    mean), as it is deployed, so that competence measures the deployed student. Meant with
    low_level_data none (a greedy action is not a sample of pi_low). Off: it steadied Acrobot
    but moved CartPole's failure to another seed, and with low_level_data agent it starves the
    policy gradient of samples (docs/graduation.md)."""
    agent_gate: bool = False
    """With solo episodes: where the high level picks the agent in an assisted episode, the
    agent acts only with probability competence, else a teacher the high level prefers
    (tlac.algorithms.graduation). Off in both variants: it keeps the training return of
    partial teachers (L + R) from collapsing, but slows the student elsewhere
    (docs/graduation.md)."""
    kl_rows: str | None = None
    """Which rows give the low level's approximate KL for the target-KL stop: agent (where the
    agent acted: pi_low's own samples), all (every row, as a PPO built on SB3 computes it) or
    high (none: only the high level's KL stops the epochs, since the imitation term moves
    pi_low on purpose; without an imitation term it acts as agent). None: the variant's
    (graduate high, paper agent)."""
    obs_encoding: str | None = None
    """raw, onehot (each integer observation dimension as indicators) or auto (onehot for an
    integer-dtype Box with small ranges, else raw; tlac.algorithms.encoding). None: the
    variant's (graduate auto, paper raw)."""
    low_level_data: str | None = None
    """Which transitions train the low level's policy gradient: all (the paper, Eq. 3 on every
    executed action), agent (only where it acted, so every ratio is an importance weight of
    pi_low's own samples), none (the imitation term alone trains the low level once the
    advice buffer holds advice; before that, and without teachers, the agent's rows: what the
    graduate variant has always computed, although until 2026-11-23 its defaults said agent,
    docs/graduation.md), silent (the agent's rows in the states where every teacher's advice
    is uniform, losses.silent_states: a random teacher, a partial one outside its region, so
    the student learns from its own returns where no teacher knows the way; elsewhere as none,
    bit for bit: Teacher L's greedy student alone 0.00 -> 0.64, 5 seeds, docs/graduation.md)
    or uninformed (the agent's rows, each weighted by how little even the most informative
    teacher says there, ``1 - max_k info_k(s)``: losses.uninformed_share; measured slower than
    none wherever a teacher is good or noisy). silent and uninformed read the teachers'
    distributions: with discrete actions and ``advice_labels`` other than sampled only, else
    they train as none. None: the variant's (graduate silent since 2026-11-24, none before;
    paper all)."""
    self_imitation: float = 0.0
    """With ``low_level_data: silent``: weight of self-imitation in the silent states
    (tlac.algorithms.graduation.SelfImitationBuffer; Oh et al. 2018): the student's own actions
    there whose Monte-Carlo return beat the critic's value are imitated from a replay of
    ``imitation_buffer_size`` rows, ``imitation_batch_size`` per minibatch. 0: off (both
    variants: on Teacher L, 5 seeds, the greedy student 0.69 +- 0.20 against 0.64 +- 0.20,
    within the seeds' spread; docs/graduation.md). Where some teacher always speaks there are
    no silent states and it changes nothing."""
    self_imitation_value: float = 0.0
    """With self_imitation: weight of SIL's value term ``0.5 max(R - V(s), 0)^2`` on the
    shared critic (Oh et al. 2018), which lifts V towards the best returns seen so that the
    filter keeps only the actions that did best. 0: off."""
    selector: str = "learned"
    """High level: learned (TL-AC), random or ucb1 (per episode) -- the Figure 11 ablations."""
    ucb_c: float = 1.0
    """UCB1 exploration constant (scaled by the observed return range)."""
    n_envs: int = 1
    """Parallel environments, used only when TLAC builds the environment from a domain name."""
    vec_env: str = "dummy"
    """How TLAC steps those environments: dummy (in this process, SB3's DummyVecEnv; needed for
    an exact resume) or subproc (one process each, SB3's SubprocVecEnv; for slow
    environments). Used only when TLAC builds the environment from a domain name."""

    def __post_init__(self) -> None:
        if self.variant not in VARIANT_DEFAULTS:
            raise UnknownNameError("variant", self.variant, list(VARIANT_DEFAULTS))
        for name, value in VARIANT_DEFAULTS[self.variant].items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)  # frozen: only while it is being made
        self.validate()

    @classmethod
    def from_settings(cls, settings: dict[str, Any]) -> TLACConfig:
        """Build and validate a config; unknown keys or bad values raise ConfigError."""
        return from_mapping(cls, "TL-AC", settings)

    @property
    def entropy_coefs(self) -> tuple[float, float]:
        """The entropy bonus of (the low level, the high level): ``ent_coef_low`` /
        ``ent_coef_high`` where set, else ``ent_coef``."""
        return (
            self.ent_coef if self.ent_coef_low is None else self.ent_coef_low,
            self.ent_coef if self.ent_coef_high is None else self.ent_coef_high,
        )

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
            "advice_cost",
            "ent_cap_high",
            "solo_budget",
            "awr_coef",
            "self_imitation",
            "self_imitation_value",
        ):
            check.number(name, getattr(self, name), 0.0)
        for name in ("awr_beta", "norm_clip", "imitation_std"):
            check.number(name, getattr(self, name), 0.0, open_low=True)
        for name, accepted in (
            ("optimizer", ["rmsprop_tf", "adam"]),
            ("update_rule", ["joint", "per_level"]),
            ("kl_rows", ["agent", "all", "high"]),
            ("obs_encoding", list(ENCODINGS)),
            ("trust", list(losses.TRUST_RULES)),
            ("advice_labels", ["sampled", "distribution", "informative", "filtered"]),
            ("low_level_data", ["all", "agent", "none", "uninformed", "silent"]),
            ("vec_env", ["dummy", "subproc"]),
            ("selector", list(SELECTOR_NAMES)),
        ):
            check.one_of(name, getattr(self, name), accepted)
        depths = {len(self.net_arch_high), len(self.net_arch_low), len(self.net_arch_critic)}
        if len(depths) != 1 or 0 in depths:
            raise ConfigError(
                "net_arch_high, net_arch_low and net_arch_critic must have the same, non-zero number "
                f"of layers (widths may differ), got {self.net_arch_high}, {self.net_arch_low}, {self.net_arch_critic}"
            )
        if self.self_imitation and self.low_level_data != "silent":
            raise ConfigError(
                f"self_imitation acts in the silent states only: it needs low_level_data 'silent', "
                f"got {self.low_level_data!r} (variant {self.variant!r})"
            )
        if self.update_rule == "per_level" and self.imitate_after_stop:
            raise ConfigError(
                "imitate_after_stop acts when the whole update stops: it needs update_rule "
                f"'joint', got 'per_level' (variant {self.variant!r})"
            )
        if self.self_imitation_value and not self.self_imitation:
            raise ConfigError(
                "self_imitation_value is SIL's value term: it needs self_imitation > 0"
            )


def domain_preset(name: str) -> dict[str, Any]:
    """The TL-AC settings of a named domain's preset (paper Tables 5, 8, 10)."""
    domain = get_domain(name)
    return load_preset(domain.presets["tlac"], "tlac") if "tlac" in domain.presets else {}


def resolve_settings(env: Any, preset: str | None, settings: dict[str, Any]) -> dict[str, Any]:
    """``TLAC(env, preset=..., **settings)``'s settings before validation: the preset (``"auto"``:
    a domain name's own, as ``tlac train`` uses it, else ``presets/default.yaml``; a preset name;
    None: none), then SB3's ``policy_kwargs``, then the settings given by name."""
    if preset == "auto":
        is_domain = isinstance(env, str) and env in domain_names()
        base = domain_preset(env) if is_domain else load_preset("default", "tlac")
    else:
        base = {} if preset is None else load_preset(preset, "tlac")
    settings = dict(settings)
    from_policy_kwargs = settings_from_policy_kwargs(settings.pop("policy_kwargs", None))
    return {**base, **from_policy_kwargs, **settings}


def settings_from_policy_kwargs(policy_kwargs: Any) -> dict[str, Any]:
    """SB3's ``policy_kwargs`` as TL-AC settings: ``net_arch`` (a list: every network; or
    ``dict(pi=[...], vf=[...])``: both actors, the critic), ``log_std_init`` and
    ``ortho_init``. Anything else is a ConfigError naming it; settings given directly win.

    >>> settings_from_policy_kwargs({"net_arch": {"pi": [32], "vf": [16]}, "ortho_init": False})
    {'net_arch_high': [32], 'net_arch_low': [32], 'net_arch_critic': [16], 'ortho_init_high': False, 'ortho_init_low': False}
    """
    if policy_kwargs is None:
        return {}
    if not isinstance(policy_kwargs, dict):
        raise ConfigError(f"policy_kwargs must be a dict (as in SB3), got {policy_kwargs!r}")
    unknown = set(policy_kwargs) - {"net_arch", "log_std_init", "ortho_init"}
    if unknown:
        raise ConfigError(
            f"policy_kwargs {sorted(unknown)} are not supported by TL-AC; it takes net_arch, "
            "log_std_init and ortho_init (its other networks' settings are TL-AC settings)"
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
