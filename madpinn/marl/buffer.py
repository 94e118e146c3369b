"""Rollout storage: one entry per policy period, tensors ``[E, N, …]`` stacked to ``[T, E, N, …]``."""

from __future__ import annotations

import torch

from madpinn.marl.features import LocalObs


class RolloutBuffer:
    """Append with :meth:`add` (the network input as the actor saw it, plus any named tensors:
    ``action``, ``logp``, ``value``, ``reward``, and whatever an extension needs), then read
    stacked tensors with :meth:`get` and the flattened observations with :meth:`flat_obs`."""

    def __init__(self):
        self._obs: list[LocalObs] = []
        self._data: dict[str, list[torch.Tensor]] = {}

    def __len__(self) -> int:
        return len(self._obs)

    def add(self, obs: LocalObs, **tensors: torch.Tensor) -> None:
        if self._data and set(tensors) != set(self._data):
            raise ValueError(f"buffer entries must all have the same keys: {sorted(self._data)} vs {sorted(tensors)}")
        self._obs.append(obs)
        for k, v in tensors.items():
            self._data.setdefault(k, []).append(v.detach())

    def get(self, name: str) -> torch.Tensor:
        """``[T, E, N, …]``."""
        if name not in self._data:
            raise KeyError(f"no '{name}' in the rollout buffer (have {sorted(self._data)})")
        return torch.stack(self._data[name])

    def flat_obs(self) -> LocalObs:
        """All stored observations as one flat batch ``[T·E·N, …]`` (same order as ``get(x).reshape(-1, …)``)."""
        return LocalObs(
            torch.stack([o.ego for o in self._obs]),
            torch.stack([o.neighbours for o in self._obs]),
            torch.stack([o.mask for o in self._obs]),
        ).flatten()
