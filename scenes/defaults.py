"""Default materials and thermal offsets per target kind and part role.

Sources and reasoning in docs/PHYSICS.md ("Thermal part defaults"): LWIR emissivities of the real
materials (plastics and painted or carbon composites ~0.9-0.95, black-anodised aluminium motor bells
~0.8-0.9, so motors emit rather than mirror the sky); motor temperature rise from infrared
thermography of hovering quadcopters (37-44 C motors, i.e. ~+15-20 K over ambient, at no payload:
Processes 2025, 13(10), 3034); motors and battery are the hottest parts. Birds: infrared
thermography of starlings flying in a wind tunnel (Ward et al. 1999, J. Exp. Biol. 202:1589-1602):
head +6.0 K, ventral brachial areas +5.3 K, flight feathers +2.2-2.5 K over air; feathers insulate,
so a bird is near ambient with a warm head and body. Airliner engines: the nacelle role carries the
side-view area average of the hot exhaust nozzle and the near-ambient nacelle skin (docs/PHYSICS.md).
"""
from __future__ import annotations

from scenes.schema import Material, Target

_MATERIALS: dict[str, Material] = {
    "body": Material(rgb_reflectance=(0.06, 0.06, 0.065), emissivity=0.92),
    "arm": Material(rgb_reflectance=(0.05, 0.05, 0.05), emissivity=0.9),
    "motor": Material(rgb_reflectance=(0.08, 0.08, 0.09), emissivity=0.85),
    "prop": Material(rgb_reflectance=(0.04, 0.04, 0.04), emissivity=0.88),
    "battery": Material(rgb_reflectance=(0.15, 0.15, 0.16), emissivity=0.9),
    "camera": Material(rgb_reflectance=(0.03, 0.03, 0.03), emissivity=0.85),
    "wing": Material(rgb_reflectance=(0.7, 0.7, 0.72), emissivity=0.88),
    "fuselage": Material(rgb_reflectance=(0.75, 0.75, 0.78), emissivity=0.85),
    "tail": Material(rgb_reflectance=(0.7, 0.7, 0.72), emissivity=0.85),
    "engine": Material(rgb_reflectance=(0.5, 0.5, 0.52), emissivity=0.6),
    "head": Material(rgb_reflectance=(0.2, 0.18, 0.15), emissivity=0.95),
    "exhaust": Material(rgb_reflectance=(0.12, 0.11, 0.1), emissivity=0.8),
    "feather": Material(rgb_reflectance=(0.25, 0.22, 0.18), emissivity=0.95),
}

_OFFSETS_K: dict[str, dict[str, float]] = {
    "quadcopter": {"body": 5.0, "arm": 2.0, "motor": 20.0, "prop": 0.5, "battery": 12.0, "camera": 6.0},
    "hexacopter": {"body": 5.0, "arm": 2.0, "motor": 22.0, "prop": 0.5, "battery": 14.0, "camera": 6.0},
    "fixed_wing": {"fuselage": 4.0, "wing": 1.0, "tail": 1.0, "motor": 30.0, "prop": 1.0, "body": 4.0},
    "bird": {"body": 4.0, "head": 6.0, "feather": 2.2, "wing": 2.3},
    "airliner": {"fuselage": -2.0, "wing": -3.0, "tail": -3.0, "engine": 80.0},
    # turboshaft: exhaust duct metal a few hundred kelvin above air, warm cowling, sun-warmed cabin
    # (docs/PHYSICS.md "Helicopter")
    "helicopter": {"fuselage": 3.0, "tail": 1.0, "engine": 35.0, "exhaust": 200.0, "prop": 0.5, "body": 2.0},
}

#: the parts of each kind whose visible colour is its paint (a generation config's ``paint_reflectance``
#: redraws them): the shell a camera sees, not the motors, rotors, lenses or engines
PAINTED_ROLES: dict[str, tuple[str, ...]] = {
    "quadcopter": ("body", "arm", "battery"),
    "hexacopter": ("body", "arm", "battery"),
    "fixed_wing": ("fuselage", "wing", "tail", "body"),
    "bird": ("body", "head", "wing", "feather"),
    "airliner": ("fuselage", "wing", "tail"),
    "helicopter": ("fuselage", "tail", "body"),
}

_MATERIAL_OVERRIDES: dict[str, dict[str, Material]] = {
    "bird": {
        "body": Material(rgb_reflectance=(0.25, 0.22, 0.18), emissivity=0.95),
        "wing": Material(rgb_reflectance=(0.22, 0.2, 0.17), emissivity=0.95),
    },
}


def material_for(target: Target, role: str) -> Material:
    if role in target.materials:
        return target.materials[role]
    kind_overrides = _MATERIAL_OVERRIDES.get(target.kind, {})
    return kind_overrides.get(role, _MATERIALS.get(role, _MATERIALS["body"]))


def offset_for(target: Target, role: str, *, end: bool = False) -> float:
    source = (target.thermal.offsets_end_k if end and target.thermal.offsets_end_k is not None
              else target.thermal.offsets_k)
    if role in source:
        return source[role]
    return _OFFSETS_K[target.kind].get(role, 2.0)
