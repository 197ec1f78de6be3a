"""The former name of :mod:`tlac.domains` (the domain registry), kept so that code written
against it still runs: ``from tlac.envs import get_domain`` is ``from tlac.domains import
get_domain``."""

from tlac.domains import (  # noqa: F401
    GYM_IDS,
    Domain,
    domain_names,
    get_domain,
    make_teachers,
    make_vec_env,
    parse_teacher_spec,
    register_domain,
    register_gym_ids,
)
