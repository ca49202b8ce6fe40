"""Procedural images for surfaces a visual tracker can hold: posters and notice boards on plaster,
wood grain, patterned carpet; and flat colours for surfaces it cannot.

Every image is drawn from a numpy generator the caller seeds (:mod:`.vision_look` seeds it from
the world's seed), so the same seed gives the same pixels and none is shipped as a file. Images
are ``uint8`` (H, W, 3). Floor and wood images span ``metres`` (MuJoCo maps them with
``texuniform``: texels per metre = size / metres): planks 0.12-0.2 m wide, carpet motifs of
0.25 m; a poster or notice board image covers its own panel.
"""

from __future__ import annotations

import numpy as np


def _u8(img: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)


def smooth_noise(rng: np.random.Generator, shape: tuple[int, int], cells: tuple[int, int]) -> np.ndarray:
    """Value noise in [0, 1]: a random grid of ``cells`` interpolated bilinearly to ``shape``, periodic."""
    h, w = shape
    ch, cw = cells
    grid = rng.random((ch + 1, cw + 1))
    grid[-1, :], grid[:, -1] = grid[0, :], grid[:, 0]  # periodic, so the texture tiles without a seam
    y = np.linspace(0.0, ch, h, endpoint=False)
    x = np.linspace(0.0, cw, w, endpoint=False)
    y0, x0 = y.astype(int), x.astype(int)
    fy, fx = (y - y0)[:, None], (x - x0)[None, :]
    g = grid
    return (g[y0][:, x0] * (1 - fy) * (1 - fx) + g[y0 + 1][:, x0] * fy * (1 - fx)
            + g[y0][:, x0 + 1] * (1 - fy) * fx + g[y0 + 1][:, x0 + 1] * fy * fx)  # fmt: skip


def flat(rgb: tuple[float, float, float], size: int = 16) -> np.ndarray:
    """One colour, nothing to track."""
    return _u8(np.broadcast_to(np.asarray(rgb, dtype=float), (size, size, 3)).copy())


def _poster(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A poster: a coloured ground, two to five bold shapes, a headline and lines of 'text'."""
    img = np.empty((h, w, 3))
    img[:] = rng.uniform(0.15, 0.95, 3)
    yy, xx = np.mgrid[0:h, 0:w]
    for _ in range(int(rng.integers(2, 6))):
        c = rng.uniform(0.0, 1.0, 3)
        cy, cx = rng.uniform(0.1, 0.7) * h, rng.uniform(0.1, 0.9) * w
        r = rng.uniform(0.08, 0.3) * w
        if rng.random() < 0.5:
            img[(yy - cy) ** 2 + (xx - cx) ** 2 < r * r] = c
        else:
            img[(np.abs(yy - cy) < r) & (np.abs(xx - cx) < 0.7 * r)] = c
    ink = np.array([0.05, 0.05, 0.08]) if img[0, 0].mean() > 0.5 else np.array([0.97, 0.97, 0.95])
    line_h = max(2, h // 40)
    y = int(0.72 * h)
    img[int(0.06 * h):int(0.06 * h) + 3 * line_h, int(0.1 * w):int(rng.uniform(0.5, 0.9) * w)] = ink  # headline
    while y + line_h < int(0.95 * h):
        x = int(0.1 * w)
        end = int(rng.uniform(0.5, 0.9) * w)
        while x < end:  # words: bars with gaps
            word = int(rng.integers(line_h, 5 * line_h))
            img[y:y + line_h, x:min(x + word, end)] = ink
            x += word + line_h
        y += 2 * line_h
    return img


def poster(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A poster of ``h`` x ``w`` pixels (uint8)."""
    return _u8(_poster(rng, h, w))


def notice_board(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A cork board in a grey frame with 10-25 pinned notes, cards and small posters (uint8)."""
    img = np.array([0.62, 0.45, 0.28]) * (0.85 + 0.3 * smooth_noise(rng, (h, w), (40, 50)))[..., None]
    f = max(2, w // 60)
    img[:f], img[-f:], img[:, :f], img[:, -f:] = 0.35, 0.35, 0.35, 0.35
    for _ in range(int(rng.integers(10, 26))):
        nh, nw = int(rng.uniform(0.1, 0.33) * h), int(rng.uniform(0.07, 0.18) * w)
        ny, nx = int(rng.integers(f + 2, max(f + 3, h - nh - f - 2))), int(rng.integers(f + 2, max(f + 3, w - nw - f - 2)))
        img[ny:ny + nh, nx:nx + nw] = _poster(rng, nh, nw) if rng.random() < 0.3 else rng.uniform(0.75, 1.0, 3)
        img[ny + 2:ny + 6, nx + nw // 2 - 2:nx + nw // 2 + 2] = rng.uniform(0.0, 1.0, 3)  # the pin
    return _u8(img)


def wood_grain(rng: np.random.Generator, size: int = 512, metres: float = 2.0) -> np.ndarray:
    """Planks along the texture's x: growth rings bent by noise, each plank its own shade."""
    px = size / metres
    yy, xx = np.mgrid[0:size, 0:size] / px
    warp = 0.08 * smooth_noise(rng, (size, size), (4, 16)) + 0.01 * smooth_noise(rng, (size, size), (16, 64))
    ring = 0.5 + 0.5 * np.sin(2.0 * np.pi * (yy + warp) * rng.uniform(60.0, 110.0))
    base = np.array([0.60, 0.43, 0.26])
    img = base * (0.72 + 0.2 * ring ** 3)[..., None]
    edges = [0.0]
    while edges[-1] < metres:
        edges.append(edges[-1] + rng.uniform(0.12, 0.2))
    for a, b in zip(edges[:-1], edges[1:]):
        rows = slice(int(a * px), min(size, int(b * px)))
        img[rows] *= rng.uniform(0.85, 1.15)
        img[max(0, int(b * px) - 1):min(size, int(b * px) + 1)] = base * 0.45  # the joint
    return _u8(img)


def patterned_carpet(rng: np.random.Generator, size: int = 512, metres: float = 2.0) -> np.ndarray:
    """Carpet tiles of 0.25 m with a motif (diamond or cross) in one of a small palette, and pile noise."""
    px = size / metres
    cell = max(4, int(0.25 * px))
    palette = np.clip(np.array([0.30, 0.33, 0.40]) + rng.uniform(-0.15, 0.15, (4, 3)), 0.0, 1.0)
    yy, xx = np.mgrid[0:size, 0:size]
    cy, cx = yy // cell, xx // cell
    u, v = (yy % cell) / cell - 0.5, (xx % cell) / cell - 0.5
    choice = rng.integers(0, len(palette), (size // cell + 1, size // cell + 1))
    img = palette[choice[cy, cx]]
    motif = np.where(rng.random((size // cell + 1, size // cell + 1))[cy, cx] < 0.5,
                     np.abs(u) + np.abs(v) < 0.3, (np.abs(u) < 0.08) | (np.abs(v) < 0.08))  # fmt: skip
    img = np.where(motif[..., None], 0.35 + 0.6 * img[..., ::-1], img)
    img *= (0.8 + 0.4 * rng.random((size, size)))[..., None]  # pile
    return _u8(img)
