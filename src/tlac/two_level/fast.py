"""TL-AC's speed-ups: each computes what a plainer formula computes, in fewer calls. The
update (:mod:`tlac.two_level.update`) reads as the plain formulas; these replace them behind
this module's boundary, and each has its test against the plain formula beside it
(tests/test_speedups.py).

With the paper's DoorKey preset an update takes up to 5 gradient steps on 16 rows, so a step's
Python and dispatch overhead counts as much as its arithmetic.

* :class:`ForeachRMSpropTFLike` equals SB3's ``RMSpropTFLike.step``, per parameter
  ``v = alpha v + (1 - alpha) g^2; p -= lr g / sqrt(v + eps)``: the per-parameter loop of
  five tensor ops replaced by five ``torch._foreach_*`` calls over all parameters.
* :class:`ForeachAdam` equals ``torch.optim.Adam(..., foreach=True).step``: its eight
  ``_foreach_`` calls without the checks, grouping and hooks that wrap them (the user
  preset's optimiser: 10 epochs of 32 steps per update).
* :func:`clip_grad_norm` equals ``torch.nn.utils.clip_grad_norm_(..., foreach=True)``,
  ``g *= min(1, max_norm / (||g||_2 + 1e-6))`` over all gradients, without its grouping by
  device and dtype (TL-AC's parameters are float32 CPU tensors).
* :func:`stepping_rows` / :func:`first_layer_on` (with :func:`narrowed_columns` and
  :func:`active_columns`): the first layer stepped on the input columns an update activates
  equals the step on the whole layer when the gradient is zero on the other rows (one-hot
  observations), up to the rounding of a matmul over fewer columns.
* :class:`ReplayDraws` / :func:`replay_plan`: the imitation term's replayed rows of every
  minibatch drawn, gathered and encoded once per update equal one
  ``AdviceBuffer.sample`` per minibatch: the same rows and the same generator state.
* :func:`update_entropy_coefs`: the entropy coefficients worked out once per update rather
  than once per minibatch (graduation.entropy_coefs reads the solo episodes' competence, which
  no gradient step changes): the same tensor, without a ``torch.tensor`` and the competence's
  window means per step.

On the CPU a ``_foreach_`` op applies the same kernel to each tensor in turn, so the optimiser
steps compute exactly what the originals do: same values, bit for bit
(tests/test_default_pinned.py), same optimiser state (a checkpoint of either loads into the
other).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import torch
from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike

from tlac.two_level import losses

if TYPE_CHECKING:
    from tlac.two_level.graduation import AdviceBuffer
    from tlac.two_level.networks import Networks

MAX_PLANNED_REPLAY_VALUES = 1 << 23
"""An update holds the replayed rows of all its minibatches, as the networks take them, when
they have at most this many values (32 MB of float32; DoorKey's preset: 320 x 1029); larger
(images, or SB3-sized rollouts of wide one-hot rows) each minibatch makes its own, and the
first layer is not narrowed (:func:`narrowed_columns`)."""


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


class ReplayDraws:
    """The imitation term's replayed rows for a whole update, drawn in one call.

    Every minibatch of an update replays ``batch_size`` rows of the advice buffer drawn
    uniformly with replacement (:meth:`tlac.two_level.graduation.AdviceBuffer.sample`). Drawing
    them one minibatch at a time cost a draw, two gathers and an encoding per minibatch; here
    the rows of every minibatch the update may take are drawn at once, from a copy of the
    generator, and :meth:`finish` then advances the generator itself by the draws of the
    minibatches actually taken (the KL stop may end an update early). ``torch.randint`` on the
    CPU draws its values one after the other, so ``k`` draws of ``n`` rows are the first
    ``k * n`` values of one draw: the rows and the generator's state are exactly those of one
    draw per minibatch.

    >>> g = torch.Generator().manual_seed(0)
    >>> draws = ReplayDraws(size=100, batch_size=4, max_batches=3, generator=g)
    >>> rows = draws.idx[draws.next()]
    >>> draws.finish()   # one minibatch taken: the generator moves by its 4 draws only
    >>> ref = torch.Generator().manual_seed(0)
    >>> (torch.equal(rows, torch.randint(100, (4,), generator=ref)),
    ...  g.get_state().equal(ref.get_state()))
    (True, True)
    """

    def __init__(self, size: int, batch_size: int, max_batches: int, generator: torch.Generator):
        self.size, self.batch_size, self.generator = size, batch_size, generator
        self.max_batches = max_batches
        peek = torch.Generator().set_state(generator.get_state())
        self.idx = torch.randint(size, (batch_size * max_batches,), generator=peek)
        self.taken = 0

    def next(self) -> slice:
        """The positions in :attr:`idx` of the next minibatch's rows."""
        if self.taken == self.max_batches:
            raise RuntimeError(f"only {self.max_batches} minibatches of rows were drawn")
        start = self.taken * self.batch_size
        self.taken += 1
        return slice(start, start + self.batch_size)

    def finish(self) -> None:
        """Advance the generator by the rows of the minibatches taken, as their own draws did."""
        if self.taken:
            torch.randint(self.size, (self.taken * self.batch_size,), generator=self.generator)


@dataclass(frozen=True)
class ReplayPlan:
    """The replayed rows of an update's minibatches (:func:`replay_plan`): which rows, as the
    networks take them, and their advice and its information, gathered once for all of them."""

    draws: ReplayDraws
    x: torch.Tensor | None
    """``(rows, ...)``: the drawn states as the update's passes take them, in draw order
    (normalised with the statistics of the update, then encoded as Networks.update_rows does);
    None where they would be too large to hold (each minibatch then makes its own)."""
    advice: torch.Tensor
    """``(n_teachers, rows, ...)``: the labels copied in every drawn row, in draw order
    (discrete actions: losses.advice_labels of the advice; Box actions: the actions meant)."""
    information: torch.Tensor
    """``(n_teachers, rows)``: how much each teacher's advice says in each row (discrete
    actions: losses.advice_information of the advice before its labels were taken; Box
    actions: the information the teachers gave, tlac.teachers.base.advice_actions)."""


def active_columns(*inputs: torch.Tensor) -> torch.Tensor:
    """The columns that are nonzero in some row of the 2-D ``inputs``: the input columns whose
    first-layer weights an update's gradients can reach (:func:`stepping_rows`).

    >>> active_columns(torch.tensor([[0.0, 1.0, 0.0]]), torch.tensor([[0.0, 0.0, 2.0]])).tolist()
    [1, 2]
    """
    magnitude = sum(x.abs().sum(0) for x in inputs)  # a sixth of the time of (x != 0).any(0)
    return (magnitude != 0).nonzero().squeeze(1)  # != keeps a column holding a NaN


def optimizer_step(optimizer: torch.optim.Optimizer) -> None:
    """``optimizer.step()``; ours without torch's profiler range and hooks."""
    if isinstance(optimizer, (ForeachRMSpropTFLike, ForeachAdam)):
        optimizer.step_unhooked()
    else:
        optimizer.step()


def narrowed_columns(
    nets: Networks,
    optimizer: torch.optim.Optimizer,
    update_rule: str,
    x: torch.Tensor,
    replay: ReplayPlan | None,
) -> torch.Tensor | None:
    """The input columns that the update's rows (the rollout's ``x``, the replayed rows)
    activate, where its first layer can step on those alone (:func:`first_layer_on`): inputs
    read by the stacked networks' first layer (no CNN), the joint update rule, and an
    optimiser that leaves weights without gradient as they are (RMSprop without momentum).
    None where that does not hold or every column is active."""
    if (
        nets.extractor_params
        or update_rule != "joint"
        or not isinstance(optimizer, ForeachRMSpropTFLike)
        or not optimizer.zero_gradient_keeps_weights()
    ):
        return None
    if replay is not None and replay.x is None:  # the replayed rows are not all known
        return None
    cols = active_columns(x) if replay is None else active_columns(x, replay.x)
    return None if len(cols) == x.shape[1] else cols


@contextmanager
def first_layer_on(
    nets: Networks, optimizer: torch.optim.Optimizer, cols: torch.Tensor | None
) -> Iterator[None]:
    """While open, the update's passes and gradient steps use only the rows ``cols`` of the
    first layer's weight (None: all of it). One-hot observations activate a third of DoorKey's
    1029 input columns in an update; the other rows' weights get no gradient, so the first
    layer's forward, weight gradient, clipping and optimiser arithmetic can skip them, and their
    optimiser statistics decay as a zero gradient's step decays them (:func:`stepping_rows`).
    The same steps as on the whole layer, up to floating-point rounding (a matmul over fewer
    columns sums its terms in another order)."""
    if cols is None:
        yield
        return
    assert isinstance(optimizer, ForeachRMSpropTFLike)
    first = nets.net.weights[0]
    with stepping_rows(optimizer, first, cols, dim=1) as part, nets.net.first_layer_as(part, cols):
        yield


def replay_plan(
    nets: Networks,
    buffer: AdviceBuffer,
    batch_size: int,
    max_batches: int,
    generator: torch.Generator,
) -> ReplayPlan:
    """The states the imitation term replays in each of up to ``max_batches`` minibatches of
    ``batch_size`` rows, drawn from the advice buffer at once (the same rows, and the same
    generator state after the update, as one draw per minibatch: :class:`ReplayDraws`), with
    their advice and (discrete actions) its information, computed once."""
    draws = ReplayDraws(len(buffer), batch_size, max_batches, generator)
    width = max(nets.obs_dim, nets.net.weights[0].shape[1])  # of a row, stored or encoded
    x = None  # too large to hold (images; wide rows over SB3-sized rollouts): per minibatch
    if draws.idx.numel() * width <= MAX_PLANNED_REPLAY_VALUES:
        x = nets.replay_rows(buffer.obs[draws.idx])
    advice = buffer.advice[draws.idx].transpose(0, 1)  # (n_teachers, rows, ...)
    if buffer.labelled is not None:  # limited advice: a teacher not asked says nothing
        asked = buffer.labelled[draws.idx].T.float()
        if not nets.discrete:
            return ReplayPlan(draws, x, advice[..., :-1], advice[..., -1] * asked)
        information = losses.advice_information(advice) * asked
        return ReplayPlan(draws, x, losses.advice_labels(advice), information)
    if not nets.discrete:  # the actions meant, and their information
        return ReplayPlan(draws, x, advice[..., :-1], advice[..., -1])
    return ReplayPlan(draws, x, losses.advice_labels(advice), losses.advice_information(advice))


def replayed_rows(
    nets: Networks, buffer: AdviceBuffer, plan: ReplayPlan, replayed: slice
) -> torch.Tensor:
    """A minibatch's replayed rows as :meth:`Networks.heads` takes them: planned, or made
    here (on the whole first layer)."""
    if plan.x is not None:
        return plan.x[replayed]
    assert nets.net.weights[0] is nets.net._layers[0][0], "a narrowed layer needs planned rows"
    return nets.replay_rows(buffer.obs[plan.draws.idx[replayed]])


def update_entropy_coefs(model: Any) -> torch.Tensor | None:
    """The ``[low, high]`` entropy coefficients of every gradient step of the update about to
    run, what ``graduation.entropy_coefs`` gives at each of them (the solo episodes change
    only while collecting); None where the loss has no entropy term (``model._use_entropy``
    off)."""
    from tlac.two_level.graduation import entropy_coefs

    if not model._use_entropy:
        return None
    return entropy_coefs(model._ent_coefs, model.solo, model._handover)
