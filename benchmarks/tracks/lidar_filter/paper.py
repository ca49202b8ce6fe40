"""The published figures of the lidar-filter track: Table 5.4 of seeds/003 (KISS-ICP loop errors
per filtering mode, Unitree B1 with a VLP-16 indoors)."""

from __future__ import annotations

from ..spec import Reference

# Table 5.4, KISS-ICP: filtering mode -> (TE m, OE rad, TVE x, y, z m). The thesis ran the naive
# ground-aware filter only ("the alternative solution proved unusable").
TABLE_5_4 = {
    "filter-none": (22.529, 0.270, 18.848, 12.129, 2.298),
    "filter-threshold": (2.585, 0.100, 0.278, 1.152, 2.297),
    "filter-naive-ground": (1.112, 0.075, 0.478, 0.986, 0.187),
}
TABLE_KEYS = ("odom_te_m", "odom_oe_rad", "odom_tve_x_m", "odom_tve_y_m", "odom_tve_z_m")


def published_references() -> list[Reference]:
    refs = []
    src = "Tab. 5.4, KISS-ICP, B1 + VLP-16 indoor"
    for pipe, values in TABLE_5_4.items():
        for key, v in zip(TABLE_KEYS, values, strict=True):
            refs.append(Reference(key, f"{v:g}", src, (), (pipe,), value=v))
    return refs
