"""Vectorised plane statistics of AHC plane extraction: PCA from point moments, closed-form 3x3
eigen-problems, forest labelling and grouped sums.

Point moments are rows ``(n, sx, sy, sz, sxx, sxy, sxz, syy, syz, szz)``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["eig3", "forest_labels", "group_sum", "moment_cov", "moment_mse", "moment_pca"]


# moments columns: n, sx, sy, sz, sxx, sxy, sxz, syy, syz, szz
def moment_cov(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = m[:, 0:1]
    mean = m[:, 1:4] / n
    e = m[:, 4:10] / n
    cov = np.empty((len(m), 3, 3))
    cov[:, 0, 0] = e[:, 0] - mean[:, 0] ** 2
    cov[:, 0, 1] = cov[:, 1, 0] = e[:, 1] - mean[:, 0] * mean[:, 1]
    cov[:, 0, 2] = cov[:, 2, 0] = e[:, 2] - mean[:, 0] * mean[:, 2]
    cov[:, 1, 1] = e[:, 3] - mean[:, 1] ** 2
    cov[:, 1, 2] = cov[:, 2, 1] = e[:, 4] - mean[:, 1] * mean[:, 2]
    cov[:, 2, 2] = e[:, 5] - mean[:, 2] ** 2
    return mean, cov


def eig3(cov: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(least, middle eigenvalue, unit eigenvector of the least) of symmetric 3x3 matrices, in
    closed form: the trigonometric solution of the characteristic cubic, the eigenvector as the
    longest cross product of two rows of (A - l I). Rows whose two least eigenvalues are too
    close for that (relative gap < 1e-6) fall back to ``numpy.linalg.eigh``."""
    a00, a11, a22 = cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2]
    a01, a02, a12 = cov[:, 0, 1], cov[:, 0, 2], cov[:, 1, 2]
    q = (a00 + a11 + a22) / 3.0
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p = np.sqrt(np.maximum((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)) / 6.0,
                           1e-300))
    det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02)
    phi = np.arccos(np.clip(det / (2.0 * p ** 3), -1.0, 1.0)) / 3.0
    lam_max = q + 2.0 * p * np.cos(phi)
    lam_min = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    lam_mid = 3.0 * q - lam_max - lam_min
    r0 = np.stack([a00 - lam_min, a01, a02], axis=1)
    r1 = np.stack([a01, a11 - lam_min, a12], axis=1)
    r2 = np.stack([a02, a12, a22 - lam_min], axis=1)

    def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                         a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)

    cands = np.stack([cross(r0, r1), cross(r0, r2), cross(r1, r2)], axis=1)  # (n, 3, 3)
    norms = np.einsum("nij,nij->ni", cands, cands)
    best = np.argmax(norms, axis=1)
    idx = np.arange(len(cov))
    vec = cands[idx, best] / np.sqrt(np.maximum(norms[idx, best], 1e-300))[:, None]
    bad = (lam_mid - lam_min) <= 1e-6 * np.maximum(lam_max, 1e-300)
    if bad.any():
        w, v = np.linalg.eigh(cov[bad])
        lam_min[bad], lam_mid[bad], vec[bad] = w[:, 0], w[:, 1], v[:, :, 0]
    return np.maximum(lam_min, 0.0), np.maximum(lam_mid, 0.0), vec


def moment_pca(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(mean, normal, mse, middle eigenvalue) of moment rows: normal = eigenvector of the least
    eigenvalue of the covariance, mse = that eigenvalue."""
    mean, cov = moment_cov(m)
    lam_min, lam_mid, normal = eig3(cov)
    return mean, normal, lam_min, lam_mid


def forest_labels(n: int, child: np.ndarray, parent: np.ndarray) -> tuple[int, np.ndarray]:
    """Components of the graph on n nodes whose edges child -> parent form a forest in which
    each node has at most one parent and the only cycles are mutual pairs (the proposals of a
    merge round). Returns (number of components, compact label per node)."""
    root = np.arange(n)
    root[child] = parent
    ar = np.arange(n)
    smaller_of_pair = (root != ar) & (root[root] == ar) & (ar < root)
    root[smaller_of_pair] = ar[smaller_of_pair]  # a mutual pair is rooted at its smaller id
    while True:
        nxt = root[root]
        if np.array_equal(nxt, root):
            break
        root = nxt
    uniq, lab = np.unique(root, return_inverse=True)
    return len(uniq), lab

def group_sum(groups: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    """Sum of ``rows`` (M, C) per group id (M,) in [0, n)."""
    m, ncol = rows.shape
    flat = (groups[:, None] * ncol + np.arange(ncol)).ravel()
    return np.bincount(flat, weights=rows.ravel(), minlength=n * ncol).reshape(n, ncol)


def moment_mse(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mean, least eigenvalue of the covariance) of moment rows, closed form (trigonometric
    solution of the characteristic cubic; the least eigenvalue is well conditioned when it is
    separated from the others, which is the case that matters for a plane test)."""
    mean, cov = moment_cov(m)
    a00, a11, a22 = cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2]
    a01, a02, a12 = cov[:, 0, 1], cov[:, 0, 2], cov[:, 1, 2]
    q = (a00 + a11 + a22) / 3.0
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p = np.sqrt(np.maximum((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)) / 6.0,
                           1e-300))
    det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02)
    r = np.clip(det / (2.0 * p ** 3), -1.0, 1.0)
    lam_min = q + 2.0 * p * np.cos(np.arccos(r) / 3.0 + 2.0 * np.pi / 3.0)
    return mean, np.maximum(lam_min, 0.0)
