"""Locomotion-mode prediction from a depth camera (the ``locomotion`` track).

- :mod:`.config`: the pipelines' configs (stages nested: ``ahc``, ``planes``, ``terrain``,
  ``footprint``, ``tsdf``).
- :mod:`.base`: frames, heel strikes, footprints and the next step's mode, shared.
- :mod:`.pipelines`: the pipelines ``terrain-recon`` and ``single-frame``.
- :mod:`.depth` / :mod:`.body`: depth-image helpers; sensor mounts on the standing device.
"""

from .config import LocomotionConfig, TerrainReconConfig
from .pipelines import SingleFramePipeline, TerrainReconstructionPipeline

__all__ = ["LocomotionConfig", "SingleFramePipeline", "TerrainReconConfig", "TerrainReconstructionPipeline"]
