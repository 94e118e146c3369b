"""Box-control systems: the Hamiltonian and the optimal control derived once from the control set.

In the style of hj_reachability's ``dynamics.py``: a system is control affine,
``f(x, u) = w(x) + B u`` with ``u`` in the box ``[−ū, ū]^m``, and declares

- ``control_mode``: ``"min"`` (the control minimises the value: V̂'s cost) or ``"max"`` (it
  maximises it: V_s's safety margin),
- ``control_bound``: ū (per axis),
- ``control_grad(∇V)``: the block ``Bᵀ∇V`` the control multiplies (shape ``[..., *control]``),
- its control-free part ``⟨∇V, w(x)⟩`` (the system's own ``drift``).

Then ``H = ⟨∇V, w⟩ ∓ ū·‖Bᵀ∇V‖₁`` and ``u* = ∓ū·sign(Bᵀ∇V)`` (− for ``min``, + for ``max``)
follow here, once. A new system is its domain, target and these four items.
"""

from __future__ import annotations

from typing import ClassVar

import torch


class BoxControlSystem:
    """Mixin deriving :meth:`hamiltonian_from` and :meth:`optimal_control` from the control set."""

    control_mode: ClassVar[str]
    """``"min"`` or ``"max"``: what the control does to the value"""
    control_ndim: ClassVar[int] = 1
    """trailing dimensions of :meth:`control_grad` (1: ``[..., m]``; 2: ``[..., agents, d]``)"""

    @property
    def control_bound(self) -> float:
        """ū: per-axis bound of the control box."""
        raise NotImplementedError

    def control_grad(self, grad: torch.Tensor) -> torch.Tensor:
        """``Bᵀ∇V``: the gradient block the control multiplies."""
        raise NotImplementedError

    def hamiltonian_from(self, drift: torch.Tensor, grad: torch.Tensor) -> torch.Tensor:
        """``opt_u ⟨∇V, w + B u⟩`` ``[B]`` given the control-free part ``drift = ⟨∇V, w⟩``."""
        dims = tuple(range(-self.control_ndim, 0))
        box = self.control_bound * self.control_grad(grad).abs().sum(dims if len(dims) > 1 else dims[0])
        return drift - box if self.control_mode == "min" else drift + box

    def optimal_control(self, grad: torch.Tensor) -> torch.Tensor:
        """Bang-bang optimiser ``∓ū·sign(Bᵀ∇V)`` (shape of :meth:`control_grad`)."""
        return self.bang_bang(self.control_grad(grad))

    def bang_bang(self, block: torch.Tensor) -> torch.Tensor:
        """``∓ū·sign(block)`` of the block ``Bᵀ∇V`` (:meth:`control_grad`) itself."""
        bound = -self.control_bound if self.control_mode == "min" else self.control_bound
        return bound * torch.sign(block)
