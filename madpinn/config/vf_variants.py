"""Value-function variants (``value_functions.vhat_variants``, ``value_functions.vs_variants``):
model names and the merged settings a variant trains with (its own agent model among them)."""

from __future__ import annotations

from typing import Any, Mapping

from madpinn.config.errors import ConfigError
from madpinn.config.merge import deep_merge
from madpinn.config.models import with_model


VF_VARIANTS = {"vhat": "vhat_variants", "vs": "vs_variants"}
"""value-function kind -> its section of variants (``value_functions.<section>.<name>``, each
deep-merged over ``value_functions.<kind>``; trained model ``<kind>_<name>``)"""


def stop_at_problem(stop_at: int | None, iterations: int) -> str | None:
    """What is wrong with ending a training of an ``iterations``-long schedule at ``stop_at`` (None:
    nothing; ``stop_at`` None runs the whole schedule): it must lie in 1..iterations."""
    if stop_at is None or 0 < stop_at <= iterations:
        return None
    return f"stop_at ({stop_at}) must lie in 1..iterations ({iterations}): it ends the run inside its schedule"


def vf_model_name(kind: str, variant: str | None = None) -> str:
    """The model name of value function ``kind`` (``vhat``) or of its variant (``vhat_h04``)."""
    return f"{kind}_{variant}" if variant else kind


def split_vf_model(name: str) -> tuple[str, str | None] | None:
    """``(kind, variant)`` of a value-function model name (``vhat`` -> ``("vhat", None)``,
    ``vhat_h04`` -> ``("vhat", "h04")``, ``vs_3d`` -> ``("vs", "3d")``); None for any other name."""
    if name in ("vhat", "vs"):
        return name, None
    kind, _, variant = name.partition("_")
    return (kind, variant) if kind in VF_VARIANTS and variant else None


FROM = "from"
"""a variant's key naming the variant it derives from (``b05: {from: cs, ...}``): its settings are
that variant's, resolved first, with its own merged over them"""


def variant_settings(variants: Mapping[str, Any], variant: str, kind: str = "vhat", section: str | None = None) -> dict:
    """The settings of ``variant`` (a key of ``variants``: one ``value_functions.<kind>_variants``)
    with its ``from`` chain resolved: the named variant's resolved settings, its own deep-merged over
    them (without ``from``). Raises :class:`ConfigError` on an unknown name or a cycle."""
    section = section or VF_VARIANTS.get(kind, f"{kind}_variants")
    chain: list[str] = []
    name: Any = variant
    while name is not None:
        if name in chain:
            raise ConfigError(f"value_functions.{section}.{variant}: its 'from' chain returns to '{name}' "
                              f"({' -> '.join([*chain, name])})")
        if name not in variants:
            where = f"{chain[-1]}.from" if chain else variant
            raise ConfigError(f"unknown {kind} variant '{name}' (value_functions.{section}{'.' + where if chain else ''}: "
                              f"{sorted(variants) or 'none'})")
        chain.append(name)
        name = variants[name].get(FROM)
    settings: dict = {}
    for name in reversed(chain):
        settings = deep_merge(settings, {k: v for k, v in variants[name].items() if k != FROM})
    return settings


def with_vf_variant(cfg: Mapping[str, Any], kind: str, variant: str | None) -> dict:
    """``cfg`` with ``value_functions.<kind>`` replaced by variant ``variant`` (its ``from`` chain
    resolved: :func:`variant_settings`) deep-merged over it and, where the variant names an agent
    model (its ``agents``: issue 63), ``agents`` with that model merged over it (``variant`` None:
    ``cfg`` itself). What a variant's training, its training hash and its checks read: every other
    key is the base configuration's."""
    if not variant:
        return cfg
    section = VF_VARIANTS.get(kind)
    variants = cfg["value_functions"][section] if section else {}
    resolved = variant_settings(variants, variant, kind, section or kind + "_variants")
    settings = {k: v for k, v in resolved.items() if k != "agents"}
    vf = {**cfg["value_functions"], kind: deep_merge(cfg["value_functions"][kind], settings)}
    model = resolved.get("agents")   # an overlay: absent = the configuration's model
    return {**cfg, "value_functions": vf, **({"agents": with_model(cfg["agents"], model)} if model else {})}
