"""Recorded sessions on disk: an episode's frames, calibration and (apart) ground truth.

Layout of a session directory (format ``exobench-session``, version 5)::

    meta.json                      format, version, exobench version, track, scenario, seed, frame
                                   counts, truth counts, every other file's size and SHA-256
    calibration.json               sensor mounts, encoder joint names, robot description (URDF text)
    frames.jsonl                   every frame, time-ordered, one JSON object per line ("kind" first)
    lidar/<sensor_id>.npz          every scan of that LiDAR in one compact stream (lidar_pack)
    <kind>/<sensor_id>/<k>.npz     arrays of the k-th frame of that sensor, for kinds with large
                                   arrays (rgbd/, and LiDAR scans whose dtypes the stream does not
                                   take; k = 000000, 000001, ...)
    truth/episode.json             scene surfaces, estimator frame, tracks, events, the climbing
                                   step's truth (or null), trajectory_w, number of LiDAR truths
    truth/tof.jsonl                ground truth of each ToF frame, in ToF frame order
    truth/lidar.npz                ground truth of every LiDAR scan of the episode, one stream
                                   (version 4, or truths the stream does not take: truth/lidar/<k>.npz,
                                   the truth of the k-th LiDAR scan of the episode, all sensors)
    truth/extra.npz                the numpy arrays of ``EpisodeTruth.extra`` (only when it has any)
    truth/segmentation/<id>.npz    per-pixel segmentation truth of every frame of that RGB-D camera
                                   (only when the episode has some)

Modules: :mod:`.codecs` (how each frame kind is written and read; the codecs are registered by
the sensor kind table, :mod:`exobench.envs.sensors.kinds`, one line per kind), :mod:`.store` (lossless JSON values and the .npz files),
:mod:`.lidar_pack` and :mod:`.packing` (the compact LiDAR streams and their bit-exact residuals),
:mod:`.calibration`, :mod:`.truth` (the ``truth/`` folder; :mod:`.segmentation` its per-pixel
part), :mod:`.io` (writing and reading directories).

Floats in JSON are written with Python's shortest round-trip repr, so reading a session gives
back the same float64 values bit for bit; NaN is written as ``null``. A session is written into
a temporary sibling directory and renamed into place, so a failed write leaves nothing behind.
:func:`iter_frames` streams: it loads a frame's binary file when its line is read. A pipeline
replayed on a session gets exactly the frames it would have had live, so it scores identically;
the truth/ folder is for the harness and can be left out when sharing real logs.

Versions: 1 had no binary files (LiDAR and RGB-D frames were refused) and no LiDAR truth;
version-1 sessions are still read (their LiDAR truth is empty). Version 2 wrote the climbing
step's fields flat for every episode; version 3 writes them as a ``stairs`` object, null when the
episode has no climbing step (versions 1 and 2 read them as the stairs part of staircase episodes
only). Version 4 adds the track, the truth counts and the file hashes to ``meta.json``; a session
is checked against them (and its frame counts) before it is read, and older versions are read
without the hash check (unless they list hashes); every version has its frames checked against
the truth they are scored with (:mod:`.checks`). Version 5 stores the LiDAR scans of each sensor and the LiDAR truths
in one compact stream each (about an eighth of version 4's size); ``write_session(...,
compact=False)`` still writes version 4. Writing gives version 5.
"""

from .calibration import calibration_from_dict, calibration_to_dict
from .codecs import CODECS, FrameCodec, codec_table, frame_from_dict, frame_to_dict, register_codec
from .io import (
    FORMAT,
    SUPPORTED_VERSIONS,
    VERSION,
    check_track,
    content_checked,
    iter_frames,
    read_meta,
    read_session,
    verify_files,
    write_session,
)
from .truth import truth_from_dict, truth_to_dict

__all__ = [
    "CODECS",
    "FORMAT",
    "SUPPORTED_VERSIONS",
    "VERSION",
    "FrameCodec",
    "calibration_from_dict",
    "check_track",
    "content_checked",
    "calibration_to_dict",
    "frame_from_dict",
    "frame_to_dict",
    "iter_frames",
    "read_meta",
    "read_session",
    "codec_table",
    "register_codec",
    "truth_from_dict",
    "truth_to_dict",
    "verify_files",
    "write_session",
]
