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
    refractive_index: 0 (default): ``specular`` and ``transmission`` hold at every incidence.
        Above 0 (glazing): they are the values at normal incidence, and the reflected share rises
        towards grazing incidence as Fresnel's equations give for a pane of that index
        (:func:`exobench.envs.sensors.lidar.optics.pane_split`).

Glazing against a dark outside (the façade windows of :class:`~exobench.models.office.OfficeParams`
``facade="windows"``), at the VLP-16's 905 nm:

- ``float_glass``: clear soda-lime float glass, refractive index 1.51 near 900 nm (Rubin, "Optical
  properties of soda lime silica glasses", Solar Energy Materials 12, 1985: n = 1.51-1.52 from 0.6
  to 1 um). Fresnel: 4.1 % per surface at normal incidence, 7.9 % for the pane (two surfaces,
  incoherent: ``2R / (1 + R)``), 17 % at 60 deg, 56 % at 80 deg. Transmission 0.84 at normal
  incidence [A: the rest absorbed by the iron of clear float, whose Fe2+ band is centred near
  1 um]. Its own diffuse backscatter 0.001 [A: a clean polished glass surface scatters of the order
  of 1e-3 of the light outside the specular direction (total integrated scatter; haze on glass data
  sheets, ASTM D1003, is 0.1-0.5 % but counts forward scatter through the pane); with it a pane is
  detected frontally only within about 3.5 m, as lidar sees clean glass mostly near normal
  incidence or close: Zhao, Yang and Schwertfeger, "Mapping with reflection", SSRR 2020].
- ``lowe_glass``: soft-coat (sputtered silver) low-emissivity glazing, reflecting 30 % at normal
  incidence at 905 nm [A: silver low-e coatings are made to reflect the near infrared, their
  reflectance rising from ~5 % in the visible to 30-50 % at 0.9-1 um (glazing manufacturers'
  spectra); we take the low end], transmission 0.60.
- ``igu_float``, ``igu_lowe``: double-glazed (insulating glass) units, EN 1279, of two float panes
  or a low-e and a float pane, their panes' reflections and transmissions combined incoherently
  (:func:`insulating_unit`): 13.5 % at normal incidence for two float panes at 905 nm (about
  14-15 % in the visible, where float absorbs less), transmission 0.71; low-e: 32.9 %, 0.52. A
  unit's ghost comes from its front or back pane in proportion to their shares (0.58 / 0.42 for
  two float panes); with bowed panes the two bow in opposite directions [A: under a climatic load
  the cavity's gas pushes both panes out, or pulls both in (Respondek, Materials 13 (2020) 286;
  Respondek, Kozlowski and Wisniowski, Materials 15 (2022) 2427, compute these deflections); that
  they reach millimetres on ordinary units, as toughening bow does, is our reading].

Panes that are not flat (the ``glass_bow_mm_per_m`` and ``glass_roller_wave_mm`` of the office
scenario and :class:`~exobench.envs.sensors.lidar.LidarConfig`, modelled in
:mod:`exobench.envs.sensors.lidar.pane_shape`; 0 = flat, the default). Glass partitions and doors
are safety glazing, usually thermally toughened, and toughened glass leaves a horizontal furnace
bowed and with a roller wave (Pilkington, "How is distortion in toughened glass defined?";
ASTM C1651 measures the roll wave as peak-to-valley depth and wavelength):

- overall bow: EN 12150-1 allows 0.003 mm/mm (3 mm per metre) for horizontally toughened float
  glass, and 0.5 mm over 300 mm of local distortion (the EN 12150-1 table as a processor quotes it,
  uniglasspolska.pl, "Ocena jakosci szkla hartowanego"). We set the centre deflection of a pane
  held flat at its edges to ``bow * diagonal`` [A: the standard measures the bow along edges and
  diagonals; a framed pane's edges are held];
- roller wave: EN 12150-1:2015 added a roller-wave limit; 0.3 mm peak-to-valley for float glass
  [A: as commonly quoted, not checked against the standard's text here; ASTM C1048 has a
  comparable limit], wavelength 0.35 m [A: the pitch of a furnace's rollers, some 0.3-0.4 m].

These are tolerance limits, the least flat a conforming pane may be: typical panes are flatter
[A]. A single value applies to every glass pane of the building (partitions, doors, windows).
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
    refractive_index: float = 0.0
    front_share: float = 1.0  # insulating glass: share of ``specular`` the front pane reflects (the rest the back pane)


def insulating_unit(name: str, front: LidarMaterial, back: LidarMaterial) -> LidarMaterial:
    """A double-glazed unit of two panes at normal incidence, their reflections and transmissions
    combined incoherently (the multiple reflections between the panes summed, as for the two faces
    of one pane): ``R = R1 + T1^2 R2 / (1 - R1 R2)``, ``T = T1 T2 / (1 - R1 R2)``; the front pane's
    share of ``R`` is ``R1 / R``. Its own echo and index are the front pane's."""
    r1, t1, r2, t2 = front.specular, front.transmission, back.specular, back.transmission
    k = 1.0 - r1 * r2
    r = r1 + t1 * t1 * r2 / k
    return LidarMaterial(name, front.reflectivity, "glass", transmission=t1 * t2 / k, specular=r,
                         refractive_index=front.refractive_index, front_share=r1 / r)  # fmt: skip


_FLOAT = LidarMaterial("float_glass", 0.001, "glass", transmission=0.84, specular=0.079, refractive_index=1.51)
_LOWE = LidarMaterial("lowe_glass", 0.001, "glass", transmission=0.60, specular=0.30, refractive_index=1.51)

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
        _FLOAT,
        _LOWE,
        insulating_unit("igu_float", _FLOAT, _FLOAT),
        insulating_unit("igu_lowe", _LOWE, _FLOAT),
    )
}

DEFAULT_MATERIAL = "concrete"


def material(name: str) -> LidarMaterial:
    """The material called ``name``; unknown names raise with the valid list."""
    try:
        return MATERIALS[name]
    except KeyError:
        raise UnknownNameError("material", name, MATERIALS) from None
