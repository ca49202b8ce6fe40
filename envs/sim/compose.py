"""A built world with the exoskeleton carrying a rig, compiled.

The device (:func:`exobench.models.exo.add_exo`) has a site per own sensor and a camera per RGB-D
mount. :func:`compose_rig` adds what a rig needs beyond that: a site for each sensor attached to
a camera (its IMU, at the optical frame, or where its ``ImuConfig.extrinsics`` put it) and for each sensor with an explicit mount, the chest camera's two-hinge rig (``chest_rig`` on the
pelvis with ``chest_yaw`` (z) and ``chest_pitch`` (y, + looks down), carrying ``rgbd_chest``,
same pose at zero angles) when asked, and one mocap body ``ped<k>`` per pedestrian (a capsule
torso+legs and a sphere head, group 0, so cameras see them), and a
:class:`~exobench.models.vision_look.WorldLook` (textures, featureless surfaces, light level)
when it is not the default. Without any of these it is exactly :func:`exobench.models.worlds.compose`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from exobench.core.transforms import matrix_to_quat_wxyz
from exobench.models.exo_spec import ExoSpec
from exobench.models.vision_look import WorldLook, apply_look
from exobench.models.worlds import BuiltWorld, CompiledScene, compose

from ..sensors.adapter import Mount

PED_RADIUS_M = 0.2
CHEST_CAMERA = "rgbd_chest"


def attached_sites(rig: Sequence) -> tuple[tuple[str, str | Mount | tuple], ...]:
    """(site, anchor) of every rig sensor that needs a site the device lacks: an IMU attached to a
    camera (anchor: the camera id, or (camera id, T_camera_imu as nested tuples) when its
    extrinsics are not the identity) and every sensor with an explicit mount (anchor: its :class:`Mount`).
    Anchors are hashable: compiled scenes are cached by them."""
    out: list[tuple[str, str | Mount | tuple]] = []
    for s in rig:
        if s.mount is not None:
            out.append((s.sensor_id, s.mount))
        elif s.attached_to is not None and s.kind == "imu":
            ext = getattr(s.config, "extrinsics", "identity")
            if ext == "identity":  # the anchor of before: the same cache keys and scenes
                out.append((s.sensor_id, s.attached_to))
            else:
                T = s.config.T_camera_imu()
                out.append((s.sensor_id, (s.attached_to, tuple(map(tuple, T.tolist())))))
    return tuple(out)


def compose_rig(
    world: BuiltWorld, exo: ExoSpec, sites: Sequence[tuple[str, str]] = (), *, chest_rig: bool = False,
    ped_heights_m: Sequence[float] = (), look: WorldLook | None = None, look_seed: int = 0,
) -> CompiledScene:  # fmt: skip
    """The world with the exoskeleton, ``sites`` (site name, camera id), the chest rig, pedestrians
    and ``look`` (its textures drawn from ``look_seed``, the world's seed)."""
    plain = look is None or look.is_default
    if not sites and not chest_rig and not ped_heights_m and plain:
        return compose(world, exo)
    import mujoco

    from exobench.models.exo import R_OPTICAL_MJCAMERA, add_exo

    spec = world.spec.copy()
    if not plain:
        apply_look(spec, look, look_seed)  # type: ignore[arg-type]
    add_exo(spec, exo)
    start = world.truth.params.get("start_w")
    if start is not None:
        pelvis = spec.body("pelvis")
        R0 = np.asarray(world.T_world_local)[:3, :3]
        pelvis.pos = [start[0], start[1], start[2] + exo.leg_m]
        pelvis.quat = list(matrix_to_quat_wxyz(R0))
    rig_body = None
    if chest_rig:
        parent, T = exo.rgbd_mount(CHEST_CAMERA)
        spec.delete(spec.camera(CHEST_CAMERA))
        rig_body = spec.body(parent).add_body(name="chest_rig", pos=list(T[:3, 3]), explicitinertial=True, mass=0.3,
                                              inertia=[1e-4, 1e-4, 1e-4])  # fmt: skip
        for jname, axis in (("chest_yaw", [0.0, 0.0, 1.0]), ("chest_pitch", [0.0, 1.0, 0.0])):
            rig_body.add_joint(name=jname, type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis)
        rig_body.add_camera(name=CHEST_CAMERA, pos=[0.0, 0.0, 0.0],
                            quat=list(matrix_to_quat_wxyz(T[:3, :3] @ R_OPTICAL_MJCAMERA)), fovy=58.0)  # fmt: skip
    for site, anchor in sites:
        if isinstance(anchor, Mount):
            spec.body(anchor.parent).add_site(name=site, pos=list(anchor.xyz_m), quat=list(anchor.quat_wxyz),
                                              size=[0.005, 0, 0], group=3)  # fmt: skip
            continue
        camera, T_ci = (anchor, None) if isinstance(anchor, str) else (anchor[0], np.array(anchor[1], dtype=float))
        parent, T = exo.rgbd_mount(camera)
        if camera == CHEST_CAMERA and rig_body is not None:
            T = T.copy()
            T[:3, 3] = 0.0  # the rig body sits at the camera's position, axes parallel to the pelvis
            body = rig_body
        else:
            body = spec.body(parent)
        if T_ci is not None:
            T = T @ T_ci
        body.add_site(name=site, pos=list(T[:3, 3]), quat=list(matrix_to_quat_wxyz(T[:3, :3])), size=[0.005, 0, 0], group=3)
    for k, h in enumerate(ped_heights_m):
        pb = spec.worldbody.add_body(name=f"ped{k}", mocap=True, pos=[0.0, 0.0, -10.0])
        r = PED_RADIUS_M
        head_r = 0.11
        torso_top = h - 2.0 * head_r
        pb.add_geom(name=f"ped{k}_body", type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[r, 0, 0],
                    fromto=[0.0, 0.0, r, 0.0, 0.0, torso_top - r], rgba=[0.25, 0.3, 0.55, 1.0], group=0,
                    contype=0, conaffinity=0)  # fmt: skip
        pb.add_geom(name=f"ped{k}_head", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[head_r, 0, 0],
                    pos=[0.0, 0.0, h - head_r], rgba=[0.85, 0.7, 0.6, 1.0], group=0, contype=0, conaffinity=0)  # fmt: skip
    model = spec.compile()
    return CompiledScene(model=model, truth=world.truth, exo=exo, spec=spec)
