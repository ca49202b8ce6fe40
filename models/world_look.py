"""How the worlds look: textures, materials, skybox, lights and render settings.

Only MuJoCo's built-in procedural textures are used (checker, flat with random marks,
gradient), so every scene can be written out with ``MjSpec.to_xml`` and needs no asset files.
The aim is an interior that reads as a building in RGB views: a tiled floor with grout lines,
concrete risers and supports, wooden plank treads, a rubber-coated ramp, plaster walls, a
light sky and three lights that cast shadows.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import mujoco

# material name used by terrain.Box -> MuJoCo material name
MATERIALS = {
    "floor": "world_floor",
    "riser": "world_concrete",
    "tread": "world_wood",
    "ramp": "world_ramp",
    "wall": "world_plaster",
}


def _texture(spec: mujoco.MjSpec, name: str, builtin: str, rgb1: tuple, rgb2: tuple, *, mark: str = "none",
             markrgb: tuple = (0.0, 0.0, 0.0), random: float = 0.0, size: int = 512, kind: str = "2d") -> None:
    import mujoco

    spec.add_texture(
        name=name,
        type={"2d": mujoco.mjtTexture.mjTEXTURE_2D, "skybox": mujoco.mjtTexture.mjTEXTURE_SKYBOX}[kind],
        builtin=getattr(mujoco.mjtBuiltin, f"mjBUILTIN_{builtin.upper()}"),
        mark=getattr(mujoco.mjtMark, f"mjMARK_{mark.upper()}"),
        rgb1=list(rgb1), rgb2=list(rgb2), markrgb=list(markrgb), random=random,
        width=size, height=size * (6 if kind == "skybox" else 1),
    )


def _material(spec: mujoco.MjSpec, name: str, texture: str, texrepeat: tuple[float, float], *,
              specular: float = 0.1, shininess: float = 0.1, reflectance: float = 0.0) -> None:
    import mujoco

    mat = spec.add_material(name=name, texrepeat=list(texrepeat), texuniform=True, specular=specular,
                            shininess=shininess, reflectance=reflectance)
    mat.textures[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = texture


def add_materials(spec: mujoco.MjSpec) -> None:
    """Textures and materials of :data:`MATERIALS`, and the skybox."""
    _texture(spec, "world_sky", "gradient", (0.78, 0.84, 0.92), (0.97, 0.97, 0.98), size=256, kind="skybox")
    # 0.5 m ceramic tiles: one checker period (2 tiles) per metre, grey grout lines
    _texture(spec, "world_tiles", "checker", (0.72, 0.70, 0.66), (0.66, 0.64, 0.60), mark="edge",
             markrgb=(0.55, 0.54, 0.51))
    _material(spec, MATERIALS["floor"], "world_tiles", (1.0, 1.0), specular=0.2, shininess=0.3)
    # board-formed concrete: flat grey with dense random specks
    _texture(spec, "world_concrete", "flat", (0.68, 0.67, 0.64), (0.68, 0.67, 0.64), mark="random",
             markrgb=(0.56, 0.55, 0.52), random=0.25, size=256)
    _material(spec, MATERIALS["riser"], "world_concrete", (3.0, 3.0), specular=0.05)
    # oak planks: a checker stretched into long boards with dark joints
    _texture(spec, "world_oak", "checker", (0.58, 0.40, 0.23), (0.52, 0.35, 0.20), mark="edge",
             markrgb=(0.33, 0.21, 0.11), size=256)
    _material(spec, MATERIALS["tread"], "world_oak", (6.0, 0.6), specular=0.3, shininess=0.5)
    # anti-slip rubber coating with light grit
    _texture(spec, "world_rubber", "flat", (0.30, 0.33, 0.32), (0.30, 0.33, 0.32), mark="random",
             markrgb=(0.45, 0.47, 0.45), random=0.12, size=256)
    _material(spec, MATERIALS["ramp"], "world_rubber", (4.0, 4.0), specular=0.05)
    _texture(spec, "world_plaster", "flat", (0.90, 0.88, 0.84), (0.90, 0.88, 0.84), mark="random",
             markrgb=(0.86, 0.84, 0.80), random=0.08, size=256)
    _material(spec, MATERIALS["wall"], "world_plaster", (2.0, 2.0), specular=0.02)


def add_lights(spec: mujoco.MjSpec, p0_w: np.ndarray, p1_w: np.ndarray, top_z: float) -> None:
    """A sun-like directional light through a window and two ceiling spots over the route p0 -> p1.

    Only the spots cast shadows: MuJoCo's orthographic shadow map of a directional light over
    a floor this large shows acne.
    """
    import mujoco

    wb = spec.worldbody
    wb.add_light(name="world_sun", type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, pos=[0.0, 0.0, top_z + 8.0],
                 dir=list(np.array([0.35, 0.25, -1.0]) / np.linalg.norm([0.35, 0.25, -1.0])), castshadow=False,
                 diffuse=[0.35, 0.34, 0.32], specular=[0.1, 0.1, 0.1], ambient=[0.22, 0.22, 0.23])
    for k, f in enumerate((0.25, 0.75)):
        p = (1 - f) * np.asarray(p0_w, float) + f * np.asarray(p1_w, float)
        wb.add_light(name=f"world_spot{k}", type=mujoco.mjtLightType.mjLIGHT_SPOT, pos=[p[0], p[1], top_z + 3.2],
                     dir=[0.0, 0.0, -1.0], cutoff=70.0, exponent=2.0, castshadow=True,
                     diffuse=[0.30, 0.29, 0.27], specular=[0.1, 0.1, 0.1], attenuation=[1.0, 0.0, 0.0])


def set_visual(spec: mujoco.MjSpec) -> None:
    """Render settings: soft headlight, large shadow maps, off-screen buffer for 848x480 and more."""
    v = spec.visual
    v.headlight.ambient = [0.18, 0.18, 0.18]
    v.headlight.diffuse = [0.22, 0.22, 0.22]
    v.headlight.specular = [0.05, 0.05, 0.05]
    v.quality.shadowsize = 4096
    v.quality.offsamples = 4
    v.global_.offwidth = 1280
    v.global_.offheight = 960
    v.map.znear = 0.002  # times the model extent: about 1-3 cm, so close-up leg cameras see the step
    v.map.zfar = 20.0


__all__ = ["MATERIALS", "add_lights", "add_materials", "set_visual"]
