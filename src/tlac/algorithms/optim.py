"""The gradient step of TL-AC's update with fewer calls, the same arithmetic.

With the paper's DoorKey preset an update takes up to 5 gradient steps on 16 rows, so a step's
Python and dispatch overhead counts as much as its arithmetic. :class:`ForeachRMSpropTFLike`
is SB3's ``RMSpropTFLike`` with its per-parameter loop of five tensor ops replaced by five
``torch._foreach_*`` calls over all parameters; :class:`ForeachAdam` is ``torch.optim.Adam``
(foreach) without the checks, grouping and hooks that wrap its eight ``_foreach_`` calls (the
user preset's optimiser: 10 epochs of 32 steps per update); :func:`clip_grad_norm` is
``torch.nn.utils.clip_grad_norm_(..., foreach=True)`` without its grouping by device and dtype
(TL-AC's parameters are float32 CPU tensors). On the CPU a ``_foreach_`` op applies the same
kernel to each tensor in turn, so both compute exactly what the originals do: same values, bit
for bit (tests/test_default_pinned.py), same optimiser state (a checkpoint of either loads
into the other). :func:`stepping_rows` steps some rows of a parameter in its place, for an
update whose gradient is zero on the other rows (the first layer on one-hot observations).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

import torch
from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike


class ForeachRMSpropTFLike(RMSpropTFLike):
    """SB3's ``RMSpropTFLike`` (TensorFlow's RMSprop: epsilon inside the square root, the
    square average started at 1), stepping every parameter with one call per operation. The
    variants TL-AC does not use (momentum, centered, weight decay, a closure, sparse gradients)
    take SB3's own step."""

    @torch.no_grad()
    def step(self, closure: Callable[[], float] | None = None) -> float | None:  # type: ignore[override]
        if closure is not None or not self.zero_gradient_keeps_weights():
            return super().step(closure)
        self._foreach_step()
        return None

    def step_unhooked(self) -> None:
        """:meth:`step` without what ``torch.optim.Optimizer`` wraps every ``step`` in (a
        profiler range and the optimiser hooks: 15-25 us of the ~140 us a step of the default's
        parameters takes on DoorKey), for TL-AC's update, which registers no hook. SB3's own
        step where that applies."""
        if not self.zero_gradient_keeps_weights():
            self.step()
            return
        with torch.no_grad():
            self._foreach_step()

    def _foreach_step(self) -> None:
        for index, group in enumerate(self.param_groups):
            params = [p for p in group["params"] if p.grad is not None]
            grads = [p.grad for p in params]
            if any(g.is_sparse for g in grads):
                super().step()
                return
            squares = [self._square_avg(p) for p in params]
            alpha = group["alpha"]
            # SB3, per parameter: square_avg.mul_(alpha).addcmul_(grad, grad, value=1 - alpha);
            # avg = square_avg.add(eps).sqrt_(); p.addcdiv_(grad, avg, value=-lr)
            torch._foreach_mul_(squares, alpha)
            torch._foreach_addcmul_(squares, grads, grads, value=1 - alpha)
            # square_avg.add(eps), written into buffers kept from step to step: a fresh
            # 3 x 1029 x 64 tensor per step cost as much as the addition itself
            avg = self._scratch(index, params)
            torch._foreach_copy_(avg, squares)
            torch._foreach_add_(avg, group["eps"])
            torch._foreach_sqrt_(avg)
            torch._foreach_addcdiv_(params, grads, avg, value=-group["lr"])

    def _scratch(self, group: int, params: list[torch.Tensor]) -> list[torch.Tensor]:
        """Buffers of the shapes of a group's stepped ``params``, in order, the same ones from
        step to step while the shapes stay (not part of the optimiser's state: its state_dict
        and checkpoints stay SB3's). Kept per position, not per tensor: the rows that
        :func:`stepping_rows` steps are a new tensor in every update."""
        kept: dict[int, list[torch.Tensor]] = self.__dict__.setdefault("_scratch_buffers", {})
        buffers = kept.setdefault(group, [])
        del buffers[len(params) :]
        for i, p in enumerate(params):
            if i == len(buffers):
                buffers.append(torch.empty_like(p, memory_format=torch.preserve_format))
            elif buffers[i].shape != p.shape:
                buffers[i] = torch.empty_like(p, memory_format=torch.preserve_format)
        return buffers

    def _square_avg(self, p: torch.Tensor) -> torch.Tensor:
        """``p``'s running square average, counting the step."""
        state = self.param_state(p)
        state["step"] += 1
        return state["square_avg"]

    def param_state(self, p: torch.Tensor) -> dict:
        """``p``'s state (SB3's: the steps taken, the square average started at 1)."""
        state = self.state[p]
        if len(state) == 0:
            state["step"] = 0
            state["square_avg"] = torch.ones_like(p, memory_format=torch.preserve_format)
        return state

    def zero_gradient_keeps_weights(self) -> bool:
        """Whether a step leaves a weight whose gradient is zero as it is (no momentum, no
        weight decay, no centring): what :func:`stepping_rows` needs."""
        return not any(
            g["momentum"] > 0 or g["centered"] or g["weight_decay"] != 0 for g in self.param_groups
        )


