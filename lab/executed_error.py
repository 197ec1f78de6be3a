"""The Box imitation error measured on the action the environment executes (issue 63), as a patch:
the probe that measured it on code without it (results/teacher-sweep/NOTES.md, "The copy's
error at the box's bounds"); adopted since in cbd8f0f0 (``networks.SATURATED``, with ``reach``
inf and ``tolerance`` 0.05), so on today's code the default ``--reach`` changes nothing.

TL-AC's Box imitation term is the squared distance between the low level's mean and the
teacher's action (tlac.two_level.losses.scaled_squared_error). The environment clips actions to
the box, so where a teacher pushes at a bound a mean beyond that bound acts the same. This probe
replaces the error, in this process only, by the distance to the set of means that execute the
teacher's action: a target within ``--tolerance`` of the half-width from a bound is met by any mean
from the target to ``--reach`` half-widths beyond that bound (``inf``: any mean beyond it).

    .venv/bin/python lab/executed_error.py sweep Pendulum-v1 q1+random 0 [--reach 0.5]
    .venv/bin/python lab/executed_error.py suite Pendulum-v1+weak 0 1 3 [--reach 0.5]

``sweep`` trains a teacher-sweep case and scores its student as the sweep does; ``suite`` runs
benchmarks/user_envs.py's TL-AC runs for one entry (``--out``, default
/tmp/executed-error-suite). One line per run.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


def executed_error(
    mean: torch.Tensor,
    targets: torch.Tensor,
    low: torch.Tensor,
    high: torch.Tensor,
    scale: torch.Tensor | None,
    tolerance: float,
    reach: float,
) -> torch.Tensor:
    """``(K, B)``: half the mean squared distance (in units of ``scale``) from the mean to the
    interval of means that execute each target: the target itself inside the box; from the
    target to ``reach`` half-widths past the bound for a target within ``tolerance`` of it.

    >>> low, high = torch.tensor([-2.0]), torch.tensor([2.0])
    >>> t = torch.tensor([[[1.99]], [[0.5]]])   # a saturated target, an inner one
    >>> executed_error(torch.tensor([[2.7]]), t, low, high, None, 0.05, math.inf).tolist()
    [[0.0], [2.4200000762939453]]
    >>> executed_error(torch.tensor([[3.5]]), t, low, high, None, 0.05, 0.5).tolist()  # 3.5 - 3
    [[0.125], [4.5]]
    """
    m = mean.unsqueeze(0)
    half = (high - low) / 2
    at_high = targets >= high - tolerance * half
    at_low = targets <= low + tolerance * half
    lowest = torch.where(at_low, low - reach * half, targets)
    highest = torch.where(at_high, high + reach * half, targets)
    error = m - torch.minimum(torch.maximum(m, lowest), highest)
    s = 1.0 if scale is None else scale
    return 0.5 * ((error / s) ** 2).mean(-1)


def patch(tolerance: float, reach: float) -> None:
    """TL-AC's Box imitation error replaced by :func:`executed_error` in this process."""
    from tlac.two_level import networks

    original = networks.Networks.advice_nll

    def advice_nll(self, low_out, latent, advice):
        if self.discrete:
            return original(self, low_out, latent, advice)
        low = torch.as_tensor(self.action_space.low, dtype=torch.float32)
        high = torch.as_tensor(self.action_space.high, dtype=torch.float32)
        return executed_error(low_out, advice, low, high, self.imitation_scale, tolerance, reach)

    networks.Networks.advice_nll = advice_nll


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=["sweep", "suite"])
    parser.add_argument("args", nargs="+", help="sweep: ENV CASE SEED...; suite: ENTRY SEED...")
    parser.add_argument("--tolerance", type=float, default=0.05)
    parser.add_argument("--reach", type=float, default=math.inf)
    parser.add_argument("--out", type=Path, default=Path("/tmp/executed-error-suite"))
    args = parser.parse_args()
    patch(args.tolerance, args.reach)
    torch.set_num_threads(1)
    if args.what == "suite":
        import runpy

        entry, seeds = args.args[0], args.args[1:]
        sys.argv = ["user_envs.py", "--envs", entry, "--learners", "tlac", "--seeds", *seeds]
        sys.argv += ["--out", str(args.out)]
        runpy.run_path(str(ROOT / "benchmarks" / "user_envs.py"), run_name="__main__")
        return
    import teacher_sweep

    from tlac import TLAC

    env_id, case, seeds = args.args[0], args.args[1], [int(s) for s in args.args[2:]]
    out = ROOT / "results" / "teacher-sweep"
    for seed in seeds:
        torch.manual_seed(seed)
        teachers = teacher_sweep.case_teachers(env_id, case, out, seed)
        model = TLAC(teacher_sweep.make_env(env_id), teachers=teachers, seed=seed)
        model.learn(teacher_sweep.budget(env_id))
        alone = teacher_sweep.deployed_alone(model, env_id)["student_alone"]
        print(f"{env_id} {case} seed {seed}: student alone {alone:.1f}", flush=True)


if __name__ == "__main__":
    main()
