"""Surface materials as the LiDAR sees them (905 nm) and as the renderer draws them.

One table serves the world builders (which record each geom's material in
``SceneTruth.geom_materials``) and the LiDAR model (which turns a material, an incidence angle
and a range into an intensity, a pass-through or a mirror ghost).

Attributes of a :class:`LidarMaterial`:
    reflectivity: diffuse (Lambertian) albedo at 905 nm, 0-1. Values are typical figures for
        building materials [A: no single source; concrete and plaster 0.3-0.6, dark fabric
        0.05-0.15, white paint 0.8].
    kind: ``"diffuse"``, ``"glass"`` (mostly transmits), ``"mirror"`` (specular reflector) or
        ``"retro"`` (retro-reflector: bright, reported above 100 on the VLP-16 intensity byte).
    transmission: fraction of beams that pass through (glass), 0-1.
    specular: fraction of beams reflected specularly (glass and mirrors): such a beam continues
        along the mirrored direction and, if it hits something, is reported along the original
        ray at the reflected path length (a ghost point). The ghost's light is mirrored out and
        back, so it keeps ``specular ** 2`` of the energy (and a return through glass
        ``transmission ** 2``): see :mod:`exobench.envs.sensors.lidar.optics`.
"""

from __future__ import annotations

from dataclasses import dataclass

from exobench.core.errors import UnknownNameError

KINDS = ("diffuse", "glass", "mirror", "retro")


@dataclass(frozen=True)
class LidarMaterial:
    name: str
    reflectivity: float
    kind: str = "diffuse"
    transmission: float = 0.0
    specular: float = 0.0


MATERIALS: dict[str, LidarMaterial] = {
    m.name: m
    for m in (
        LidarMaterial("concrete", 0.35),
        LidarMaterial("plaster", 0.6),
        LidarMaterial("wood", 0.45),
        LidarMaterial("tiles", 0.5),
        LidarMaterial("polished_floor", 0.3, "mirror", specular=0.3),
        LidarMaterial("carpet", 0.15),
        LidarMaterial("fabric", 0.1),
        LidarMaterial("metal", 0.5, "mirror", specular=0.5),
        LidarMaterial("plant", 0.4),
        LidarMaterial("skin", 0.5),
        LidarMaterial("glass", 0.05, "glass", transmission=0.85, specular=0.1),
        LidarMaterial("mirror", 0.05, "mirror", specular=0.95),
        LidarMaterial("retroreflector", 0.9, "retro"),
    )
}

DEFAULT_MATERIAL = "concrete"


def material(name: str) -> LidarMaterial:
    """The material called ``name``; unknown names raise with the valid list."""
    try:
        return MATERIALS[name]
    except KeyError:
        raise UnknownNameError("material", name, MATERIALS) from None
