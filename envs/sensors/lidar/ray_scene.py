"""A private copy of a scene's ray-visible geoms, grouped into spatial zones, for fast ``mj_multiRay``.

``mj_multiRay`` tests every ray against every geom of every body whose bounding sphere the ray
passes (a quick spherical-angle test first, then the exact intersection). A procedural world
puts all its geoms in the world body, so a VLP-16 sweep of the office (28,800 rays, ~280
static geoms) spends most of its time stepping through geoms that lie nowhere near the ray:
even with every geom culled by the cut-off, a sweep costs ~18 ms on this machine.
:class:`RayScene` compiles, once per model and sensor, a model holding only the geoms the
sensor's ray casts can hit (its geom groups, visible, not on the excluded body):

- static geoms (welded to the world) in *zone* bodies: a k-d split of their centres into
  groups of at most ``leaf_size`` geoms, each zone a body at the world origin (so every geom
  keeps its world pose bit for bit), whose bounding sphere lets ``mj_multiRay`` skip the whole
  zone for rays that miss it; geoms larger than ``large_m`` (floors, ceilings, long walls)
  stay in the world body, tested by every ray as before;
- moving geoms (the exoskeleton) in one mocap body per original body, with their local poses;
  :meth:`RayScene.sync` copies the bodies' poses from the simulation before a sweep.

Hits are the same surfaces at the same distances as casting on the original model: the same
geom types, sizes and world poses, and the same intersection code. The geoms are visited in
another order, so of two geoms hit at exactly the same distance (coplanar faces meeting at a
seam) another one may be reported; moving geoms are posed through their body's position and
quaternion, which can differ from the simulation's own kinematics in the last bits.

A scene with geoms other than primitives (meshes, height fields, SDFs), flexes or skins is not
copied (:func:`build_ray_scene` returns None) and is cast on the original model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PRIMITIVE_TYPES = ("PLANE", "SPHERE", "CAPSULE", "ELLIPSOID", "CYLINDER", "BOX")


@dataclass(eq=False)
class RayScene:
    """The private casting model (see the module docstring).

    Attributes:
        model, data: the private model and its data (zones posed once, mocap bodies by ``sync``).
        geom_of: original geom id of each private geom, (ngeom_private,).
        mocap_source: original body id of each private mocap body, in mocap order.
        group: the geom-group mask to cast with (every private geom is in group 0).
        n_zones: zone bodies made for the static geoms.
    """

    model: object
    data: object
    geom_of: np.ndarray
    mocap_source: np.ndarray
    group: np.ndarray
    n_zones: int

    def sync(self, data: object) -> None:
        """Pose the moving geoms as the original bodies are in ``data`` (current kinematics)."""
        import mujoco

        if len(self.mocap_source) == 0:
            return
        d = self.data
        d.mocap_pos[:] = np.asarray(data.xpos)[self.mocap_source]  # type: ignore[attr-defined]
        d.mocap_quat[:] = np.asarray(data.xquat)[self.mocap_source]  # type: ignore[attr-defined]
        mujoco.mj_kinematics(self.model, d)

    def original_geoms(self, gid: np.ndarray) -> np.ndarray:
        """Private geom ids (-1 = no hit) to the original model's."""
        return np.where(gid >= 0, self.geom_of[np.maximum(gid, 0)], -1).astype(np.int32)


def ray_visible_geoms(model: object, geomgroup: np.ndarray, body_exclude: int) -> np.ndarray:
    """Geoms ``mj_ray`` does not eliminate for this group mask and excluded body (static included)."""
    m = model
    ng = int(m.ngeom)  # type: ignore[attr-defined]
    g = np.arange(ng)
    grp = np.clip(np.asarray(m.geom_group), 0, 5)  # type: ignore[attr-defined]
    mat = np.asarray(m.geom_matid)  # type: ignore[attr-defined]
    alpha = np.asarray(m.geom_rgba)[:, 3]  # type: ignore[attr-defined]
    if int(m.nmat) > 0:  # type: ignore[attr-defined]
        alpha = np.where(mat >= 0, np.asarray(m.mat_rgba)[np.maximum(mat, 0), 3], alpha)  # type: ignore[attr-defined]
    keep = (np.asarray(m.geom_bodyid) != body_exclude) & (alpha != 0) & (np.asarray(geomgroup)[grp] != 0)  # type: ignore[attr-defined]
    return g[keep]


def _zones(centres: np.ndarray, leaf_size: int) -> list[np.ndarray]:
    """k-d split of the points (indices) at the median of the longer horizontal axis."""
    out: list[np.ndarray] = []
    stack = [np.arange(len(centres))]
    while stack:
        idx = stack.pop()
        if len(idx) <= leaf_size:
            out.append(idx)
            continue
        c = centres[idx]
        axis = int(np.argmax(np.ptp(c[:, :2], axis=0)))
        order = idx[np.argsort(c[:, axis], kind="stable")]
        half = len(order) // 2
        stack += [order[half:], order[:half]]
    return out


