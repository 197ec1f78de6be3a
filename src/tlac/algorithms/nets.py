"""Networks for TL-AC: the high-level actor, the low-level actor and the shared critic
(paper, section 3.2 and Figure 1), evaluated together in ONE batched matmul per layer.

With [64, 64] networks eager PyTorch spends its time on dispatch, not arithmetic, so three
separate MLPs cost three times the kernel launches of one stacked MLP. :class:`StackedMLP`
holds the weights of M member networks in tensors of shape ``(M, in, out)`` and runs all
members with ``torch.baddbmm``. Members may have different widths (the paper allows a size
per level): a narrower member is zero-padded, and a fixed 0/1 mask keeps the padded weights
at exactly zero, so each member computes exactly its own MLP. All members need the same
number of hidden layers.
"""

from __future__ import annotations

import math

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
                f"all levels need the same number of hidden layers to share one stacked network, got {hidden}"
            )
        self.members = len(hidden)
        self.out_dims = list(out_dims)
        # widths[m] = [in, h1, ..., hL, out] for member m
        widths = [[in_dim, *h, o] for h, o in zip(hidden, out_dims, strict=True)]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        masks = []
        self.needs_mask = False
        for layer in range(len(widths[0]) - 1):
            fan_in = max(w[layer] for w in widths)
            fan_out = max(w[layer + 1] for w in widths)
            weight = torch.zeros(self.members, fan_in, fan_out)
            bias = torch.zeros(self.members, 1, fan_out)
            mask = torch.zeros(self.members, fan_in, fan_out)
            last = layer == len(widths[0]) - 2
            for m, w in enumerate(widths):
                n_in, n_out = w[layer], w[layer + 1]
                mask[m, :n_in, :n_out] = 1.0
                if n_in != fan_in or n_out != fan_out:
                    self.needs_mask = True
                lin = nn.Linear(n_in, n_out)  # PyTorch's default init (SB3 with ortho_init=False)
                if ortho_init[m]:  # SB3's orthogonal init: sqrt(2) hidden, given gain at the output
                    nn.init.orthogonal_(lin.weight, gain=out_gains[m] if last else math.sqrt(2))
                    nn.init.zeros_(lin.bias)
                weight[m, :n_in, :n_out] = lin.weight.detach().T
                bias[m, 0, :n_out] = lin.bias.detach()
            self.weights.append(nn.Parameter(weight))
            self.biases.append(nn.Parameter(bias))
            masks.append(mask)
        for i, mask in enumerate(masks):
            self.register_buffer(f"mask{i}", mask)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = x.unsqueeze(0).expand(self.members, *x.shape)
        n_layers = len(self.weights)
        last_hidden = h
        for i in range(n_layers):
            w = self.weights[i]
            if self.needs_mask:
                w = w * getattr(self, f"mask{i}")
            h = torch.baddbmm(self.biases[i], h, w)
            if i < n_layers - 1:
                h = torch.tanh(h)
                last_hidden = h
        return h, last_hidden


def gaussian_log_prob(actions: torch.Tensor, mean: torch.Tensor, log_std: torch.Tensor) -> torch.Tensor:
    """Log-density of a diagonal Gaussian, summed over action dimensions."""
    var = torch.exp(2 * log_std)
    return (-((actions - mean) ** 2) / (2 * var) - log_std - 0.5 * math.log(2 * math.pi)).sum(-1)


def gaussian_entropy(log_std: torch.Tensor) -> torch.Tensor:
    """Entropy of a diagonal Gaussian, summed over action dimensions."""
    return (0.5 + 0.5 * math.log(2 * math.pi) + log_std).sum(-1)


def gsde_log_std(latent: torch.Tensor, log_std_matrix: torch.Tensor, epsilon: float = 1e-6) -> torch.Tensor:
    """Per-sample log std of generalized state-dependent exploration (Raffin et al. 2022):
    the action noise is ``latent @ eps_matrix`` with ``eps_matrix ~ N(0, std^2)``, so its variance
    is ``latent^2 @ std^2``. The latent features are detached, as in SB3's default."""
    variance = (latent.detach() ** 2) @ torch.exp(2 * log_std_matrix)
    return 0.5 * torch.log(variance + epsilon)


def categorical_log_probs(logits: torch.Tensor) -> torch.Tensor:
    return torch.log_softmax(logits, dim=-1)


def categorical_entropy(log_probs: torch.Tensor) -> torch.Tensor:
    return -(log_probs.exp() * log_probs).sum(-1)


def sample_categorical(logits: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
    """Gumbel-max sampling: ``argmax(logits + Gumbel noise)`` is a sample of softmax(logits)."""
    u = torch.rand(logits.shape, generator=generator).clamp_(1e-20, 1.0)
    return torch.argmax(logits - torch.log(-torch.log(u)), dim=-1)
