"""Insole force pads: :class:`ContactConfig`, :class:`ContactSensor` and :func:`contact_forces`."""

from .config import ContactConfig
from .model import ContactSensor, contact_forces

__all__ = ["ContactConfig", "ContactSensor", "contact_forces"]
