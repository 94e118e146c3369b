"""System dynamics. Each system owns its bounds, dynamics and (where learned) Hamiltonian."""

from madpinn.dynamics.double_integrator import DoubleIntegrator

__all__ = ["DoubleIntegrator"]
