"""How a world looks to a visual tracker: surfaces it can hold or lose, and the light level.

:class:`WorldLook` is applied to a built world's spec before it is compiled
(:func:`apply_look`; :func:`exobench.envs.sim.compose.compose_rig` does it); its default changes
nothing, so the worlds, their frames and every figure of before stay the same.

- ``surfaces="textured"``: plaster walls carry posters (A2-A0) and notice boards (1.2 x 0.9 m)
  every 0.5-2.5 m along both faces, wooden surfaces (desk tops, stair treads) wood grain, carpets
  a tile pattern (:mod:`.textures`), all drawn at build time from ``seed`` (the world's seed: a
  different office, different posters). MuJoCo maps a 2D texture on a box by its x and y only,
  so a vertical wall face cannot carry one: each poster is a 1 mm panel of its own on the wall,
  facing out, in geom group 1 (cameras render groups 0-2, the LiDAR casts 0 and 2) and without
  collisions. MuJoCo's rangefinders (the ToF sensors) see every group: on a poster they read 1.1
  mm short. The panels have no surface in the scene truth (segmentation truth: none);
- ``surfaces="textured_floors"``: ``textured`` and the floors that stay plain under it (the
  office's corridor tiles and polished stone, a course's ground) carpet-tiled too, with a motif
  repeating every 8 m: what a real office's corridor floor gives a thigh camera, which sees the
  floor and the lower walls rather than posters at eye height (seeds/000: the Exosense unit on
  the thigh);
- ``surfaces="featureless"``: walls and ceilings flat white and floors flat light grey with no
  marks at all (a white corridor: a tracker finds nothing on them but the edges between them);
- ``light_level``: every light (sun, ceiling spots, the camera's headlight) scaled by it, e.g. 0.3
  for a dim room; 1 is the world's own lighting. MuJoCo's renderer has no exposure control, so a
  dim room renders darker, as an auto-exposure camera at its longest exposure would show it.

Only looks change (MuJoCo textures, materials and lights): geometry, LiDAR materials and the
scene truth are the same.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from exobench.core.errors import ConfigError, check_range

from . import textures

if TYPE_CHECKING:
    import mujoco

SURFACES = ("default", "textured", "textured_floors", "featureless")
WHITE_RGB = (0.93, 0.93, 0.92)
FLOOR_GREY_RGB = (0.78, 0.78, 0.77)
# material -> (image maker, metres the image spans)
_TEXTURED: dict[str, tuple[Any, float]] = {
    "world_wood": (textures.wood_grain, 2.0),
    "office_wood": (textures.wood_grain, 2.0),
    "office_carpet": (textures.patterned_carpet, 2.0),
}
# textured_floors: every plain floor carpet-tiled, over 8 m before the motif repeats (a 2 m repeat
# in a corridor would give place recognition the same view every 2 m)
_FLOORS: dict[str, tuple[Any, float]] = {
    "world_floor": (lambda rng, metres: textures.patterned_carpet(rng, size=2048, metres=metres), 8.0),
    "office_polished": (lambda rng, metres: textures.patterned_carpet(rng, size=2048, metres=metres), 8.0),
}
_FEATURELESS: dict[str, tuple[float, float, float]] = {
    "world_plaster": WHITE_RGB,
    "office_ceiling": WHITE_RGB,
    "world_floor": FLOOR_GREY_RGB,
    "office_carpet": FLOOR_GREY_RGB,
    "office_polished": FLOOR_GREY_RGB,
}


@dataclass(frozen=True)
class WorldLook:
    """Surfaces (``default``, ``textured``, ``featureless``) and light level (0.02-2, 1 = as built)."""

    surfaces: str = "default"
    light_level: float = 1.0

    def __post_init__(self) -> None:
        if self.surfaces not in SURFACES:
            raise ConfigError("surfaces", self.surfaces, "one of " + ", ".join(SURFACES))
        object.__setattr__(self, "light_level", check_range("light_level", self.light_level, 0.02, 2.0))

    @property
    def is_default(self) -> bool:
        return self.surfaces == "default" and self.light_level == 1.0


def _image_texture(spec: mujoco.MjSpec, name: str, img: np.ndarray) -> None:
    import mujoco

    h, w, _ = img.shape
    tex = spec.add_texture(name=name, type=mujoco.mjtTexture.mjTEXTURE_2D, width=w, height=h, nchannel=3)
    tex.data = np.ascontiguousarray(img).tobytes()


def _retexture(spec: mujoco.MjSpec, material: str, texture: str, img: np.ndarray, metres: float) -> None:
    import mujoco

    mat = spec.material(material)
    if mat is None:  # this world has no such surface
        return
    _image_texture(spec, texture, img)
    mat.textures[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = texture
    mat.texuniform = True
    mat.texrepeat = [1.0 / metres, 1.0 / metres]


def texture_images(seed: int, surfaces: str) -> dict[str, tuple[np.ndarray, float]]:
    """material -> (image, metres it spans) that ``surfaces`` gives a world of ``seed``. One
    generator per material, keyed by its name, so adding a material does not reshuffle the others."""
    if surfaces in ("textured", "textured_floors"):
        out = {}
        made = {**_TEXTURED, **_FLOORS} if surfaces == "textured_floors" else _TEXTURED
        for mat, (make, metres) in made.items():
            rng = np.random.default_rng([int(seed), zlib.crc32(f"texture:{mat}".encode())])
            out[mat] = (make(rng, metres=metres), metres)
        return out
    if surfaces == "featureless":
        return {mat: (textures.flat(rgb), 1.0) for mat, rgb in _FEATURELESS.items()}
    return {}


POSTER_GROUP = 1
PANEL_HALF_M = 0.0005  # 1 mm panels
PANEL_GAP_M = 0.0001  # off the wall, so the depth test never mixes the two
PX_PER_M = 300  # poster texels per metre: finer than a 640 px camera sees at 0.5 m


def _walls(spec: mujoco.MjSpec) -> list[Any]:
    """The world's plaster boxes that are walls: at least 1.8 m tall, at most 0.3 m thick."""
    import mujoco

    out = []
    for g in spec.worldbody.geoms:
        if g.type == mujoco.mjtGeom.mjGEOM_BOX and g.material == "world_plaster":
            hx, hy, hz = g.size
            if hz >= 0.9 and min(hx, hy) <= 0.15:
                out.append(g)
    return out


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])  # fmt: skip


