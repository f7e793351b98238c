"""Terrain and horizon-clutter assets: the surface properties of each named asset (pure data).

Each asset is one material: visible albedo (linear sRGB), LWIR emissivity, solar absorptivity and
the two effective heat-transfer coefficients of the surface energy balance
(simulator.physics.terrain_thermal), plus default dimensions. Sources in docs/PHYSICS.md
("Terrain"): albedos from Oke, *Boundary Layer Climates* (1987) table 1.1; LWIR emissivities from
the ECOSTRESS spectral library (Meerdink et al. 2019; grass, conifer/deciduous leaves, soil,
asphalt, brick, galvanised steel); the heat-transfer coefficients are effective values chosen so
that the midday / clear-night temperature differences to air match the ranges reported there
(grass and tree canopies within a few kelvin of air, dry soil and asphalt far warmer at midday).
"""
from __future__ import annotations

from dataclasses import dataclass

Category = str  # "ground" | "trees" | "building" | "mast"


@dataclass(frozen=True)
class TerrainAsset:
    category: Category
    rgb_albedo: tuple[float, float, float]
    emissivity: float
    solar_absorptivity: float
    h_day_w_m2k: float       # effective heat loss coefficient in sunlight (convection + evapotranspiration + storage)
    h_night_w_m2k: float     # the same at night
    texture: float = 0.25    # relative albedo variation across the surface (rms of the multiplier)
    temperature_texture_k: float = 0.8  # rms surface-temperature variation
    width_m: float = 0.0     # default footprint (buildings, masts)
    depth_m: float = 0.0
    height_m: float = 0.0


TERRAIN_ASSETS: dict[str, TerrainAsset] = {
    # ground covers
    "grass": TerrainAsset("ground", (0.10, 0.16, 0.06), 0.98, 0.77, 80.0, 20.0, 0.25, 0.8),
    "field": TerrainAsset("ground", (0.26, 0.21, 0.14), 0.95, 0.80, 30.0, 15.0, 0.30, 1.5),
    "soil": TerrainAsset("ground", (0.16, 0.12, 0.08), 0.95, 0.85, 30.0, 15.0, 0.20, 1.2),
    "asphalt": TerrainAsset("ground", (0.09, 0.09, 0.10), 0.95, 0.90, 25.0, 40.0, 0.10, 0.5),
    "snow": TerrainAsset("ground", (0.80, 0.82, 0.85), 0.99, 0.20, 20.0, 10.0, 0.05, 0.4),
    # tree lines
    "deciduous": TerrainAsset("trees", (0.06, 0.10, 0.04), 0.97, 0.82, 150.0, 40.0, 0.25, 0.6, height_m=16.0),
    "conifer": TerrainAsset("trees", (0.04, 0.07, 0.04), 0.98, 0.88, 130.0, 40.0, 0.20, 0.6, height_m=20.0),
    # buildings
    "house": TerrainAsset("building", (0.45, 0.38, 0.32), 0.92, 0.60, 25.0, 30.0, 0.10, 0.5, 10.0, 8.0, 7.0),
    "barn": TerrainAsset("building", (0.50, 0.50, 0.50), 0.90, 0.55, 25.0, 25.0, 0.08, 0.5, 25.0, 12.0, 9.0),
    "block": TerrainAsset("building", (0.55, 0.53, 0.50), 0.92, 0.55, 25.0, 35.0, 0.08, 0.5, 30.0, 15.0, 30.0),
    # masts (thin: usually sub-pixel in width, visible as a line)
    "lattice_mast": TerrainAsset("mast", (0.45, 0.45, 0.45), 0.30, 0.60, 50.0, 25.0, 0.0, 0.3, 1.2, 1.2, 40.0),
    "pole": TerrainAsset("mast", (0.35, 0.30, 0.25), 0.93, 0.70, 50.0, 25.0, 0.0, 0.3, 0.35, 0.35, 12.0),
}


def assets_of(category: Category) -> list[str]:
    return sorted(name for name, a in TERRAIN_ASSETS.items() if a.category == category)


def check_asset(name: str, category: Category) -> str:
    """The name if it is a known asset of this category; ValueError (pydantic names the field) if not."""
    asset = TERRAIN_ASSETS.get(name)
    if asset is None or asset.category != category:
        raise ValueError(f"unknown terrain asset {name!r} for {category}; known: {', '.join(assets_of(category))}")
    return name
