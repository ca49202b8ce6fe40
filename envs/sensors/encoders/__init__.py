"""Leg joint encoders: :class:`EncoderConfig` and :class:`EncoderSensor`."""

from .config import EncoderConfig
from .model import ENCODER_ID, EncoderSensor

__all__ = ["ENCODER_ID", "EncoderConfig", "EncoderSensor"]
