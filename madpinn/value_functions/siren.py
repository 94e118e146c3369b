"""SIREN MLP with exact, hand-derived input gradients and a hand-derived training backward.

``N(x) = w_o · h_L + b_o`` with ``h_l = sin(a_l)``, ``a_l = ω_l (W_l h_{l−1} + b_l)``, ``h_0 = x``
(Sitzmann et al. 2020 initialisation; ``ω_1 = first_omega``, hidden ``ω = hidden_omega``).

A PINN loss needs ``N`` and its input gradient ``∇_x N``; its parameter gradient is a second-order
(double-backward) quantity. Instead of autograd's ``create_graph=True`` double backward, this
module computes

- :meth:`Siren.value_and_input_grad`: ``N`` and ``∇_x N`` in one forward and one reverse sweep
  (analytic, no autograd; used by policies under ``torch.no_grad()``), and
- :meth:`Siren.accumulate_loss_grad`: the same two sweeps, then the exact adjoint of both
  (``6`` matrix products per hidden layer, like autograd, but no graph, fused elementwise work,
  buffers reused in place), accumulating ``∂loss/∂θ`` into ``.grad``.

Shapes: ``x [B, d_in]`` (normalised inputs), ``N [B]``, ``∇_x N [B, d_in]``.
"""

from __future__ import annotations

import math
from typing import Callable

import torch
from torch import nn


