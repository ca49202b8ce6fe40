"""RTLS planes (eq. 11-18) against batch total least squares fits of the same points."""

import numpy as np
import pytest

from exobench.perception.stairs.rtls import HorizontalPlane, RtlsPlane, VerticalPlane, make_plane

OFFSET = np.array([3.2, -2.7, 4.1])  # metres away from the origin, where V - n e e^T cancels


def _cloud(rng, n, normal, noise=1.5e-3, spread=0.4):
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    uv = rng.uniform(-spread, spread, (n, 2))
    return OFFSET + uv[:, :1] * a + uv[:, 1:] * b + rng.normal(0.0, noise, (n, 1)) * normal


def _batch_general(P):
    e = P.mean(axis=0)
    _, s, Vt = np.linalg.svd(P - e)
    n = Vt[-1]
    return n, e, float(np.sqrt(np.mean(((P - e) @ n) ** 2)))


def _batch_horizontal(P):
    e = P.mean(axis=0)
    return np.array([0.0, 0.0, 1.0]), e, float(np.std(P[:, 2]))


def _batch_vertical(P):
    e = P.mean(axis=0)
    _, _, Vt = np.linalg.svd(P[:, :2] - e[:2])
    n = np.array([Vt[-1, 0], Vt[-1, 1], 0.0])
    return n, e, float(np.sqrt(np.mean(((P - e) @ n) ** 2)))


CASES = [
    (RtlsPlane, _batch_general, [0.2, -0.3, 1.0]),
    (HorizontalPlane, _batch_horizontal, [0.0, 0.0, 1.0]),
    (VerticalPlane, _batch_vertical, [0.8, 0.6, 0.0]),
]


def _assert_same(plane, P, batch):
    n_b, e_b, s_b = batch(P)
    n = plane.normal
    assert abs(np.linalg.norm(n) - 1.0) < 1e-12
    sign = 1.0 if np.dot(n, n_b) >= 0 else -1.0
    np.testing.assert_allclose(n, sign * n_b, atol=1e-9, rtol=0)
    np.testing.assert_allclose(plane.centroid, e_b, atol=1e-9, rtol=0)
    assert abs(plane.sigma_m - s_b) < 1e-9
    q = P[0] + 0.01
    assert abs(plane.distance(q) - float(np.dot(q - e_b, sign * n_b))) < 1e-9


@pytest.mark.parametrize("cls,batch,normal", CASES, ids=["general", "horizontal", "vertical"])
def test_recursion_equals_batch_fit_after_adds_and_removes(cls, batch, normal):
    rng = np.random.default_rng(4)
    pool = _cloud(rng, 400, normal)
    plane = cls()
    active: list[int] = []
    free = list(range(len(pool)))
    rng.shuffle(free)
    for step in range(1500):
        if active and (rng.random() < 0.45 or not free):
            i = active.pop(int(rng.integers(len(active))))
            plane.remove(pool[i])
            free.append(i)
        else:
            i = free.pop()
            plane.add(pool[i])
            active.append(i)
        if len(active) >= 4 and step % 50 == 0:
            _assert_same(plane, pool[active], batch)
    while len(active) > 5:
        plane.remove(pool[active.pop(0)])
    _assert_same(plane, pool[active], batch)
    assert plane.n == len(active)


@pytest.mark.parametrize("kind", ["general", "horizontal", "vertical"])
def test_emptying_a_plane_and_refilling_it(kind):
    rng = np.random.default_rng(1)
    plane = make_plane(kind)
    P = _cloud(rng, 30, [0.0, 0.0, 1.0] if kind != "vertical" else [1.0, 0.0, 0.0])
    for p in P:
        plane.add(p)
    for p in P:
        plane.remove(p)
    assert plane.n == 0 and np.all(np.isnan(plane.centroid)) and np.isnan(plane.sigma_m)
    with pytest.raises(ValueError):
        plane.remove(P[0])
    Q = P + np.array([1.0, 2.0, 3.0])  # far from the first reference point
    for p in Q:
        plane.add(p)
    batch = {"general": _batch_general, "horizontal": _batch_horizontal, "vertical": _batch_vertical}[kind]
    _assert_same(plane, Q, batch)


def test_htvr_normals_are_constrained():
    rng = np.random.default_rng(2)
    P = _cloud(rng, 50, [0.3, 0.1, 1.0])  # a tilted cloud: the constrained fits ignore the tilt
    h, v = HorizontalPlane(), VerticalPlane()
    for p in P:
        h.add(p)
        v.add(p)
    np.testing.assert_array_equal(h.normal, [0.0, 0.0, 1.0])
    assert v.normal[2] == 0.0 and abs(np.linalg.norm(v.normal) - 1.0) < 1e-12
