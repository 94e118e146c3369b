"""Where do MAD-PINN's collisions come from? Classifies every collision onset of an episode
(issue 14: on either backend; formerly ``scripts/diagnose_collisions.py``, double integrator only).

:class:`CollisionProbe` wraps a MAD-PINN policy (plain or filtered) and, at each collision onset
(pair distance first ≤ r, seen at the policy's decision times) of agents i, j, records:

- ``observed``: j was among i's selected neighbours and i among j's (``both``), one way
  (``one``), or neither (``none``) — ``none``/``one`` point to the n = 2 observation or the
  neighbour choice, ``both`` to V̂, the control or its tracking;
- ``crowd``: other agents within 0.3 m of i or j (more than n = 2 agents in play);
- ``infeasible_lead_s``: how long before the onset V̂ first declared i or j infeasible in the
  uninterrupted infeasible stretch ending at the onset (0 = feasible at the onset);
- ``closing_speed``: −d/dt of the pair distance at the onset (m/s).

:func:`summarise` turns the events into the figures the gap decomposition reports.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import torch


class CollisionProbe:
    """Wraps a MAD-PINN policy; classifies collision onsets seen at its decision times."""

    def __init__(self, policy, r: float, crowd_radius: float = 0.3):
        self.policy, self.r, self.crowd_radius = policy, r, crowd_radius
        self.events: list[dict] = []
        self.scenario_offset = 0

    def __getattr__(self, name):   # stats, summarise_stats, ... of the wrapped policy
        if name == "policy":
            raise AttributeError(name)
        return getattr(self.policy, name)

    def reset(self, state, goals):
        self.policy.reset(state, goals)
        S, N, _ = state.shape
        self.touching = torch.zeros(S, N, N, dtype=torch.bool)
        self.infeasible_since = torch.full((S, N), -1.0)   # start of the current infeasible stretch (s), −1: feasible

    def act(self, state, goals, t):
        u = self.policy.act(state, goals, t)
        mad = getattr(self.policy, "nominal", self.policy)   # madpinn-filtered wraps the MAD-PINN policy
        agent = mad.spec.agent
        p, v = agent.position(state).detach().cpu().double(), agent.velocity(state).detach().cpu().double()
        rel = p[:, :, None] - p[:, None]
        d = rel.norm(dim=-1)
        S, N, _ = d.shape
        eye = torch.eye(N, dtype=torch.bool)
        infeasible = (mad.last_search.z >= mad.vhat.z_max * (1 - 1e-9)).reshape(S, N).cpu()   # z* = z_max
        self.infeasible_since = torch.where(infeasible, torch.where(self.infeasible_since < 0, t, self.infeasible_since),
                                            torch.full_like(self.infeasible_since, -1.0))
        touch = (d <= self.r) & ~eye
        onset = touch & ~self.touching & torch.triu(torch.ones(N, N, dtype=torch.bool), 1)
        nb = mad.neighbours.cpu()
        for s, i, j in onset.nonzero().tolist():
            i_sees_j = bool((nb[s, i] == j).any())
            j_sees_i = bool((nb[s, j] == i).any())
            crowd = int((((d[s, i] < self.crowd_radius) | (d[s, j] < self.crowd_radius)) & ~eye[i] & ~eye[j]).sum())
            starts = [float(self.infeasible_since[s, a]) for a in (i, j) if self.infeasible_since[s, a] >= 0]
            closing = float(-(rel[s, i, j] * (v[s, i] - v[s, j])).sum() / d[s, i, j].clamp_min(1e-9))
            self.events.append({
                "scenario": self.scenario_offset + s, "i": i, "j": j, "t": float(t),
                "observed": "both" if i_sees_j and j_sees_i else ("one" if i_sees_j or j_sees_i else "none"),
                "crowd": crowd, "infeasible_lead_s": float(t - min(starts)) if starts else 0.0,
                "closing_speed": closing, "speed_i": float(v[s, i].norm()), "speed_j": float(v[s, j].norm()),
            })
        self.touching |= touch
        return u


def summarise(events: list[dict]) -> dict:
    """Counts and medians of collision-onset events (see the module docstring)."""
    lead = np.array([e["infeasible_lead_s"] for e in events])
    closing = np.array([e["closing_speed"] for e in events])
    observed = Counter(e["observed"] for e in events)
    n = len(events)
    return {
        "collision_onsets": n,
        "observed": dict(observed),
        "observed_both_share": observed.get("both", 0) / n if n else float("nan"),
        "crowd": {str(k): v for k, v in sorted(Counter(min(e["crowd"], 3) for e in events).items())},
        "feasible_at_onset": int((lead == 0).sum()),
        "feasible_at_onset_share": float((lead == 0).mean()) if n else float("nan"),
        "infeasible_lead_s_median": float(np.median(lead[lead > 0])) if (lead > 0).any() else float("nan"),
        "closing_speed_median": float(np.median(closing)) if n else float("nan"),
        "closing_speed_quartiles": np.percentile(closing, [25, 75]).round(2).tolist() if n else None,
    }