class ForeachAdam(torch.optim.Adam):
    """``torch.optim.Adam(..., foreach=True)``: its ``_multi_tensor_adam`` arithmetic, the same
    ``_foreach_`` calls in the same order with the same per-parameter bias corrections, without
    what surrounds them in every ``step`` (the profiler range and hooks, the grouping of
    tensors by device and dtype, the checks of options TL-AC does not use): 103 us a step
    instead of 163 us on the user preset's six stacked parameters (a 6-feature, 3-action
    environment; 3,000 steps each, measured alone). What TL-AC does not use (amsgrad, weight
    decay, maximize, capturable, differentiable, fused, a tensor learning rate or betas, sparse
    or complex gradients) takes torch's own step. Same state, so checkpoints load into either."""

    def step_unhooked(self) -> None:
        """:meth:`step`'s arithmetic for TL-AC's update, which registers no hook."""
        if not self._plain():
            self.step()
            return
        with torch.no_grad():
            for group in self.param_groups:
                self._foreach_step(group)

    def _plain(self) -> bool:
        """Whether every group and gradient is what :meth:`_foreach_step` computes for."""
        return all(
            not (g["amsgrad"] or g["maximize"] or g["capturable"] or g["differentiable"])
            and not g["fused"]
            and g["weight_decay"] == 0
            and not torch.is_tensor(g["lr"])
            and not any(torch.is_tensor(b) for b in g["betas"])
            and not any(
                p.grad is not None and (p.grad.is_sparse or p.grad.is_complex())
                for p in g["params"]
            )
            for g in self.param_groups
        )

    def _foreach_step(self, group: dict) -> None:
        params = [p for p in group["params"] if p.grad is not None]
        if not params:
            return
        grads = [p.grad for p in params]
        states = [self._state(p) for p in params]
        exp_avgs = [s["exp_avg"] for s in states]
        exp_avg_sqs = [s["exp_avg_sq"] for s in states]
        steps = [s["step"] for s in states]
        beta1, beta2 = group["betas"]
        lr = group["lr"]
        torch._foreach_add_(steps, 1.0)  # Adam's: torch._foreach_add_(steps, tensor(1.0))
        torch._foreach_lerp_(exp_avgs, grads, 1 - beta1)
        torch._foreach_mul_(exp_avg_sqs, beta2)
        torch._foreach_addcmul_(exp_avg_sqs, grads, grads, 1 - beta2)
        counts = [s.item() for s in steps]  # Adam's _get_value(step), per parameter
        step_size = [(lr / (1 - beta1**t)) * -1 for t in counts]
        bias_correction2_sqrt = [(1 - beta2**t) ** 0.5 for t in counts]
        denominators = torch._foreach_sqrt(exp_avg_sqs)
        torch._foreach_div_(denominators, bias_correction2_sqrt)
        torch._foreach_add_(denominators, group["eps"])
        torch._foreach_addcdiv_(params, exp_avgs, denominators, step_size)

    def _state(self, p: torch.Tensor) -> dict:
        """``p``'s state, started as torch's Adam starts it (a CPU float step, zero moments)."""
        state = self.state[p]
        if len(state) == 0:
            state["step"] = torch.tensor(0.0, dtype=torch.get_default_dtype())
            state["exp_avg"] = torch.zeros_like(p, memory_format=torch.preserve_format)
            state["exp_avg_sq"] = torch.zeros_like(p, memory_format=torch.preserve_format)
        return state


@contextmanager
def stepping_rows(
    optimizer: ForeachRMSpropTFLike, param: torch.Tensor, rows: torch.Tensor, dim: int
) -> Iterator[torch.Tensor]:
    """Yield ``part``, the rows ``rows`` (along ``dim``) of parameter ``param`` as a leaf of
    its own, which ``optimizer`` steps in ``param``'s place while the context is open, with
    those rows of its square average. On exit ``part`` and its square average go back into
    ``param``'s rows, and the other rows' square averages are multiplied by ``alpha`` once per
    step taken.

    That is exactly what those steps do when ``param``'s gradient is zero outside ``rows``:
    ``square_avg = alpha * square_avg + (1 - alpha) * 0``, and the weight moves by
    ``lr * 0 / sqrt(square_avg + eps) = 0``. TL-AC's first layer on one-hot observations is
    such a parameter: an input column that is 0 in every row of an update gives its weights
    no gradient, and on DoorKey about 300 of the 1029 columns are active in an update, so its
    gradient, clipping and optimiser arithmetic run on those rows only (the rows of the weight
    ``(members, in, out)`` along ``dim=1`` are the layer's input columns).

    >>> w = torch.nn.Parameter(torch.ones(2, 3))
    >>> opt = ForeachRMSpropTFLike([w], lr=0.1, alpha=0.5, eps=1e-5)
    >>> with stepping_rows(opt, w, torch.tensor([1]), dim=1) as part:
    ...     part.grad = torch.ones(2, 1)
    ...     _ = opt.step()
    >>> [round(v, 3) for v in w[0].tolist()], opt.state[w]["square_avg"][0].tolist()
    ([1.0, 0.9, 1.0], [0.5, 1.0, 0.5])
    """
    assert optimizer.zero_gradient_keeps_weights(), "a step moves weights whose gradient is zero"
    group = next(g for g in optimizer.param_groups if any(p is param for p in g["params"]))
    position = next(i for i, p in enumerate(group["params"]) if p is param)
    state = optimizer.param_state(param)
    part = param.detach().index_select(dim, rows).requires_grad_()
    optimizer.state[part] = {
        "step": state["step"],
        "square_avg": state["square_avg"].index_select(dim, rows),
    }
    group["params"][position] = part
    try:
        yield part
    finally:
        group["params"][position] = param
        stepped = optimizer.state.pop(part)
        with torch.no_grad():
            for _ in range(stepped["step"] - state["step"]):
                state["square_avg"].mul_(group["alpha"])
            state["square_avg"].index_copy_(dim, rows, stepped["square_avg"])
            param.index_copy_(dim, rows, part)
        state["step"] = stepped["step"]


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
