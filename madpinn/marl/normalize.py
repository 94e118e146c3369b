"""Running observation and return normalisation (float64 statistics, Chan's parallel update)."""

from __future__ import annotations

import torch

from madpinn.marl.features import LocalObs

CLIP = 10.0


class RunningMeanStd:
    """Mean and variance of a stream of ``[B, F]`` samples."""

    def __init__(self, features: int, eps: float = 1e-4):
        self.mean = torch.zeros(features, dtype=torch.float64)
        self.var = torch.ones(features, dtype=torch.float64)
        self.count = torch.tensor(eps, dtype=torch.float64)

    def update(self, x: torch.Tensor) -> None:
        x = x.detach().cpu().to(torch.float64).reshape(-1, self.mean.numel())
        n = x.shape[0]
        if n == 0:
            return
        mean, var = x.mean(0), x.var(0, unbiased=False)
        delta = mean - self.mean
        total = self.count + n
        self.mean = self.mean + delta * n / total
        self.var = (self.var * self.count + var * n + delta**2 * self.count * n / total) / total
        self.count = total

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        m = self.mean.to(device=x.device, dtype=x.dtype)
        s = self.var.sqrt().clamp_min(1e-6).to(device=x.device, dtype=x.dtype)
        return ((x - m) / s).clamp(-CLIP, CLIP)

    def state_dict(self) -> dict:
        return {"mean": self.mean.clone(), "var": self.var.clone(), "count": self.count.clone()}

    def load_state_dict(self, d: dict) -> None:
        if d["mean"].shape != self.mean.shape:
            raise ValueError(f"normaliser has {d['mean'].numel()} features, expected {self.mean.numel()}")
        self.mean, self.var, self.count = (d[k].to(torch.float64) for k in ("mean", "var", "count"))


class ObsNormalizer:
    """Normalises ego features and (real, unmasked) neighbour features separately."""

    def __init__(self, ego_features: int, neighbour_features: int):
        self.ego = RunningMeanStd(ego_features)
        self.neighbours = RunningMeanStd(neighbour_features)

    def update(self, obs: LocalObs) -> None:
        self.ego.update(obs.ego)
        self.neighbours.update(obs.neighbours[obs.mask])

    def __call__(self, obs: LocalObs) -> LocalObs:
        nbr = self.neighbours.normalize(obs.neighbours) * obs.mask.unsqueeze(-1)
        return LocalObs(self.ego.normalize(obs.ego), nbr, obs.mask)

    def state_dict(self) -> dict:
        return {"ego": self.ego.state_dict(), "neighbours": self.neighbours.state_dict()}

    def load_state_dict(self, d: dict) -> None:
        self.ego.load_state_dict(d["ego"])
        self.neighbours.load_state_dict(d["neighbours"])


class ReturnNormalizer:
    """Scales rewards by the running std of the discounted return (per env × agent stream)."""

    def __init__(self, discount: float):
        self.discount = float(discount)
        self.rms = RunningMeanStd(1)
        self._ret: torch.Tensor | None = None

    def reset(self, shape: torch.Size, device=None) -> None:
        self._ret = torch.zeros(shape, dtype=torch.float64, device=device)

    def __call__(self, reward: torch.Tensor) -> torch.Tensor:
        if self._ret is None or self._ret.shape != reward.shape:
            self.reset(reward.shape, reward.device)
        self._ret = self._ret * self.discount + reward.to(torch.float64)
        self.rms.update(self._ret.reshape(-1, 1))
        return reward / float(self.rms.var.sqrt().clamp_min(1e-6))

    def state_dict(self) -> dict:
        return self.rms.state_dict()

    def load_state_dict(self, d: dict) -> None:
        self.rms.load_state_dict(d)
