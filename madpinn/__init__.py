"""madpinn: reproduction of MAD-PINN (decentralized physics-informed multi-agent safe control).

Dependency arrows point one way:
dynamics -> value functions -> policies -> simulation -> evaluation -> workflow/figures.
"""

__version__ = "0.1.0"
