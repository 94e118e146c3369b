"""System dynamics. Each system owns its bounds, dynamics and (where learned) Hamiltonian.

Agent models implement :class:`~madpinn.dynamics.agent_model.AgentModel`; :data:`MODELS` names
them, and ``agents.model`` chooses one (:meth:`madpinn.settings.AgentSettings.dynamics`).
"""

from madpinn.dynamics.agent_model import AgentModel
from madpinn.dynamics.double_integrator import DoubleIntegrator
from madpinn.dynamics.double_integrator_3d import DoubleIntegrator3D

MODELS: dict[str, type[AgentModel]] = {m.name: m for m in (DoubleIntegrator, DoubleIntegrator3D)}
"""agent models by name (``agents.model``; the planar double integrator of SPEC §1 is the paper's)"""
PAPER_MODEL = DoubleIntegrator.name
"""the model of every description and hash that names none: those written before issue 63 item 2
(value-function checkpoints, settings hashes), which stay as they were"""


def model_class(name: str) -> type[AgentModel]:
    """The agent model named ``name`` (a clear error for an unknown one)."""
    if name not in MODELS:
        raise ValueError(f"unknown agent model {name!r}; known: {sorted(MODELS)}")
    return MODELS[name]


__all__ = ["AgentModel", "DoubleIntegrator", "DoubleIntegrator3D", "MODELS", "PAPER_MODEL", "model_class"]
