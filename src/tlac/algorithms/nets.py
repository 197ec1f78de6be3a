"""Networks for TL-AC: the high-level actor, the low-level actor and the shared critic
(paper, section 3.2 and Figure 1), evaluated together in ONE batched matmul per layer.

With [64, 64] networks eager PyTorch spends its time on dispatch, not arithmetic, so three
separate MLPs cost three times the kernel launches of one stacked MLP. :class:`StackedMLP`
holds the weights of M member networks in tensors of shape ``(M, in, out)`` and runs all
members with ``torch.baddbmm``. Members may have different widths (the paper allows a size
per level): a narrower member is zero-padded, and a fixed 0/1 mask keeps the padded weights
at exactly zero, so each member computes exactly its own MLP. Only the layers where widths
differ carry a mask (usually the output layer): multiplying a large first layer by ones in
every pass cost a fifth of TL-AC's update time. All members need the same number of hidden
layers.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import torch
from torch import nn

HIGH, LOW, CRITIC = 0, 1, 2  # member order in the stack


class StackedMLP(nn.Module):
    """M MLPs with tanh hidden layers, same input, evaluated as one batched computation.

    ``forward(x)`` with ``x`` of shape ``(B, in_dim)`` returns ``(out, last_hidden)`` of shapes
    ``(M, B, max_out)`` and ``(M, B, max_hidden)``; member ``m``'s output is
    ``out[m, :, :out_dims[m]]``.
    """

    def __init__(
        self,
        in_dim: int,
        hidden: list[list[int]],
        out_dims: list[int],
        ortho_init: list[bool],
        out_gains: list[float],
    ):
        super().__init__()
        depths = {len(h) for h in hidden}
        if len(depths) != 1:
            raise ValueError(
                "all levels need the same number of hidden layers to share one stacked network, "
                f"got {hidden}"
            )
        self.members = len(hidden)
        self.out_dims = list(out_dims)
        # widths[m] = [in, h1, ..., hL, out] for member m
        widths = [[in_dim, *h, o] for h, o in zip(hidden, out_dims, strict=True)]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        masks: list[torch.Tensor | None] = []
        for layer in range(len(widths[0]) - 1):
            fan_in = max(w[layer] for w in widths)
            fan_out = max(w[layer + 1] for w in widths)
            weight = torch.zeros(self.members, fan_in, fan_out)
            bias = torch.zeros(self.members, 1, fan_out)
            mask = torch.zeros(self.members, fan_in, fan_out)
            padded = False
            last = layer == len(widths[0]) - 2
            for m, w in enumerate(widths):
                n_in, n_out = w[layer], w[layer + 1]
                mask[m, :n_in, :n_out] = 1.0
                padded = padded or n_in != fan_in or n_out != fan_out
                lin = nn.Linear(n_in, n_out)  # PyTorch's default init (SB3 with ortho_init=False)
                if ortho_init[m]:  # SB3's orthogonal init: sqrt(2) hidden, given gain at the output
                    nn.init.orthogonal_(lin.weight, gain=out_gains[m] if last else math.sqrt(2))
                    nn.init.zeros_(lin.bias)
                weight[m, :n_in, :n_out] = lin.weight.detach().T
                bias[m, 0, :n_out] = lin.bias.detach()
            self.weights.append(nn.Parameter(weight))
            self.biases.append(nn.Parameter(bias))
            masks.append(mask if padded else None)
        for i, mask in enumerate(masks):
            if mask is not None:
                self.register_buffer(f"mask{i}", mask)
        # plain Python references to the same tensors: indexing a ParameterList costs more
        # than the matmul it feeds (load_state_dict copies in place, so they stay valid)
        self._layers = [
            (w, b, masks[i]) for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True))
        ]
        # NumPy views of the same memory, for acting: one small NumPy matmul costs ~1 us of
        # overhead against ~5 us for a PyTorch op, and acting needs no gradient. The
        # optimizer updates the parameters in place, so the views always see current weights.
        self._np_layers = [(w.detach().numpy(), b.detach().numpy()) for w, b, _ in self._layers]

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = x.unsqueeze(0).expand(self.members, *x.shape)
        last = len(self._layers) - 1
        last_hidden = h
        for i, (w, b, mask) in enumerate(self._layers):
            h = torch.baddbmm(b, h, w if mask is None else w * mask)
            if i < last:
                h = torch.tanh(h)
                last_hidden = h
        return h, last_hidden

    @contextmanager
    def first_layer_as(self, weight: torch.Tensor, cols: torch.Tensor) -> Iterator[None]:
        """While open, :meth:`forward` takes rows with the input columns ``cols`` only and
        uses ``weight``, those rows of the first layer's weight (``(M, len(cols), out)``), as
        the first layer (tlac.two_level.fast.stepping_rows). Acting (:meth:`forward_numpy`)
        keeps the whole layer."""
        w, b, mask = self._layers[0]
        self._layers[0] = (weight, b, None if mask is None else mask.index_select(1, cols))
        try:
            yield
        finally:
            self._layers[0] = (w, b, mask)

    def forward_numpy(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`forward` without autograd, in NumPy, for acting. Padded weights are exactly
        zero (the mask is applied in every training forward pass, so gradients never reach
        them), hence no mask is needed here."""
        return tanh_mlp_numpy(self._np_layers, x[None])

    def member_numpy(self, m: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """A copy of member ``m``'s layers as ``(weight, bias)`` NumPy arrays (padded as in the
        stack), for :func:`tanh_mlp_numpy`: a frozen snapshot of one network."""
        return [(w[m].copy(), b[m].copy()) for w, b in self._np_layers]


def tanh_mlp_numpy(
    layers: list[tuple[np.ndarray, np.ndarray]], x: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A tanh MLP's ``(output, last hidden layer)`` in NumPy: ``h = x @ w + b`` per layer, tanh
    between layers. Stacked ``(M, in, out)`` weights with ``x`` of shape ``(1, B, in)`` give
    every member at once; one member's ``(in, out)`` weights with ``(B, in)`` give that one."""
    h = x
    last = len(layers) - 1
    last_hidden = h
    for i, (w, b) in enumerate(layers):
        h = np.matmul(h, w) + b
        if i < last:
            h = np.tanh(h)
            last_hidden = h
    return h, last_hidden


def np_log_softmax(logits: np.ndarray) -> np.ndarray:
    z = logits - logits.max(axis=-1, keepdims=True)
    return z - np.log(np.exp(z).sum(axis=-1, keepdims=True))


def np_sample_categorical(logits: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Gumbel-max sampling: ``argmax(logits + Gumbel noise)`` is a sample of softmax(logits)."""
    return np.argmax(logits + rng.gumbel(size=logits.shape), axis=-1)


def np_gaussian_log_prob(actions: np.ndarray, mean: np.ndarray, log_std: np.ndarray) -> np.ndarray:
    """NumPy twin of :func:`gaussian_log_prob`."""
    return (
        -((actions - mean) ** 2) / (2 * np.exp(2 * log_std)) - log_std - 0.5 * math.log(2 * math.pi)
    ).sum(-1)


def np_gsde_log_std(
    latent: np.ndarray, log_std_matrix: np.ndarray, epsilon: float = 1e-6
) -> np.ndarray:
    """NumPy twin of :func:`gsde_log_std`."""
    return 0.5 * np.log((latent**2) @ np.exp(2 * log_std_matrix) + epsilon)


def gaussian_log_prob(
    actions: torch.Tensor, mean: torch.Tensor, log_std: torch.Tensor
) -> torch.Tensor:
    """Log-density of a diagonal Gaussian, summed over action dimensions."""
    var = torch.exp(2 * log_std)
    return (-((actions - mean) ** 2) / (2 * var) - log_std - 0.5 * math.log(2 * math.pi)).sum(-1)


def gaussian_entropy(log_std: torch.Tensor) -> torch.Tensor:
    """Entropy of a diagonal Gaussian, summed over action dimensions."""
    return (0.5 + 0.5 * math.log(2 * math.pi) + log_std).sum(-1)


def gsde_log_std(
    latent: torch.Tensor, log_std_matrix: torch.Tensor, epsilon: float = 1e-6
) -> torch.Tensor:
    """Per-sample log std of generalized state-dependent exploration (Raffin et al. 2022):
    the action noise is ``latent @ eps_matrix`` with ``eps_matrix ~ N(0, std^2)``, so its variance
    is ``latent^2 @ std^2``. The latent features are detached, as in SB3's default."""
    variance = (latent.detach() ** 2) @ torch.exp(2 * log_std_matrix)
    return 0.5 * torch.log(variance + epsilon)


def categorical_log_probs(logits: torch.Tensor) -> torch.Tensor:
    return torch.log_softmax(logits, dim=-1)


def categorical_entropy(log_probs: torch.Tensor) -> torch.Tensor:
    return -(log_probs.exp() * log_probs).sum(-1)


def member_grad_norms(
    stacked: list[torch.Tensor], members: int, extra: dict[int, list[torch.Tensor]]
) -> torch.Tensor:
    """The L2 norm of each member's gradient, ``(members,)``: the gradients of a stack's
    parameters (each of shape ``(members, ...)``, member ``m`` at index ``m``) plus, per member,
    the gradients of its own separate parameters (``extra``, e.g. the low level's log std).

    >>> w = torch.tensor([[3.0, 0.0], [0.0, 1.0]])
    >>> member_grad_norms([w], 2, {1: [torch.tensor([0.0, 0.0, 1.0])]}).tolist()
    [3.0, 1.4142135381698608]
    """
    squares = torch.zeros(members)
    for grad in stacked:
        squares += grad.pow(2).reshape(members, -1).sum(1)
    for m, grads in extra.items():
        for grad in grads:
            squares[m] += grad.pow(2).sum()
    return squares.sqrt()


def clip_coefficients(norms: torch.Tensor, max_norm: float) -> torch.Tensor:
    """What ``torch.nn.utils.clip_grad_norm_`` multiplies a gradient by, per norm:
    ``min(1, max_norm / (norm + 1e-6))``.

    >>> clip_coefficients(torch.tensor([0.25, 2.0]), 0.5).tolist()
    [1.0, 0.24999988079071045]
    """
    return (max_norm / (norms + 1e-6)).clamp(max=1.0)
