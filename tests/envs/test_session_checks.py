"""A session checks itself before it is scored: the track it was recorded for, every file's
hash, frame and truth counts; a missing or malformed file is one line naming it, exit 2."""

from __future__ import annotations

import hashlib
import json
import shutil

import pytest
from click.testing import CliRunner

from exobench.benchmarks.cli import cli
from exobench.envs.session import read_meta, write_session


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "stairs"
    r = CliRunner().invoke(cli, ["record", str(path)])
    assert r.exit_code == 0, r.output
    return path


@pytest.fixture
def session(recorded, tmp_path):
    path = tmp_path / "s"
    shutil.copytree(recorded, path)
    return path


def _replay(path, *args):
    return CliRunner().invoke(cli, ["replay", str(path), "--pipeline", "rtls", "--json", *args])


def _one_error_line(r, *needles):
    assert r.exit_code == 2, (r.exit_code, r.output, r.exception)
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("exobench: error: "), r.stderr
    for needle in needles:
        assert needle in err[0], (needle, err[0])


def _rehash(path):
    """Make meta.json agree with the files as they are now (an edit that also forges the hashes)."""
    meta = json.loads((path / "meta.json").read_text())
    meta["files"] = {
        rel: {"bytes": (path / rel).stat().st_size, "sha256": hashlib.sha256((path / rel).read_bytes()).hexdigest()}
        for rel in meta.get("files", {})
        if (path / rel).exists()
    }
    (path / "meta.json").write_text(json.dumps(meta))


def test_the_session_records_its_track_and_replays_on_it(session):
    assert read_meta(session)["track"] == "stairs"
    r = _replay(session)  # no --track: the recorded one
    assert r.exit_code == 0, r.output
    assert json.loads(r.output.splitlines()[0])["metrics"]["failed"] is False


def test_replay_on_another_track_is_one_line(session):
    _one_error_line(_replay(session, "--track", "odometry"), "recorded for track 'stairs'", "odometry")


@pytest.mark.parametrize("forged", [False, True], ids=["as-cut", "hashes-forged"])
def test_a_session_with_40_percent_of_its_frames_cut_is_refused(session, forged):
    lines = (session / "frames.jsonl").read_text().splitlines(keepends=True)
    (session / "frames.jsonl").write_text("".join(lines[: int(len(lines) * 0.6)]))
    if forged:
        _rehash(session)
    _one_error_line(_replay(session), "frames.jsonl")


def test_a_cut_truth_file_is_refused_even_with_forged_hashes(session):
    lines = (session / "truth" / "tof.jsonl").read_text().splitlines(keepends=True)
    (session / "truth" / "tof.jsonl").write_text("".join(lines[:-5]))
    _rehash(session)
    _one_error_line(_replay(session), "truth")


DAMAGE = {
    "missing": None,
    "empty": b"",
    "list": b"[1, 2, 3]\n",
    "non-utf8": b'{"a": "\xff\xfe\xfa"}\n',
    "truncated": "half",
}
FILES = ["meta.json", "calibration.json", "frames.jsonl", "truth/episode.json", "truth/tof.jsonl"]


# with the hashes forged, the damage must be caught by parsing; meta.json holds the hashes itself
CASES = [(rel, damage, forged) for rel in FILES for damage in DAMAGE for forged in (False, True)
         if not (forged and rel == "meta.json")]  # fmt: skip


@pytest.mark.parametrize("rel,damage,forged", CASES, ids=[f"{r}-{d}-{'parse' if f else 'hash'}" for r, d, f in CASES])
def test_a_missing_or_malformed_file_is_one_line_naming_it(session, rel, damage, forged):
    target = session / rel
    data = target.read_bytes()
    how = DAMAGE[damage]
    if how is None:
        target.unlink()
    elif how == "half":
        target.write_bytes(data[: len(data) // 2 + 7])
    else:
        target.write_bytes(how)
    if forged:
        _rehash(session)
        if how is None:  # a file the forged meta.json no longer lists must still be there
            assert rel not in json.loads((session / "meta.json").read_text())["files"]
    _one_error_line(_replay(session), rel.rsplit("/", 1)[-1])


def test_an_old_session_is_read_without_the_hash_check_and_says_so(session):
    meta = json.loads((session / "meta.json").read_text())
    for key in ("files", "truth_counts", "track"):
        meta.pop(key)
    (session / "meta.json").write_text(json.dumps({**meta, "version": 3}))
    r = _replay(session)
    assert r.exit_code == 0, r.output
    assert "no file hashes" in r.stderr


def test_float_arrays_are_stored_byte_shuffled_and_come_back_bit_exact(tmp_path):
    import numpy as np

    from exobench.envs.session.store import SHUFFLED, load_npz, save_npz

    rng = np.random.default_rng(0)
    a = np.cumsum(rng.normal(size=(5000, 3)), axis=0)
    a[7, 1] = np.nan
    a.view(np.uint64)[9, 2] = 0x7FF8DEADBEEF0001  # a NaN with a payload
    a[11, 0] = -0.0
    arrays = {"a": a, "b": rng.normal(size=4000).astype(np.float32), "c": np.arange(300, dtype=np.int64),
              "small": np.array([1.5, np.nan])}  # fmt: skip
    save_npz(tmp_path / "x.npz", arrays)
    with np.load(tmp_path / "x.npz") as z:
        assert SHUFFLED in z.files and z["a"].dtype == np.uint8 and z["c"].dtype == np.int64
    back = load_npz(tmp_path, "x.npz", tuple(arrays))
    for k, v in arrays.items():
        assert back[k].dtype == v.dtype and back[k].shape == v.shape and back[k].tobytes() == v.tobytes(), k
    save_npz(tmp_path / "shuffled.npz", {"a": a})
    np.savez_compressed(tmp_path / "plain.npz", a=a)
    assert (tmp_path / "shuffled.npz").stat().st_size < 0.9 * (tmp_path / "plain.npz").stat().st_size


def test_lidar_truth_hit_points_are_stored_as_a_residual(tmp_path):
    import numpy as np

    from exobench.envs.session.truth import lidar_truth_arrays

    rng = np.random.default_rng(1)
    n = 400
    origin, d, r = rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.uniform(1, 9, n)
    hit = origin + r[:, None] * d
    hit[5] += 0.25  # a ghost: not on its ray
    from exobench.core import LidarTruth

    lt = LidarTruth(0.1, "l", r, hit, np.zeros(n, int), np.zeros(n, int), np.full(n, "wood"), np.zeros(n, np.int8),
                    np.full(n, -1), rng.uniform(size=n), origin, d)  # fmt: skip
    a = lidar_truth_arrays(lt)
    assert "hit_w" not in a and np.count_nonzero(a["hit_w_xor"]) == 3


@pytest.mark.parametrize("umask", [0o022, 0o077])
def test_session_folders_get_ordinary_permissions(tmp_path, umask):
    import os
    import stat

    from exobench.envs.sim import StairScenario, simulate_stairs

    ep = simulate_stairs(StairScenario.from_dict({}), 0)
    old = os.umask(umask)
    try:
        path = write_session(ep, tmp_path / "s")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o777 & ~umask
