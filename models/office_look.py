"""How the office looks: the building materials of :mod:`world_look` plus office ones.

Built-in procedural textures only, so the spec writes out with ``to_xml`` and needs no files:
carpet (speckled blue-grey), polished stone floor (large light tiles with grout, reflective),
glass (untextured, transparent), light birch wood for desks, cabinets and doors, dark
blue-grey fabric, green foliage, brushed aluminium, white 0.6 m ceiling tiles. Plaster walls,
corridor tiles and concrete pots reuse ``world_plaster``, ``world_floor`` and ``world_concrete``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .world_look import _material, _texture, add_materials

if TYPE_CHECKING:
    import mujoco

GLASS_RGBA = (0.70, 0.82, 0.86, 0.22)


def add_office_materials(spec: mujoco.MjSpec) -> None:
    """Every material a :class:`~exobench.models.office_furniture.Solid` ``look`` may name, and the skybox."""
    add_materials(spec)
    _texture(spec, "office_carpet", "flat", (0.36, 0.40, 0.46), (0.36, 0.40, 0.46), mark="random",
             markrgb=(0.27, 0.30, 0.35), random=0.35, size=256)
    _material(spec, "office_carpet", "office_carpet", (4.0, 4.0), specular=0.0)
    # 0.6 m polished stone tiles: one checker period (2 tiles) per 1.2 m
    _texture(spec, "office_stone", "checker", (0.84, 0.83, 0.80), (0.79, 0.78, 0.75), mark="edge",
             markrgb=(0.66, 0.65, 0.62))
    _material(spec, "office_polished", "office_stone", (1 / 1.2, 1 / 1.2), specular=0.8, shininess=0.9, reflectance=0.25)
    _texture(spec, "office_birch", "checker", (0.80, 0.66, 0.46), (0.76, 0.62, 0.43), mark="edge",
             markrgb=(0.62, 0.48, 0.32), size=256)
    _material(spec, "office_wood", "office_birch", (1.0, 8.0), specular=0.3, shininess=0.5)
    _texture(spec, "office_fabric", "flat", (0.22, 0.29, 0.37), (0.22, 0.29, 0.37), mark="random",
             markrgb=(0.16, 0.22, 0.29), random=0.3, size=256)
    _material(spec, "office_fabric", "office_fabric", (8.0, 8.0), specular=0.0)
    _texture(spec, "office_leaves", "flat", (0.20, 0.45, 0.17), (0.20, 0.45, 0.17), mark="random",
             markrgb=(0.10, 0.30, 0.08), random=0.5, size=256)
    _material(spec, "office_plant", "office_leaves", (6.0, 6.0), specular=0.1)
    _texture(spec, "office_alu", "flat", (0.62, 0.63, 0.65), (0.62, 0.63, 0.65), mark="random",
             markrgb=(0.56, 0.57, 0.59), random=0.1, size=64)
    _material(spec, "office_metal", "office_alu", (10.0, 10.0), specular=0.7, shininess=0.8)
    # 0.6 m acoustic ceiling tiles
    _texture(spec, "office_ceiling_tiles", "checker", (0.94, 0.94, 0.93), (0.93, 0.93, 0.92), mark="edge",
             markrgb=(0.78, 0.78, 0.77))
    _material(spec, "office_ceiling", "office_ceiling_tiles", (1 / 1.2, 1 / 1.2), specular=0.0)
    spec.add_material(name="office_glass", rgba=list(GLASS_RGBA), specular=0.9, shininess=0.9, reflectance=0.0)
