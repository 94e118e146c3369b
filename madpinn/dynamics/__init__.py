"""System dynamics. Each system owns its bounds, dynamics and (where learned) Hamiltonian.

Agent models implement :class:`~madpinn.dynamics.agent_model.AgentModel`; :data:`MODELS` names them.
"""

from madpinn.dynamics.agent_model import AgentModel
from madpinn.dynamics.double_integrator import DoubleIntegrator

MODELS: dict[str, type[AgentModel]] = {"double_integrator": DoubleIntegrator}
"""agent models by name (the planar double integrator of SPEC §1 is the paper's)"""
AGENT: type[AgentModel] = MODELS["double_integrator"]
"""the agents' model: the layout (sizes, position and velocity slices) every observation, pair
state and policy row follows"""

__all__ = ["AGENT", "AgentModel", "DoubleIntegrator", "MODELS"]