def _matrix_quat(R: np.ndarray) -> list[float]:
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R).ravel())
    return list(q)


def hang_posters(spec: mujoco.MjSpec, rng: np.random.Generator) -> int:
    """Posters and notice boards on both faces of every wall (see the module docstring); returns
    how many were hung. Each has its own texture (``look_poster<k>``), so no two are alike."""
    import mujoco

    k = 0
    for wall in _walls(spec):
        R = _quat_matrix(np.asarray(wall.quat))
        half = np.asarray(wall.size, dtype=float)
        thin = 0 if half[0] < half[1] else 1
        along = 1 - thin
        for side in (1.0, -1.0):
            s = -half[along] + rng.uniform(0.3, 2.0)
            while True:
                board = rng.random() < 0.2
                wm = 1.2 if board else rng.uniform(0.42, 0.84)  # A2 to A0
                hm = 0.9 if board else wm * 1.414
                if s + wm > half[along] - 0.1 or hm > 2 * half[2] - 0.4:
                    break
                bottom = rng.uniform(0.9, 1.1) if board else 1.5 - 0.5 * hm + rng.uniform(-0.1, 0.1)
                local = np.zeros(3)
                local[thin] = side * (half[thin] + PANEL_GAP_M + PANEL_HALF_M)
                local[along] = s + 0.5 * wm
                local[2] = -half[2] + max(0.2, bottom) + 0.5 * hm
                # panel axes: x along the wall, y up, z out of the wall (right-handed)
                z_ax = side * R[:, thin]
                y_ax = R[:, 2]
                x_ax = np.cross(y_ax, z_ax)
                h_px, w_px = max(8, int(hm * PX_PER_M)), max(8, int(wm * PX_PER_M))
                img = textures.notice_board(rng, h_px, w_px) if board else textures.poster(rng, h_px, w_px)
                name = f"look_poster{k}"
                _image_texture(spec, name, img)
                mat = spec.add_material(name=name, texrepeat=[0.5, 0.5], texuniform=False, specular=0.1)
                mat.textures[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = name
                spec.worldbody.add_geom(
                    name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.5 * wm, 0.5 * hm, PANEL_HALF_M],
                    pos=list(np.asarray(wall.pos, dtype=float) + R @ local),
                    quat=_matrix_quat(np.column_stack([x_ax, y_ax, z_ax])), material=name, group=POSTER_GROUP,
                    contype=0, conaffinity=0,
                )  # fmt: skip
                k += 1
                s += wm + rng.uniform(0.5, 2.5)
    return k


def apply_look(spec: mujoco.MjSpec, look: WorldLook, seed: int) -> None:
    """Give the world in ``spec`` the surfaces and light level of ``look`` (in place)."""
    import mujoco

    for mat, (img, metres) in texture_images(seed, look.surfaces).items():
        _retexture(spec, mat, f"look_{mat}", img, metres)
    if look.surfaces in ("textured", "textured_floors"):
        hang_posters(spec, np.random.default_rng([int(seed), zlib.crc32(b"posters")]))
    if look.surfaces == "textured_floors":
        for mat in _FLOORS:  # a carpet has no gloss
            m = spec.material(mat)
            if m is not None:
                m.specular, m.reflectance = 0.0, 0.0
    if look.surfaces == "featureless":
        for mat in _FEATURELESS:  # no gloss either: a specular highlight is a feature too
            m = spec.material(mat)
            if m is not None:
                m.specular, m.reflectance = 0.0, 0.0
    k = look.light_level
    if k != 1.0:
        for light in spec.worldbody.find_all(mujoco.mjtObj.mjOBJ_LIGHT):
            for attr in ("diffuse", "specular", "ambient"):
                setattr(light, attr, list(np.clip(np.asarray(getattr(light, attr)) * k, 0.0, 1.0)))
        h = spec.visual.headlight
        for attr in ("diffuse", "specular", "ambient"):
            setattr(h, attr, list(np.clip(np.asarray(getattr(h, attr)) * k, 0.0, 1.0)))
