"""System dynamics. Each system owns its bounds, dynamics and (where learned) Hamiltonian.

Agent models implement :class:`~madpinn.dynamics.agent_model.AgentModel`, one module each; the
package imports every one of its modules, so :data:`MODELS` holds each model a module defines
(nothing lists them), and ``agents.model`` chooses one (:meth:`madpinn.settings.AgentSettings.dynamics`).
"""

from madpinn.dynamics.agent_model import AgentModel, model_class, registered_models
from madpinn.dynamics.double_integrator import DoubleIntegrator
from madpinn.submodules import import_submodules

import_submodules(__name__)   # each agent model's module registers its model (and a job's hash reaches them all)
MODELS: dict[str, type[AgentModel]] = registered_models()
"""agent models by name (``agents.model``; the planar double integrator of SPEC §1 is the paper's)"""
PAPER_MODEL = DoubleIntegrator.name
"""the model of every description and hash that names none: those written before issue 63 item 2
(value-function checkpoints, settings hashes), which stay as they were"""


__all__ = ["AgentModel", "DoubleIntegrator", "MODELS", "PAPER_MODEL", "model_class"]
