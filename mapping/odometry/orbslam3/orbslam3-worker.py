"""ORB-SLAM3 worker: the only file of exobench that imports pyorbslam3 (GPL-3.0).

Not a module of exobench (its name is not an identifier, so nothing can import it): the
``orb-slam3`` adapter runs it as ``python orbslam3-worker.py`` and talks to it over its stdin and
stdout. ORB-SLAM3 prints to the C++ standard output, so the first thing done here is to move the
protocol to a duplicate of the stdout descriptor and point descriptor 1 at stderr.

Protocol (both ways): a message is a 4-byte little-endian length, that many bytes of a JSON
header, then the raw bytes of each array the header lists in ``arrays`` (name, dtype, shape), in
order. Requests: ``init`` (vocabulary, settings) -> ``ready``; ``track`` (stamp ``t``; arrays
``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32, ``imu`` (N, 7) float64 rows
``[t, gx, gy, gz, ax, ay, az]``) -> ``tracked`` (state, pose_valid, points, imu_initialised,
map_changed; array ``pose_wc`` (4, 4) when valid); ``close`` (optional ``trajectory``: a path to
save ORB-SLAM3's EuRoC trajectory export to after its shutdown) -> ``closed`` (``saved``, or
``save_error`` when ORB-SLAM3 had nothing to save). A request that raises
is answered ``error`` (message) and the worker goes on; a closed stdin ends it.
"""

import json
import os
import struct
import sys

import numpy as np


def _read_exact(fd, n):
    chunks, left = [], n
    while left:
        b = os.read(fd, left)
        if not b:
            return None
        chunks.append(b)
        left -= len(b)
    return b"".join(chunks)


def _read(fd):
    head = _read_exact(fd, 4)
    if head is None:
        return None, {}
    header = json.loads(_read_exact(fd, struct.unpack("<I", head)[0]))
    arrays = {}
    for name, dtype, shape in header.get("arrays", ()):
        dt = np.dtype(dtype)
        n = int(np.prod(shape)) * dt.itemsize
        arrays[name] = np.frombuffer(_read_exact(fd, n) if n else b"", dtype=dt).reshape(shape)
    return header, arrays


def _write(fd, header, arrays=None):
    arrays = arrays or {}
    header = dict(header, arrays=[(k, a.dtype.str, list(a.shape)) for k, a in arrays.items()])
    body = json.dumps(header).encode()
    data = b"".join([struct.pack("<I", len(body)), body, *(np.ascontiguousarray(a).tobytes() for a in arrays.values())])
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def main():
    out = os.dup(1)
    os.dup2(2, 1)  # ORB-SLAM3's prints go to stderr, never into the protocol
    inp = sys.stdin.fileno()
    import pyorbslam3 as pos

    slam = None
    while True:
        req, arrays = _read(inp)
        if req is None:
            break
        op = req.get("op")
        try:
            if op == "init":
                slam = pos.Slam(req["vocabulary"], req["settings"], pos.Sensor.IMU_RGBD, use_viewer=False)
                _write(out, {"op": "ready"})
            elif op == "track":
                res = slam.track_rgbd(arrays["rgb"], arrays["depth"], float(req["t"]), imu=arrays["imu"])
                reply = {"op": "tracked", "state": res.state.name, "pose_valid": bool(res.pose_valid),
                         "points": int(res.num_tracked_points), "imu_initialised": bool(slam.imu_initialized()),
                         "map_changed": bool(slam.map_changed())}
                pose = res.pose_wc if res.pose_valid else None
                _write(out, reply, {"pose_wc": np.asarray(pose, dtype=np.float64)} if pose is not None else None)
            elif op == "close":
                reply = {"op": "closed", "saved": False}
                if slam is not None:
                    slam.shutdown()
                    if req.get("trajectory"):
                        try:  # ORB-SLAM3 raises when its atlas holds no keyframe (every map was reset)
                            slam.save_trajectory_euroc(req["trajectory"])
                            reply["saved"] = True
                        except Exception as e:
                            reply["save_error"] = f"{type(e).__name__}: {e}"
                _write(out, reply)
                break
            else:
                _write(out, {"op": "error", "message": f"unknown request {op!r}"})
        except Exception as e:  # the adapter records it as the frame's failure
            _write(out, {"op": "error", "message": f"{type(e).__name__}: {e}"})


if __name__ == "__main__":
    main()