class Siren(nn.Module):
    def __init__(self, in_features: int, hidden: int = 256, layers: int = 3,
                 first_omega: float = 30.0, hidden_omega: float = 30.0):
        super().__init__()
        if layers < 1 or hidden < 1 or in_features < 1:
            raise ValueError("Siren needs in_features, hidden, layers ≥ 1")
        self.in_features, self.hidden, self.n_layers = in_features, hidden, layers
        self.omegas = [float(first_omega)] + [float(hidden_omega)] * (layers - 1)
        dims = [in_features] + [hidden] * layers
        self.hidden_layers = nn.ModuleList(nn.Linear(dims[i], dims[i + 1]) for i in range(layers))
        self.out = nn.Linear(hidden, 1)
        self.reset_parameters()

    def reset_parameters(self) -> None:
        with torch.no_grad():
            for i, lin in enumerate(self.hidden_layers):
                fan_in = lin.in_features
                bound = 1.0 / fan_in if i == 0 else math.sqrt(6.0 / fan_in) / self.omegas[i]
                lin.weight.uniform_(-bound, bound)
                lin.bias.uniform_(-1.0 / math.sqrt(fan_in), 1.0 / math.sqrt(fan_in))
            bound = math.sqrt(6.0 / self.hidden) / self.omegas[-1]
            self.out.weight.uniform_(-bound, bound)
            self.out.bias.zero_()

    # ---- plain autograd forward (reference, tests) --------------------------------------
    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = x
        for lin, w in zip(self.hidden_layers, self.omegas):
            h = torch.sin(w * lin(h))
        return self.out(h)[..., 0]

    def forward_reusing_buffers(self, x: torch.Tensor) -> torch.Tensor:
        """:meth:`forward` under ``torch.no_grad()`` with the same operations in the same order,
        each layer's ``[B, hidden]`` activations written in place into a reused workspace buffer
        (no fresh large allocation per call), so ``N [B]`` is bitwise :meth:`forward`'s."""
        with torch.no_grad():
            h = x
            for i, (lin, w) in enumerate(zip(self.hidden_layers, self.omegas)):
                a = self._buffer(("forward", i), (x.shape[0], lin.out_features), x)
                h = torch.addmm(lin.bias, h, lin.weight.t(), out=a).mul_(w).sin_()   # sin(ω·lin(h))
            return torch.addmm(self.out.bias, h, self.out.weight.t())[:, 0]

    # ---- analytic input gradient ----------------------------------------------------------
    def _kept(self, name: str, build: Callable[[], list]) -> list:
        """``build()`` (tensors derived from the parameters, built under ``no_grad``), kept until a
        parameter changes: its storage or its version counter, which every in-place update such as
        an optimiser step moves."""
        key = tuple((p.data_ptr(), p._version) for lin in (*self.hidden_layers, self.out) for p in (lin.weight, lin.bias))
        kept = self.__dict__.setdefault("_kept_tensors", {})
        if name not in kept or kept[name][0] != key:
            with torch.no_grad():
                kept[name] = (key, build())
        return kept[name][1]

    def _scaled(self):
        """``(ω_l W_l, ω_l b_l)`` per hidden layer: the frequencies folded into the weights."""
        return self._kept("scaled", lambda: [(w * lin.weight, w * lin.bias) for lin, w in zip(self.hidden_layers, self.omegas)])

    def _sweeps(self, x: torch.Tensor, reuse: bool):
        """Forward sweep (``h_l = sin a_l``, ``cos a_l``) and reverse sweep ``∂N/∂h_{l−1} =
        (cos a_l ⊙ ∂N/∂h_l) V_l``; returns ``(N [B], ∇_x N [B, d_in])``. ``reuse``: every
        ``[B, hidden]`` intermediate is written into a reused workspace buffer (the same operations,
        so bitwise the same results; the two returned tensors are fresh)."""
        scaled = self._scaled()
        B = x.shape[0]
        out = (lambda key: self._buffer(("sweeps", key), (B, self.hidden), x)) if reuse else (lambda key: None)  # noqa: E731
        cs, h = [], x
        for layer, (weight, bias) in enumerate(scaled):
            a = torch.addmm(bias, h, weight.t(), out=out(("a", layer)))
            h = torch.sin(a, out=out(("h", layer)))
            cs.append(a.cos_())
        n = torch.addmm(self.out.bias, h, self.out.weight.t())[:, 0]
        g = self.out.weight.expand(B, -1)
        for layer in range(self.n_layers - 1, -1, -1):
            dp = torch.mul(cs[layer], g, out=out(("dp", layer)))   # δ'_l = cos(a_l) ⊙ ∂N/∂h_l
            g = torch.mm(dp, scaled[layer][0], out=out(("g", layer)) if layer else None)   # ∂N/∂h_{l−1}
        return n, g

    def value_and_input_grad(self, x: torch.Tensor, reuse: bool = False):
        """``N [B]`` and ``∇_x N [B, d_in]`` without autograd (exact); ``reuse``: the ``[B, hidden]``
        intermediates in reused workspace buffers (bitwise the same; both returned tensors fresh)."""
        with torch.no_grad():
            return self._sweeps(x.detach(), reuse=reuse)

    def input_grad_reusing_buffers(self, x: torch.Tensor) -> torch.Tensor:
        """``∇_x N [B, d_in]``, bitwise :meth:`value_and_input_grad`'s, its ``[B, hidden]``
        intermediates in reused workspace buffers (no fresh large allocation per call)."""
        with torch.no_grad():
            return self._sweeps(x.detach(), reuse=True)[1]

    # ---- fused training backward ----------------------------------------------------------
    def _buffer(self, key, shape, like: torch.Tensor) -> torch.Tensor:
        """Reusable workspace tensor of ``shape`` (fresh large CPU allocations cost page faults
        each time): the first ``shape[0]`` rows, a contiguous view, of a buffer that only grows,
        so calls with varying batch sizes reuse it too."""
        ws = self.__dict__.setdefault("_workspace", {})
        buf = ws.get(key)
        if buf is None or buf.shape[1:] != shape[1:] or buf.dtype != like.dtype or buf.device != like.device:
            buf = None
        if buf is None or buf.shape[0] < shape[0]:
            buf = torch.empty((shape[0], *shape[1:]), dtype=like.dtype, device=like.device)
            ws[key] = buf
        return buf[: shape[0]]

    def accumulate_loss_grad(
        self, x: torch.Tensor,
        head: Callable[[torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor, torch.Tensor]],
    ):
        """Compute ``N`` and ``∇_x N``, call ``head(N, ∇_x N) -> (loss, ∂loss/∂N, ∂loss/∂∇_x N)``
        and add the exact ``∂loss/∂θ`` to every parameter's ``.grad``. Returns ``(loss, N, ∇_x N)``.

        With ``V_l = ω_l W_l``: ``a_l = V_l h_{l−1} + ω_l b_l``, ``g_{l−1} = δ'_l V_l``,
        ``δ'_l = cos(a_l) ⊙ g_l``; the adjoints (bars) of both sweeps give ``∂/∂V_l`` and
        ``∂/∂W_l = ω_l ∂/∂V_l``. All ``[B, hidden]`` intermediates live in a reused workspace
        (13 buffers for 3 layers) and are overwritten in place once dead.
        """
        with torch.no_grad():
            x = x.detach()
            L, B, H = self.n_layers, x.shape[0], self.hidden
            buf = lambda key: self._buffer(key, (B, H), x)  # noqa: E731
            scaled = self._scaled()
            w_o = self.out.weight  # [1, H]
            cs, hs = [None] + [buf(("c", l)) for l in range(1, L + 1)], [x] + [buf(("h", l)) for l in range(1, L + 1)]
            dps = [None] + [buf(("dp", l)) for l in range(1, L + 1)]
            gs = [None] + [buf(("g", l)) for l in range(1, L)] + [w_o.expand(B, H)]
            # forward sweep: cs[l] = cos a_l, hs[l] = sin a_l
            for layer in range(1, L + 1):
                weight, bias = scaled[layer - 1]
                torch.addmm(bias, hs[layer - 1], weight.t(), out=cs[layer])
                torch.sin(cs[layer], out=hs[layer])
                cs[layer].cos_()
            n = torch.addmm(self.out.bias, hs[L], w_o.t())[:, 0]
            # reverse sweep: ∇_x N
            for layer in range(L, 0, -1):
                torch.mul(cs[layer], gs[layer], out=dps[layer])
                if layer > 1:
                    torch.mm(dps[layer], scaled[layer - 1][0], out=gs[layer - 1])
            g0 = torch.mm(dps[1], scaled[0][0])
            loss, n_bar, g_bar = head(n, g0)
            # adjoint of the ∇_x N sweep, from the input layer upwards
            v_bar, a_from_cos = [None] * (L + 1), [None] * (L + 1)
            gb = g_bar
            for layer in range(1, L + 1):
                dp_bar = buf("dp_bar_top") if layer == L else buf("dp_bar")
                torch.mm(gb, scaled[layer - 1][0].t(), out=dp_bar)  # ∂/∂δ'_l
                v_bar[layer] = torch.mm(dps[layer].t(), gb)
                gb = torch.mul(dp_bar, cs[layer], out=dps[layer])  # ∂/∂g_l (δ'_l is dead now)
                if layer < L:  # minus ∂/∂a_l through cos: δ̄'⊙g_l⊙sin a_l, stored over g_l
                    a_from_cos[layer] = gs[layer].mul_(dp_bar).mul_(hs[layer])
                else:
                    a_from_cos[layer] = dp_bar.mul_(gs[layer]).mul_(hs[layer])
            w_out_grad = gb.sum(0, keepdim=True)  # g_L = w_o for every sample
            # adjoint of the forward sweep, from the output downwards
            w_out_grad.add_(torch.mm(n_bar[None, :], hs[L]))
            grads = {self.out.weight: w_out_grad, self.out.bias: n_bar.sum().reshape(1)}
            h_bar = torch.mul(n_bar[:, None], w_o, out=dps[L])
            for layer in range(L, 0, -1):
                lin, w = self.hidden_layers[layer - 1], self.omegas[layer - 1]
                ab = cs[layer].mul_(h_bar).sub_(a_from_cos[layer])  # ∂/∂a_l, over cos a_l
                v_bar[layer].addmm_(ab.t(), hs[layer - 1])
                grads[lin.weight] = v_bar[layer].mul_(w)
                grads[lin.bias] = ab.sum(0).mul_(w)
                if layer > 1:
                    h_bar = torch.mm(ab, scaled[layer - 1][0], out=hs[layer])  # h_l is dead now
            for p, gr in grads.items():
                if p.grad is None:
                    p.grad = gr
                else:
                    p.grad.add_(gr)
        return loss, n, g0
