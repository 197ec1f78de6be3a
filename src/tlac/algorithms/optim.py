"""The gradient step of TL-AC's update with fewer calls, the same arithmetic.

With the paper's DoorKey preset an update takes up to 5 gradient steps on 16 rows, so a step's
Python and dispatch overhead counts as much as its arithmetic. :class:`ForeachRMSpropTFLike`
is SB3's ``RMSpropTFLike`` with its per-parameter loop of five tensor ops replaced by five
``torch._foreach_*`` calls over all parameters; :func:`clip_grad_norm` is
``torch.nn.utils.clip_grad_norm_(..., foreach=True)`` without its grouping by device and dtype
(TL-AC's parameters are float32 CPU tensors). On the CPU a ``_foreach_`` op applies the same
kernel to each tensor in turn, so both compute exactly what the originals do: same values, bit
for bit (tests/test_default_pinned.py), same optimiser state (a checkpoint of either loads
into the other).
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike


class ForeachRMSpropTFLike(RMSpropTFLike):
    """SB3's ``RMSpropTFLike`` (TensorFlow's RMSprop: epsilon inside the square root, the
    square average started at 1), stepping every parameter with one call per operation. The
    variants TL-AC does not use (momentum, centered, weight decay, a closure, sparse gradients)
    take SB3's own step."""

    @torch.no_grad()
    def step(self, closure: Callable[[], float] | None = None) -> float | None:  # type: ignore[override]
        if closure is not None or any(
            g["momentum"] > 0 or g["centered"] or g["weight_decay"] != 0 for g in self.param_groups
        ):
            return super().step(closure)
        for group in self.param_groups:
            params = [p for p in group["params"] if p.grad is not None]
            grads = [p.grad for p in params]
            if any(g.is_sparse for g in grads):
                return super().step(closure)
            squares = [self._square_avg(p) for p in params]
            alpha = group["alpha"]
            # SB3, per parameter: square_avg.mul_(alpha).addcmul_(grad, grad, value=1 - alpha);
            # avg = square_avg.add(eps).sqrt_(); p.addcdiv_(grad, avg, value=-lr)
            torch._foreach_mul_(squares, alpha)
            torch._foreach_addcmul_(squares, grads, grads, value=1 - alpha)
            # square_avg.add(eps), written into buffers kept from step to step: a fresh
            # 3 x 1029 x 64 tensor per step cost as much as the addition itself
            avg = [
                torch.add(s, group["eps"], out=self._scratch(p))
                for p, s in zip(params, squares, strict=True)
            ]
            torch._foreach_sqrt_(avg)
            torch._foreach_addcdiv_(params, grads, avg, value=-group["lr"])
        return None

    def _scratch(self, p: torch.Tensor) -> torch.Tensor:
        """A buffer of parameter ``p``'s shape, the same one at every step (not part of the
        optimiser's state: its state_dict and checkpoints stay SB3's)."""
        scratch: dict[int, torch.Tensor] = self.__dict__.setdefault("_scratch_buffers", {})
        if id(p) not in scratch or scratch[id(p)].shape != p.shape:
            scratch[id(p)] = torch.empty_like(p, memory_format=torch.preserve_format)
        return scratch[id(p)]

    def _square_avg(self, p: torch.Tensor) -> torch.Tensor:
        """``p``'s running square average, counting the step (SB3's state, started at 1)."""
        state = self.state[p]
        if len(state) == 0:
            state["step"] = 0
            state["square_avg"] = torch.ones_like(p, memory_format=torch.preserve_format)
        state["step"] += 1
        return state["square_avg"]


def clip_grad_norm(grads: list[torch.Tensor], max_norm: float) -> torch.Tensor:
    """``torch.nn.utils.clip_grad_norm_(params, max_norm, foreach=True)`` on the parameters'
    gradients ``grads`` (float32 CPU tensors): the same operations in the same order, without
    its grouping of tensors by device and dtype. Returns the total norm before clipping.

    >>> g = [torch.tensor([3.0, 0.0]), torch.tensor([4.0])]
    >>> float(clip_grad_norm(g, 1.0)), [round(v, 4) for v in torch.cat(g).tolist()]
    (5.0, [0.6, 0.0, 0.8])
    """
    total = torch.linalg.vector_norm(torch.stack(torch._foreach_norm(grads, 2.0)), 2.0)
    coef = max_norm / (total + 1e-6)  # Tensor.__rtruediv__, as torch's clip_grad_norm_ writes it
    torch._foreach_mul_(grads, torch.clamp(coef, max=1.0))
    return total
