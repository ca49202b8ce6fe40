"""Locomotion-mode prediction (the ``locomotion`` track)."""
