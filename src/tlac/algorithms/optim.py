"""RMSprop with TensorFlow's conventions, updating all parameters with foreach kernels.

The paper's optimizer is stable-baselines3's ``RMSpropTFLike`` (Tables 4-10): RMSprop whose
squared-gradient average starts at ONE (not zero) and whose epsilon goes INSIDE the square
root. SB3's version loops over parameters in Python; with TL-AC's few, small parameter
tensors that loop costs more than the arithmetic, so this one does the same update with
``torch._foreach_*`` kernels (no momentum, not centered: the settings the paper uses). The
tests check it against SB3's ``RMSpropTFLike`` step for step.
"""

from __future__ import annotations

from collections.abc import Iterable

import torch


class RMSpropTFLikeForeach(torch.optim.Optimizer):
    """``v <- alpha v + (1 - alpha) g^2`` (``v`` starts at 1); ``p <- p - lr g / sqrt(v + eps)``."""

    def __init__(
        self,
        params: Iterable[torch.Tensor],
        lr: float = 1e-2,
        alpha: float = 0.99,
        eps: float = 1e-8,
    ):
        if lr < 0 or eps < 0 or not 0.0 <= alpha <= 1.0:
            raise ValueError(f"invalid RMSprop settings lr={lr}, alpha={alpha}, eps={eps}")
        super().__init__(params, {"lr": lr, "alpha": alpha, "eps": eps})

    @torch.no_grad()
    def step(self, closure=None):  # type: ignore[override]
        loss = None if closure is None else closure()
        for group in self.param_groups:
            params = [p for p in group["params"] if p.grad is not None]
            if not params:
                continue
            grads = [p.grad for p in params]
            square_avgs = []
            for p in params:
                state = self.state[p]
                if not state:
                    state["step"] = 0
                    state["square_avg"] = torch.ones_like(p, memory_format=torch.preserve_format)
                state["step"] += 1
                square_avgs.append(state["square_avg"])
            alpha = group["alpha"]
            torch._foreach_mul_(square_avgs, alpha)
            torch._foreach_addcmul_(square_avgs, grads, grads, value=1 - alpha)
            denominators = torch._foreach_add(square_avgs, group["eps"])
            torch._foreach_sqrt_(denominators)
            torch._foreach_addcdiv_(params, grads, denominators, value=-group["lr"])
        return loss
