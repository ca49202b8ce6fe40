"""The sensor kinds the simulation core can mount and a session can store: one line each.

A sensor kind is, on the simulation side, its adapter (how the recorder runs it:
:class:`~exobench.envs.sensors.adapter.SensorAdapter`) and its session codec (how its frames
are written and read: :class:`~exobench.envs.session.codecs.FrameCodec`); what the core knows
of its frames (fault forms, NaN and absurd-value rules) is its record in the core table
(:data:`exobench.core.kinds.KINDS`), named by the codec's ``kind``. The sensor kind name and
the frame kind name differ only where the sensor is not its frames (``encoders`` record
``joints``). :func:`registration_problems` says, kind by kind, what one of the two tables lacks.
"""

from __future__ import annotations

from dataclasses import dataclass

from exobench.core import UnknownNameError
from exobench.core.kinds import KINDS, record_problems

from ..session import codecs
from ..session.codecs import FrameCodec, register_codec
from .adapter import SensorAdapter
from .contact.adapter import ContactAdapter
from .encoders.adapter import EncoderAdapter
from .imu.adapter import ImuAdapter
from .lidar.adapter import LidarAdapter
from .odometry.adapter import OdometryAdapter
from .rgbd.adapter import RgbdAdapter
from .tof.adapter import ToFAdapter


@dataclass(frozen=True)
class SensorKind:
    """One sensor kind of the simulation: ``adapter`` runs it in the recorder, ``codec`` stores
    its frames (``codec.kind`` is its frame kind, a key of :data:`exobench.core.kinds.KINDS`)."""

    name: str
    adapter: type[SensorAdapter]
    codec: FrameCodec


SENSOR_KINDS: dict[str, SensorKind] = {}
"""Every sensor kind by name (fill it with :func:`register_sensor_kind` only)."""


def register_sensor_kind(name: str, adapter: type[SensorAdapter], codec: FrameCodec) -> SensorKind:
    """Add a sensor kind and its codec (to :data:`exobench.envs.session.codecs.CODECS`); a name,
    frame kind or frame type registered twice is refused with a ``ValueError``."""
    if name in SENSOR_KINDS:
        raise ValueError(f"sensor kind {name!r} is registered already")
    if codecs.CODECS.get(codec.kind) is not codec:  # the shipped codecs register themselves
        register_codec(codec)
    SENSOR_KINDS[name] = kind = SensorKind(name, adapter, codec)
    return kind


def unregister_sensor_kind(name: str) -> None:
    """Remove a sensor kind and its codec (a test that registered its own kind cleans up with this)."""
    kind = SENSOR_KINDS.pop(name)
    codecs.CODECS.pop(kind.codec.kind, None)


def adapter_class(kind: str) -> type[SensorAdapter]:
    """The adapter of a sensor kind; :class:`UnknownNameError` names the known kinds."""
    if kind not in SENSOR_KINDS:
        raise UnknownNameError("sensor kind", kind, SENSOR_KINDS)
    return SENSOR_KINDS[kind].adapter


_ADAPTER_PARTS = ("needs_dynamics", "calibration_shared", "has_mount", "streams", "instants", "observe",
                  "finish", "take", "close", "calibration_params", "calibration_extra")  # fmt: skip
_CODEC_PARTS = ("encode", "decode", "example")


def kind_problems(name: str) -> list[str]:
    """What sensor kind ``name`` lacks in either table, one line each (empty when nothing)."""
    where = f"sensor kind {name!r}"
    sk = SENSOR_KINDS.get(name)
    if sk is None:
        return [f"{where}: no adapter and no session codec (no register_sensor_kind line in envs/sensors/kinds.py)"]
    out = [f"{where}: adapter {getattr(sk.adapter, '__name__', sk.adapter)} has no {p}"
           for p in _ADAPTER_PARTS if not hasattr(sk.adapter, p)]  # fmt: skip
    if not isinstance(sk.codec, FrameCodec):
        return [*out, f"{where}: no session codec ({sk.codec!r} is not a FrameCodec)"]
    out += [f"{where}: codec has no {p} function" for p in _CODEC_PARTS if not callable(getattr(sk.codec, p))]
    frame_kind = sk.codec.kind
    if codecs.CODECS.get(frame_kind) is not sk.codec:
        out.append(f"{where}: its codec {frame_kind!r} is not the one sessions use")
    record = KINDS.get(frame_kind)
    if record is None:
        out.append(f"{where}: frame kind {frame_kind!r} has no core record (exobench.core.kinds.register_kind): "
                   "no fault forms, no NaN-value counter, no absurd-value rule, refused by check_frame")  # fmt: skip
    elif record.frame_type is not sk.codec.frame_type:
        out.append(f"{where}: its codec writes {sk.codec.frame_type.__name__}, "
                   f"its core record {frame_kind!r} is {record.frame_type.__name__}")  # fmt: skip
    else:
        out += [f"{where}: frame kind {frame_kind!r}: {p}" for p in record_problems(record)]
    return out


def registration_problems() -> list[str]:
    """What every kind of the two tables lacks: each sensor kind (:func:`kind_problems`) and each
    core frame kind that no sensor kind records and stores."""
    out = [p for name in SENSOR_KINDS for p in kind_problems(name)]
    stored = {sk.codec.kind for sk in SENSOR_KINDS.values() if isinstance(sk.codec, FrameCodec)}
    out += [f"frame kind {k!r}: no adapter and no session codec (no register_sensor_kind line in "
            "envs/sensors/kinds.py)" for k in KINDS if k not in stored and k not in EPISODE_KINDS]  # fmt: skip
    for k in EPISODE_KINDS:
        codec = codecs.CODECS.get(k)
        if k not in KINDS or codec is None or codec.frame_type is not KINDS[k].frame_type:
            out.append(f"episode frame kind {k!r}: needs a core record and a session codec of the same frame type")
    return out


EPISODE_KINDS = ("session", "place_label")
"""Frame kinds no sensor measures: the episode composer writes them (session starts, place labels
as a user gives them), so they have a core record and a session codec but no adapter."""


# the table of shipped sensor kinds: one line each
register_sensor_kind("tof", ToFAdapter, codecs.TOF)
register_sensor_kind("imu", ImuAdapter, codecs.IMU)
register_sensor_kind("encoders", EncoderAdapter, codecs.JOINTS)
register_sensor_kind("contact", ContactAdapter, codecs.CONTACT)
register_sensor_kind("lidar", LidarAdapter, codecs.LIDAR)
register_sensor_kind("rgbd", RgbdAdapter, codecs.RGBD)
register_sensor_kind("odometry", OdometryAdapter, codecs.ODOMETRY)