def build_ray_scene(
    model: object, data: object, geomgroup: np.ndarray, body_exclude: int, *, leaf_size: int = 12, large_m: float = 6.0,
    only: np.ndarray | None = None,
) -> RayScene | None:
    """The private casting model of ``model`` for one sensor; None if the scene cannot be copied.

    ``data`` gives the world poses of the static geoms (its kinematics must be current); ``only``
    (geom ids) keeps those of the ray-visible geoms alone (the BVH caster's moving and curved ones).
    """
    import mujoco

    m = model
    if int(getattr(m, "nflex", 0)) > 0 or int(getattr(m, "nskin", 0)) > 0:
        return None
    geoms = ray_visible_geoms(m, geomgroup, body_exclude)
    if only is not None:
        geoms = geoms[np.isin(geoms, only)]
    types = np.asarray(m.geom_type)[geoms]  # type: ignore[attr-defined]
    allowed = {int(getattr(mujoco.mjtGeom, f"mjGEOM_{t}")) for t in PRIMITIVE_TYPES}
    if not all(int(t) in allowed for t in types):
        return None
    body = np.asarray(m.geom_bodyid)[geoms]  # type: ignore[attr-defined]
    static = (np.asarray(m.body_weldid)[body] == 0) & (np.asarray(m.body_mocapid)[body] < 0)  # type: ignore[attr-defined]
    xpos = np.asarray(data.geom_xpos)  # type: ignore[attr-defined]
    xmat = np.asarray(data.geom_xmat)  # type: ignore[attr-defined]
    rbound = np.asarray(m.geom_rbound)  # type: ignore[attr-defined]

    spec = mujoco.MjSpec()
    spec.modelname = "exobench_ray_scene"
    wb = spec.worldbody
    order: list[int] = []

    def add(parent: object, g: int, pos: np.ndarray, quat: np.ndarray) -> None:
        parent.add_geom(  # type: ignore[attr-defined]
            type=mujoco.mjtGeom(int(m.geom_type[g])), size=[float(v) for v in m.geom_size[g]],  # type: ignore[attr-defined]
            pos=[float(v) for v in pos], quat=[float(v) for v in quat], group=0, rgba=[1.0, 1.0, 1.0, 1.0],
        )  # fmt: skip
        order.append(int(g))

    def world_pose(g: int) -> tuple[np.ndarray, np.ndarray]:
        if int(m.geom_bodyid[g]) == 0:  # type: ignore[attr-defined]
            return np.asarray(m.geom_pos[g]), np.asarray(m.geom_quat[g])  # type: ignore[attr-defined]
        q = np.zeros(4)
        mujoco.mju_mat2Quat(q, xmat[g])
        return xpos[g], q

    st = geoms[static]
    size = np.asarray(m.geom_size)  # type: ignore[attr-defined]
    infinite = np.zeros(len(st), dtype=bool)
    plane = int(mujoco.mjtGeom.mjGEOM_PLANE)
    for i, g in enumerate(st):
        infinite[i] = int(m.geom_type[g]) == plane and (size[g, 0] <= 0 or size[g, 1] <= 0)  # type: ignore[attr-defined]
    large = infinite | (rbound[st] > large_m)
    for g in st[large]:
        add(wb, g, *world_pose(int(g)))
    small = st[~large]
    zones = _zones(xpos[small], leaf_size) if len(small) else []
    for k, z in enumerate(zones):
        zb = wb.add_body(name=f"zone{k}")
        for g in small[z]:
            add(zb, int(g), *world_pose(int(g)))
    mocap_source: list[int] = []
    for b in np.unique(body[~static]):
        mb = wb.add_body(name=f"moving{b}", mocap=True)
        for g in geoms[~static][body[~static] == b]:
            add(mb, int(g), np.asarray(m.geom_pos[g]), np.asarray(m.geom_quat[g]))  # type: ignore[attr-defined]
        mocap_source.append(int(b))
    if not order:
        return None
    pm = spec.compile()
    pd = mujoco.MjData(pm)
    scene = RayScene(
        model=pm, data=pd, geom_of=np.array(order, dtype=np.int64), mocap_source=np.array(mocap_source, dtype=np.int64),
        group=np.array([1, 0, 0, 0, 0, 0], dtype=np.uint8), n_zones=len(zones),
    )  # fmt: skip
    mujoco.mj_kinematics(pm, pd)
    scene.sync(data)
    return scene


__all__ = ["PRIMITIVE_TYPES", "RayScene", "build_ray_scene", "ray_visible_geoms"]
